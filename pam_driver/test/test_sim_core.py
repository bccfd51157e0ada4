"""SimCore (pam_driver.sim_core): the simulated rig's decisions, called directly (no ROS, no
spinning): the lockstep protocol, the realtime stepping that never pauses, commands from the
past, bad voltages, non-finite samples and the /diagnostics policy."""

import math

import pytest

from pam_common.diagnostics import ERROR, OK, WARN
from pam_common.run_health import LATE_SAMPLES, MISSED_SAMPLES, SAMPLES_TAKEN
from pam_driver.sim_config import build_config
from pam_driver.sim_core import RealtimeSampler, SimCore

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
    [first] = core.realtime_samples(0, [0])
    assert (first.counter, core.rig.k) == (1, 0)     # the first deadline: sample 0, no step
    [after] = core.realtime_samples(3, [4 * H_NS])   # 3 missed, then this deadline's
    assert (after.counter, after.t_ns, core.rig.k) == (5, 4 * H_NS, 4)
    core.stats.record(0.0)
    core.stats.record(3.5e-3, 3)                     # the stall: 3 samples missed
    _, _, values = core.report(1.0)
    assert values[MISSED_SAMPLES] == 3 and values[LATE_SAMPLES] >= 3
    assert values[SAMPLES_TAKEN] == 5


def test_realtime_commands_are_held_and_timed():
    core = SimCore(build_config({}), start=0.0)
    core.realtime_samples(0, [0])
    out = core.on_command(8.0, 3.0, 0, 1_000_000)
    assert out.applied == (8.0, 3.0) and out.sample is None
    core.realtime_samples(0, [H_NS, 2 * H_NS])
    assert core.rig.u == (8.0, 3.0) and core.rig.k == 2   # held over both steps


def sampler(backlog=20, start=0.0, start_ns=7_000_000_000):
    core = SimCore(build_config({}), start=start)
    return core, RealtimeSampler(core, 1e-3, start, start_ns, backlog)


def test_the_sampler_takes_one_sample_per_deadline_on_time():
    core, s = sampler()
    assert s.wait(-0.5e-3) == pytest.approx(0.5e-3)    # before the first deadline
    assert s.next(-0.5e-3) is None
    for n in range(5):
        sample, lateness, missed = s.next(n * 1e-3 + 1e-4)
        assert (sample.counter, sample.t_ns, missed) == (n + 1, 7_000_000_000 + n * H_NS, 0)
        assert lateness == pytest.approx(1e-4)
        assert s.next(n * 1e-3 + 2e-4) is None           # the next deadline is not due yet
    assert core.rig.k == 4


def test_after_a_stall_the_plant_has_moved_on_with_the_held_command_and_the_loop_sees_each_sample():
    """A stall of 4.5 periods after sample 0: the plant stepped through the 5 passed deadlines
    at once with the command held during the stall; the 5 samples leave in order, late, each
    stamped with its deadline; a command applied while they leave does not reach the steps
    already taken."""
    core, s = sampler()
    s.next(0.0)
    core.on_command(8.0, 3.0, 0, 0)
    held = core.rig.x.copy()
    out = [s.next(5.5e-3)]
    assert core.rig.k == 5                               # every passed deadline stepped at once
    core.on_command(0.0, 10.0, 0, 0)                     # the answer to the oldest, late
    out += [s.next(5.6e-3) for _ in range(3)]
    assert s.wait(5.7e-3) == 0.0                         # one still waiting: no sleep
    out.append(s.next(5.7e-3))
    assert s.next(5.8e-3) is None and s.wait(5.8e-3) == pytest.approx(0.2e-3)
    assert [o[0].counter for o in out] == [2, 3, 4, 5, 6]
    assert [o[0].t_ns - 7_000_000_000 for o in out] == [n * H_NS for n in range(1, 6)]
    assert [o[2] for o in out] == [0] * 5
    assert [o[1] for o in out] == pytest.approx([4.5e-3, 3.6e-3, 2.6e-3, 1.6e-3, 0.7e-3])
    # the plant: 5 steps with (8, 3) V from the held state, none with the late (0, 10) V
    reference = SimCore(build_config({}), start=0.0)
    reference.rig.x = held
    reference.rig.set_command(8.0, 3.0)
    for _ in range(5):
        reference.rig.step()
    assert (core.rig.x == reference.rig.x).all()
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


def test_a_stall_longer_than_the_backlog_drops_the_oldest_samples():
    """backlog 3 and a stall of 10 periods after sample 0: 4 samples wait (this deadline's and 3
    overdue), the 6 older ones are missed (stepped, never taken), counted with the first sample
    that leaves; a later stall while one still waits drops the oldest waiting one."""
    core, s = sampler(backlog=3)
    s.next(0.0)
    sample, lateness, missed = s.next(10.2e-3)
    assert (sample.counter, missed, core.rig.k) == (8, 6, 10)
    assert lateness == pytest.approx(9.2e-3)       # the stall: the oldest missed one's
    assert [s.next(10.3e-3)[0].counter for _ in range(2)] == [9, 10]   # 11 (10 ms) waits
    sample, lateness, missed = s.next(14.1e-3)    # 4 more due: 5 would wait, the oldest goes
    assert (sample.counter, missed, core.rig.k) == (12, 1, 14)
    assert lateness == pytest.approx(4.1e-3)       # counter 11's deadline was 10 ms
    assert s.next(14.2e-3)[1] == pytest.approx(2.2e-3)   # 13: its own lateness again
    sample, lateness, missed = s.next(16.1e-3)    # 2 more due: 4 wait, none goes
    assert (sample.counter, missed, core.rig.k) == (14, 0, 16)
    assert [s.next(16.2e-3)[0].counter for _ in range(3)] == [15, 16, 17]
    assert s.next(16.2e-3) is None
