"""SimCore (pam_driver.sim_core): the simulated rig's decisions, called directly (no ROS, no
spinning): the lockstep protocol, the realtime stepping that never pauses, commands from the
past, bad voltages, non-finite samples and the /diagnostics policy."""

import math

import pytest

from pam_common.diagnostics import ERROR, OK, WARN
from pam_common.run_health import LATE_SAMPLES, MISSED_SAMPLES, SAMPLES_TAKEN
from pam_driver.sim_config import build_config
from pam_driver.sim_core import SimCore

H_NS = 1_000_000      # ns, the model step at the default 1 kHz


def lockstep_core(**overrides) -> SimCore:
    return SimCore(build_config({'timing': 'lockstep', 'scenario': 'mild', **overrides}),
                   start=0.0)


def test_lockstep_steps_once_per_command_for_the_current_step():
    core = lockstep_core()
    first = core.first_lockstep_sample()
    assert (first.t_ns, first.counter) == (0, 1)
    out = core.on_command(7.0, 4.0, 0, 0)          # stamp 0: for the current step
    assert out.ok and out.applied == (7.0, 4.0) and out.step == 0 and not out.past
    assert (out.sample.t_ns, out.sample.counter) == (H_NS, 2)
    out = core.on_command(7.0, 4.0, H_NS, 0)       # stamped t_1: for step 1
    assert (out.sample.t_ns, out.sample.counter, core.rig.k) == (2 * H_NS, 3, 2)
    assert core.current == out.sample


def test_lockstep_ignores_commands_from_the_past():
    core = lockstep_core()
    core.first_lockstep_sample()
    core.on_command(6.0, 5.0, 0, 0)
    core.on_command(6.0, 5.0, H_NS, 0)             # now at step 2, t_2 = 2 ms
    out = core.on_command(9.0, 1.0, H_NS, 0)       # for step 1: the past
    assert out.past == 1 and out.applied is None and out.sample is None
    assert out.t_k_ns == 2 * H_NS and out.step == 2
    assert core.rig.k == 2 and core.rig.u == (6.0, 5.0)     # nothing stepped, nothing applied
    level, message, values = core.report(1.0)
    assert level == WARN and '1 commands from the past ignored' in message
    assert values['past commands ignored'] == 1
    assert core.report(2.0)[0] == OK                # counted once: the next window is clean


def test_bad_voltages_are_sanitised_counted_and_reported():
    core = lockstep_core()
    core.first_lockstep_sample()
    out = core.on_command(math.nan, 12.0, 0, 0)
    assert not out.ok and out.applied == (0.0, 10.0)
    assert (out.non_finite, out.out_of_range) == (1, 1)
    level, message, _ = core.report(1.0)
    assert level == WARN and 'bad command voltages sanitised' in message


def test_the_same_seed_and_commands_give_the_same_samples():
    def run(seed):
        core = lockstep_core(seed=seed)
        samples = [core.first_lockstep_sample()]
        for k in range(50):
            samples.append(core.on_command(5.5 + math.sin(k / 7.0), 5.5, k * H_NS, 0).sample)
        return samples
    assert run(3) == run(3)
    assert run(3) != run(4)


def test_realtime_never_pauses_it_steps_through_missed_samples():
    core = SimCore(build_config({}), start=0.0)
    first = core.realtime_sample(0, 0)
    assert (first.counter, core.rig.k) == (1, 0)     # the first deadline: sample 0, no step
    after = core.realtime_sample(3, 4 * H_NS)        # 3 missed, then this deadline's
    assert (after.counter, after.t_ns, core.rig.k) == (5, 4 * H_NS, 4)
    core.stats.record(0.0)
    core.stats.record(3.5e-3, 3)                     # the stall: 3 samples missed
    _, _, values = core.report(1.0)
    assert values[MISSED_SAMPLES] == 3 and values[LATE_SAMPLES] >= 3
    assert values[SAMPLES_TAKEN] == 5


def test_realtime_commands_are_held_and_timed():
    core = SimCore(build_config({}), start=0.0)
    core.realtime_sample(0, 0)
    out = core.on_command(8.0, 3.0, 0, 1_000_000)
    assert out.applied == (8.0, 3.0) and out.sample is None
    core.realtime_sample(0, H_NS)
    core.realtime_sample(0, 2 * H_NS)
    assert core.rig.u == (8.0, 3.0) and core.rig.k == 2   # held over both steps


@pytest.mark.parametrize('fault, nonfinite, level', [('sampling thread stopped: X', 0, ERROR),
                                                     ('', 1, ERROR)])
def test_a_failed_sampler_or_a_suppressed_sample_is_an_error(fault, nonfinite, level):
    core = lockstep_core()
    core.fault = fault
    core.nonfinite_samples = nonfinite
    assert core.report(1.0)[0] == level


def test_a_non_finite_state_is_suppressed_and_counted():
    core = lockstep_core()
    core.rig.x[:] = math.nan
    assert core.first_lockstep_sample() is None
    assert core.nonfinite_samples == 1 and all(math.isnan(v) for v in core.nonfinite_state)
