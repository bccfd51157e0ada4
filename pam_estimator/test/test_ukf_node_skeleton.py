"""ukf_node follows the node skeleton (pam_common.node_skeleton): --help, a stray argument, a
misspelt parameter (pam_common.testing.assert_follows_the_skeleton)."""

from pam_common.testing import assert_follows_the_skeleton
from pam_estimator import ukf_config


def test_follows_the_skeleton(node_process):
    assert_follows_the_skeleton(node_process, 'ukf_node', 'pam_estimator', ukf_config.PARAMETERS)
