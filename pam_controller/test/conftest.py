"""Fixtures of the pam_controller tests: see pam_driver.testing (shared topic-level support)."""

from pam_driver.testing import (node_process, probe, ros_context, ros_domain,  # noqa: F401
                                stamp_ns, wait_until)
