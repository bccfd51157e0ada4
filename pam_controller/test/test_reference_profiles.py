"""reference_node's profiles (no ROS) and the node as a real process."""

import math

import numpy as np
import pytest

from pam_common.node_params import ConfigError, defaults
from pam_controller.reference_node import PARAMETERS, build_config, profile_value, step_levels
from pam_interfaces.msg import Reference


def values(**overrides):
    v = defaults(PARAMETERS)
    v.update(overrides)
    return build_config(v)


def test_steps_stay_within_the_amplitude_and_hold():
    v = values(profile='steps', amplitude=math.radians(20.0), hold=8.0, duration=64.0, seed=3)
    levels = step_levels(v)
    assert len(levels) == 8 and levels[0] == 0.0
    assert np.all(np.abs(levels) <= math.radians(20.0) + 1e-12)
    assert profile_value(v, levels, 8.5) == levels[1] == profile_value(v, levels, 15.9)
    assert profile_value(v, levels, 100.0) == levels[-1]            # holds the last value
    looped = values(profile='steps', seed=3, repeat=True)
    assert profile_value(looped, step_levels(looped), 64.0 + 8.5) == levels[1]


@pytest.mark.parametrize('kind, t, expected', [('sine', 2.5, 0.2), ('ramp', 0.0, 0.0),
                                               ('ramp', 2.5, 0.2), ('ramp', 7.5, -0.2),
                                               ('constant', 3.0, 0.0)])
def test_ramp_sine_constant(kind, t, expected):
    v = values(profile=kind, amplitude=0.2, period=10.0)
    assert profile_value(v, None, t) == pytest.approx(expected)


def test_the_envelope_is_enforced():
    with pytest.raises(ConfigError, match='amplitude'):
        values(mode='torque', amplitude=2.5, offset=1.0)
    with pytest.raises(ConfigError, match='profile'):
        values(profile='square')


def test_reference_node_publishes(node_process, probe):
    got = probe.subscribe(Reference, '/pam/reference')
    node = node_process('reference_node', 'pam_controller', '-p', 'mode:=torque', '-p',
                        'profile:=sine', '-p', 'amplitude:=1.5', '-p', 'period:=1.0')
    node.wait_for(lambda: len(got) >= 150, 30.0, '150 references (1.5 periods)')
    msgs = got.messages()
    assert all(m.mode == Reference.TORQUE for m in msgs)
    assert max(m.value for m in msgs) > 1.0 and min(m.value for m in msgs) < -1.0
