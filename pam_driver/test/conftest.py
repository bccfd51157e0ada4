"""Fixtures of the pam_driver tests: see pam_common.testing (shared with the other packages)."""

import types

import pytest

from pam_common.testing import (
    all_finite,
    diagnostic_statuses,
    installed_config,
    node_process,
    probe,
    ros_context,
    ros_domain,
    stamp_ns,
    wait_until,
)


@pytest.fixture
def sim_node(node_process):
    """Factory: sim_node(*ros_args) starts `sim_node --ros-args *ros_args` (raw=True: exact
    argv)."""
    def start(*args, raw: bool = False):
        return node_process('sim_node', 'pam_driver', *args, raw=raw)
    return start


@pytest.fixture(scope='session')
def helpers():
    """Helper functions for test modules (conftest is not importable by name)."""
    return types.SimpleNamespace(wait_until=wait_until, stamp_ns=stamp_ns,
                                 diagnostic_statuses=diagnostic_statuses, all_finite=all_finite,
                                 installed_config=installed_config)
