"""PiConfig (pam_controller.pi_config): pi_node's frozen configuration, built once from its
parameter table and checked there; a run-time change builds a new one, checked the same way."""

import dataclasses

import pytest

from pam_common.node_params import ConfigError, defaults
from pam_controller.control_loop import ANGLE, TORQUE
from pam_controller.pi import PiGains
from pam_controller.pi_config import PARAMETERS, PiConfig
from pam_model.rest import BETA, REST_COMMAND


def test_the_defaults_are_the_tables():
    config = PiConfig.default()
    table = defaults(PARAMETERS)
    assert config.mode == ANGLE
    assert config.angle == PiGains(table['kp_angle'], table['ki_angle'], BETA, 0.0, 10.0)
    assert config.torque == PiGains(table['kp_torque'], table['ki_torque'], BETA, 0.0, 10.0)
    assert config.safe_command == REST_COMMAND
    assert config.frame_id == 'pam_joint' and config.feedback == 'estimate'
    assert not config.realtime.asked
    loop = config.make_loop()
    assert loop.mode == ANGLE and loop.safe_command == REST_COMMAND and loop.enabled


def test_it_is_frozen():
    config = PiConfig.default()
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.anti_windup = 'back_calculation'
    with pytest.raises(TypeError):
        config.values['kp_angle'] = 1.0          # the values it was built from are read-only


@pytest.mark.parametrize('changes, names', [
    ({'kp_angle': -1.0}, 'kp_angle'),
    ({'u_min': 6.0}, 'beta must lie'),
    ({'u_min': 8.0, 'u_max': 7.0}, 'u_min'),
    ({'anti_windup': 'clamp'}, 'anti_windup'),
    ({'safe_command': [5.5, 12.0]}, 'safe_command'),
    ({'mode': 'speed'}, 'mode'),
    ({'cpu_affinity': [-1]}, 'cpu_affinity'),
])
def test_bad_values_are_named_and_change_nothing(changes, names):
    config = PiConfig.default()
    with pytest.raises(ConfigError, match=names):
        config.changed(changes)
    assert config == PiConfig.default()


def test_a_change_builds_a_new_config():
    config = PiConfig.default()
    changed = config.changed({'kp_torque': 3.0, 'beta': 5.0, 'anti_windup': 'back_calculation',
                              'mode': 'torque'})
    assert changed.torque == PiGains(3.0, config.torque.ki, 5.0, 0.0, 10.0)
    assert changed.angle.beta == 5.0 and changed.anti_windup == 'back_calculation'
    assert changed.mode == TORQUE
    assert config.torque.kp == defaults(PARAMETERS)['kp_torque']    # the old one untouched
    assert 'torque kp 3 V/(N m)' in changed.describe()
