"""pam_common.joint_states without ROS: the decimation and the checks of joint_name and
joint_states_rate (the nodes' JointState topics: pam_driver/test/test_sim_node_joint_states.py,
test_driver_node.py, pam_estimator/test/test_ukf_node_joint_states.py)."""

import pytest

from pam_common.joint_states import (
    check_joint_states,
    every_nth_sample,
    joint_state_params,
    urdf_joint_name,
)
from pam_common.node_params import ConfigError, Deferred, check_all, defaults


def test_every_nth_sample():
    assert every_nth_sample(1000.0, 1000.0) == 1
    assert every_nth_sample(100.0, 1000.0) == 10
    assert every_nth_sample(300.0, 1000.0) == 3         # round(3.33): 333 Hz, the nearest
    assert every_nth_sample(0.0, 1000.0) == 0           # off
    assert every_nth_sample(1000.0, 500.0) == 1         # never more than every sample


def test_the_defaults_come_from_the_urdf():
    specs = joint_state_params('joint_states', 'the joint')
    assert isinstance(specs[0].default, Deferred)         # read when needed, not at import
    assert specs[0].default_text() == "'seesaw_joint'"
    values = check_all(specs, defaults(specs))
    assert urdf_joint_name() == ('seesaw_joint', '')
    assert values == {'joint_name': 'seesaw_joint', 'joint_states_rate': 1000.0}
    assert check_joint_states(values, 1000.0) is values
    assert check_joint_states(values, 500.0) is values    # the default: every sample


@pytest.mark.parametrize('name, rate, sample_rate, message', [
    ('', 100.0, 1000.0, "parameter 'joint_name': empty; give the joint's name (the URDF's is "
                        "'seesaw_joint')"),
    ('j', 1500.0, 1000.0, "parameter 'joint_states_rate': 1500 Hz is above the sample rate "
                          '1000 Hz'),
    ('j', 600.0, 500.0, "parameter 'joint_states_rate': 600 Hz is above the sample rate 500 Hz"),
])
def test_bad_values_are_refused(name, rate, sample_rate, message):
    with pytest.raises(ConfigError) as error:
        check_joint_states({'joint_name': name, 'joint_states_rate': rate}, sample_rate)
    assert str(error.value).startswith(message)


def test_a_rate_known_later_is_not_checked_against_one():
    values = {'joint_name': 'j', 'joint_states_rate': 5000.0}
    assert check_joint_states(values, None) is values
