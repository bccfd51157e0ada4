"""SimulatedRig (pam_model.rig), the plant sim_node and pam-emulator wrap, called directly: the
held command and its sanitising, the sample clock, the sensor's seeded noise, the locked joint,
and its bad initial states. (Its unmodelled effects are test_effects.py's.)"""

import math

import numpy as np
import pytest

from pam_model.model import PamModel
from pam_model.rest import REST_COMMAND, REST_STATE
from pam_model.rig import SimulatedRig
from pam_model.sensor import PressureSensor


def test_the_command_is_held_between_samples_and_sanitised():
    rig = SimulatedRig(PamModel(), REST_STATE, u0=REST_COMMAND)
    assert rig.u == REST_COMMAND and rig.bad_commands == 0
    assert rig.set_command(7.0, 4.0) and rig.u == (7.0, 4.0)
    for _ in range(5):
        rig.step()
    assert rig.u == (7.0, 4.0)                       # held: nothing but set_command changes it
    assert not rig.set_command(math.nan, 12.5)       # non-finite -> 0 V (vent), clipped to 10 V
    assert rig.u == (0.0, 10.0)
    assert (rig.non_finite_commands, rig.out_of_range_commands, rig.bad_commands) == (1, 1, 2)


def test_the_sample_clock_is_the_step_count_times_h():
    rig = SimulatedRig(PamModel(), REST_STATE)
    assert (rig.k, rig.t) == (0, 0.0)
    for _ in range(250):
        rig.step()
    assert rig.k == 250 and rig.t == pytest.approx(0.25)
    sample = rig.sample()
    assert sample.t == rig.t and np.array_equal(sample.x, rig.x)
    T_f, sigma = rig.step_full()
    assert math.isfinite(T_f) and 1 <= sigma <= 18 and rig.k == 251


def test_the_sensor_noise_is_the_seeds():
    def readings(seed):
        rig = SimulatedRig(PamModel(), REST_STATE, sensor=PressureSensor(noise_std=2000.0),
                           seed=seed)
        return [tuple(rig.sample().p_measured) for _ in range(20)]
    assert readings(3) == readings(3)
    assert readings(3) != readings(4)
    noise = np.array(readings(3))[:, 0] - REST_STATE[2]
    assert 500.0 < np.std(noise) < 5000.0


def test_a_locked_joint_holds_its_angle_while_the_pressures_move():
    rig = SimulatedRig(PamModel(locked=True), (0.1, 0.3, 4.5e5, 4.5e5), u0=(9.0, 1.0))
    assert rig.x[1] == 0.0                            # a locked joint starts at rest
    for _ in range(200):
        rig.step()
    assert rig.x[0] == pytest.approx(0.1) and rig.x[1] == 0.0
    assert rig.x[2] > 4.6e5 and rig.x[3] < 4.4e5
    assert rig.plant is None                          # no effects: the paper's model


@pytest.mark.parametrize('x0', [(0.0, 0.0, 4.5e5), (0.0, math.nan, 4.5e5, 4.5e5)])
def test_a_bad_initial_state_is_refused_naming_the_units(x0):
    with pytest.raises(ValueError, match=r'4 finite numbers \[rad, rad/s, Pa, Pa\]'):
        SimulatedRig(PamModel(), x0)
