"""Fixtures of the pam_bringup tests: see pam_common.testing (shared topic-level support)."""

from pam_common.testing import node_process, probe, ros_context, ros_domain, stamp_ns, wait_until
