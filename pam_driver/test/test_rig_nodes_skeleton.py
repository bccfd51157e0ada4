"""sim_node and driver_node follow the node skeleton (pam_common.node_skeleton): --help, a stray
argument, a misspelt parameter (pam_common.testing.assert_follows_the_skeleton)."""

import pytest

from pam_common.testing import assert_follows_the_skeleton
from pam_driver import driver_config, sim_config


@pytest.mark.parametrize('node, specs', [('sim_node', sim_config.PARAMETERS),
                                         ('driver_node', driver_config.PARAMETERS)])
def test_follows_the_skeleton(node_process, node, specs):
    assert_follows_the_skeleton(node_process, node, 'pam_driver', specs)
