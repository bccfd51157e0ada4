"""ukf_node's parameter table imports without a ROS environment (no AMENT_PREFIX_PATH): the URDF
default of joint_name is read when first needed, not at import."""

from pam_common.testing import assert_imports_without_ament


def test_ukf_config_imports_without_ament():
    assert_imports_without_ament('pam_estimator.ukf_config')
