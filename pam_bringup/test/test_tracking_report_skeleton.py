"""tracking_report follows the node skeleton (pam_common.node_skeleton): --help, a stray
argument, a misspelt parameter (pam_common.testing.assert_follows_the_skeleton)."""

from pam_bringup import tracking_report
from pam_common.testing import assert_follows_the_skeleton


def test_follows_the_skeleton(node_process):
    assert_follows_the_skeleton(node_process, 'tracking_report', 'pam_bringup',
                                tracking_report.PARAMETERS)
