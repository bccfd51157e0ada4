"""bag_record and bag_play follow the node skeleton (pam_common.node_skeleton): --help, a stray
argument, a misspelt parameter (pam_common.testing.assert_follows_the_skeleton)."""

import pytest

from pam_bag import bag_play, bag_record
from pam_common.testing import assert_follows_the_skeleton


@pytest.mark.parametrize('node', [bag_record, bag_play], ids=lambda module: module.NODE_NAME)
def test_follows_the_skeleton(node_process, node):
    assert_follows_the_skeleton(node_process, node.NODE_NAME, 'pam_bag', node.PARAMETERS)
