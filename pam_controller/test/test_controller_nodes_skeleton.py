"""pi_node, reference_node and profile_player follow the node skeleton (pam_common.node_skeleton):
--help, a stray argument, a misspelt parameter (pam_common.testing.assert_follows_the_skeleton)."""

import pytest

from pam_common.testing import assert_follows_the_skeleton
from pam_controller import pi_node, profile_player, reference_node


@pytest.mark.parametrize('node', [pi_node, reference_node, profile_player],
                         ids=lambda module: module.NODE_NAME)
def test_follows_the_skeleton(node_process, node):
    assert_follows_the_skeleton(node_process, node.NODE_NAME, 'pam_controller', node.PARAMETERS)
