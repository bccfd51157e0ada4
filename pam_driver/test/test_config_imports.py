"""The rig nodes' parameter tables import without a ROS environment (no AMENT_PREFIX_PATH): the
URDF default of joint_name is read when first needed, not at import."""

import pytest

from pam_common.testing import assert_imports_without_ament


@pytest.mark.parametrize('module', ['pam_driver.sim_config', 'pam_driver.driver_config'])
def test_config_imports_without_ament(module):
    assert_imports_without_ament(module)
