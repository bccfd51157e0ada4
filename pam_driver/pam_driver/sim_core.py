"""The simulated rig's decisions, without ROS: sim_node is a thin wrapper over SimCore.

SimCore owns the plant (pam_model.rig.SimulatedRig, built by SimConfig.make_rig) and decides
what a rig decides: when the plant steps (lockstep: one step per command for the current step;
realtime: one step per sample deadline, with a held command, never pausing), which commands are
applied (a lockstep command from the past is ignored and counted; bad voltages are sanitised by
the rig and counted), what a sample reads (a plain SimSample; a non-finite one is suppressed and
counted) and how healthy the rig is (report(): the /diagnostics level, message and values). Every
method is called with the core's lock taken by the core itself, so the node's sampling thread and
its executor thread can call it concurrently. Times: ns stamps on the node clock, s elsewhere.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from typing import NamedTuple

from pam_common.latency import CommandTiming
from pam_common.levels import ERROR, OK, WARN
from pam_common.run_health import LATE_SAMPLES, MISSED_SAMPLES, SAMPLES_TAKEN, WORST_STALL_MS
from pam_common.timing import RateStatistics

from .sim_config import SimConfig
from .supply_sensor import SupplySensor

RATE_TOLERANCE = 0.05      # realtime: WARN when the achieved rate is off by more than this
LATE_TOLERANCE = 0.0       # realtime: WARN when more than this fraction of a window is late


class SimSample(NamedTuple):
    """One sample of the rig: stamp t_ns (ns), counter (the plant's step k + 1), the measured
    pressures p1, p2 (Pa abs), the true angle (rad), velocity (rad/s) and torque (N m), and the
    supply transducer's reading (Pa abs; None when not published)."""

    t_ns: int
    counter: int
    p1: float
    p2: float
    angle: float
    velocity: float
    torque: float
    supply: float | None


class CommandOutcome(NamedTuple):
    """What one valve command did. ok: its voltages were usable as given (else sanitised);
    applied: the command the valves now hold (V; None when ignored as from the past); step: the
    plant's step it applies from; past: the commands from the past so far when this one was
    one (0 otherwise), with t_k_ns the stamp of the current step; sample: the sample of the step
    it made (lockstep; None otherwise or when not finite); the rig's counts of commands
    received, non-finite and out-of-range voltages."""

    ok: bool
    applied: tuple[float, float] | None
    step: int
    past: int
    t_k_ns: int
    sample: SimSample | None
    received: int
    non_finite: int
    out_of_range: int


class SimCore:
    """The plant and its counters. `config`: the node's SimConfig; `start` (s, monotonic):
    the start of the rate statistics."""

    def __init__(self, config: SimConfig, start: float | None = None):
        self.config = config
        self.rig = config.make_rig()
        self.lock = threading.Lock()
        self.timing = CommandTiming()       # realtime: sample -> command latency at the rig
        self.stats = RateStatistics(1.0 / config.rate, time.monotonic() if start is None
                                    else start)
        self.supply = (SupplySensor(self.rig, config.sensor, config.seed)
                       if config.publish_supply_pressure else None)
        self._period_ns = 1e9 / config.rate
        self._stepped = False               # realtime: the first deadline takes sample 0
        self.current: SimSample | None = None   # lockstep: the sample of the current step
        self.commands_received = 0
        self.past_commands = 0
        self.nonfinite_samples = 0
        self.nonfinite_state: list[float] = []   # the state of the last one suppressed
        self.republished = 0
        self.samples_published = 0
        self.last_raw_command = (math.nan, math.nan)
        self._reported = {'bad': 0, 'past': 0}
        self.fault = ''

    # --- samples -------------------------------------------------------------------------------
    def stamp(self, k: int) -> int:
        """ns, lockstep: the simulated time t_k = k / rate of step k."""
        return round(k * self._period_ns)

    def _sample(self, t_ns: int) -> SimSample | None:
        """Read the rig (draws sensor noise) stamped t_ns; None, counted, if not finite."""
        sample = self.rig.sample()
        values = (float(sample.p_measured[0]), float(sample.p_measured[1]), float(sample.x[0]),
                  float(sample.x[1]), float(sample.torque))
        if not all(math.isfinite(v) for v in values):
            self.nonfinite_samples += 1
            self.nonfinite_state = [float(v) for v in sample.x]
            return None
        self.timing.on_sample(t_ns)
        supply = self.supply.measure() if self.supply is not None else None
        return SimSample(t_ns, self.rig.k + 1, *values, supply)

    def first_lockstep_sample(self) -> SimSample | None:
        """Lockstep: sample 0 (stamp 0), the one the first command answers."""
        with self.lock:
            self.current = self._sample(self.stamp(0))
            return self.current

    def realtime_samples(self, skipped: int, stamps_ns) -> list[SimSample | None]:
        """Realtime, deadlines that have passed: the plant steps through `skipped` of them
        unsampled (missed), then takes the sample of each deadline stamped in stamps_ns (ns), in
        order; one model step before each, all with the command held now; the first deadline
        ever is sample 0 (no step before it)."""
        with self.lock:
            samples = []
            for i in range(skipped + len(stamps_ns)):
                if self._stepped:
                    self.rig.step()
                self._stepped = True
                if i >= skipped:
                    samples.append(self._sample(stamps_ns[i - skipped]))
            return samples

    def published(self) -> None:
        """A sample left (counted for /diagnostics)."""
        with self.lock:
            self.samples_published += 1

    def republish(self) -> tuple[SimSample | None, int]:
        """Lockstep, no command for a while: the current sample again (counted) and its step."""
        with self.lock:
            self.republished += 1
            return self.current, self.rig.k

    # --- commands ------------------------------------------------------------------------------
    def on_command(self, u1: float, u2: float, stamp_ns: int, now_ns: int) -> CommandOutcome:
        """A valve command (V) stamped stamp_ns (0: for the current step), arrived at now_ns.

        Lockstep: a command for the current step (stamp >= t_k, or 0) is applied and the plant
        steps once (its sample in the outcome); an older one is ignored and counted. Realtime:
        applied, held until the next one, its latency recorded."""
        with self.lock:
            self.commands_received += 1
            self.last_raw_command = (u1, u2)
            rig = self.rig
            step = rig.k
            past, t_k, sample = 0, 0, None
            if self.config.lockstep:
                t_k = self.stamp(step)
                if stamp_ns != 0 and stamp_ns < t_k:
                    self.past_commands += 1
                    past, ok = self.past_commands, True
                else:
                    ok = rig.set_command(u1, u2)
                    rig.step()
                    sample = self.current = self._sample(self.stamp(rig.k))
            else:
                ok = rig.set_command(u1, u2)
                self.timing.on_command(stamp_ns, now_ns)
            return CommandOutcome(ok, None if past else rig.u, step, past, t_k, sample,
                                  self.commands_received, rig.non_finite_commands,
                                  rig.out_of_range_commands)

    # --- health --------------------------------------------------------------------------------
    def report(self, now: float) -> tuple[int, str, dict]:
        """The rig's /diagnostics: (level, message, values) for the window ending now (s,
        monotonic). ERROR: the sampling failed (fault) or a non-finite sample was suppressed;
        WARN: bad or past commands in the window, or (realtime) the achieved rate off by more
        than RATE_TOLERANCE or late samples; OK otherwise."""
        config = self.config
        window = self.stats.window(now)
        with self.lock:
            rig = self.rig
            bad = rig.bad_commands
            values = {
                'timing': config.timing,
                'rate target (Hz)': config.rate,
                'achieved rate (Hz)': window.achieved_rate,
                'late steps (last window)': window.late_steps,
                'max lateness (ms)': window.max_lateness * 1e3,
                'samples published': self.samples_published,
                'simulated time (s)': rig.t,
                'commands received': self.commands_received,
                'non-finite commands': rig.non_finite_commands,
                'out-of-range commands': rig.out_of_range_commands,
                'past commands ignored': self.past_commands,
                'last command u1 (V)': rig.u[0],
                'last command u2 (V)': rig.u[1],
                'last command received (V)': self.last_raw_command,
                'joint mode': config.joint_mode,
                'plant parameters': config.plant_parameters,
                'scenario': config.scenario_name or 'none',
                'supply_pressure published': self.supply is not None,
                'non-finite samples suppressed': self.nonfinite_samples,
                'last sample counter': rig.k + 1,
            }
            if config.lockstep:
                values['republished samples'] = self.republished
            else:       # since the start or ~/reset_statistics
                values.update({SAMPLES_TAKEN: window.total_samples
                               + window.total_skipped_periods,
                               LATE_SAMPLES: window.total_late_steps
                               + window.total_skipped_periods,
                               MISSED_SAMPLES: window.total_skipped_periods,
                               WORST_STALL_MS: window.max_lateness_total * 1e3})
                values.update(self.timing.histogram.summary())
            new_bad = bad - self._reported['bad']
            new_past = self.past_commands - self._reported['past']
            self._reported = {'bad': bad, 'past': self.past_commands}
            k = rig.k

        if self.fault:
            return ERROR, self.fault, values
        problems = []
        level = OK
        if self.nonfinite_samples:
            level = ERROR
            problems.append(f'{self.nonfinite_samples} non-finite samples suppressed')
        if new_bad:
            level = max(level, WARN)
            problems.append(f'{new_bad} bad command voltages sanitised in the last window')
        if new_past:
            level = max(level, WARN)
            problems.append(f'{new_past} commands from the past ignored in the last window')
        if (not config.lockstep and window.duration > 0.5
                and not abs(window.achieved_rate - config.rate) <= RATE_TOLERANCE * config.rate):
            level = max(level, WARN)
            problems.append(f'achieved rate {window.achieved_rate:.1f} Hz, target '
                            f'{config.rate:g} Hz ({window.late_steps} late steps)')
        if (not config.lockstep and window.samples
                and window.late_steps > LATE_TOLERANCE * window.samples):
            level = max(level, WARN)
            problems.append(f'{window.late_steps} of {window.samples} samples late by more than '
                            f'a period (max {window.max_lateness * 1e3:.2f} ms): not real time, '
                            'the plant went on with the held command')
        if problems:
            message = '; '.join(problems)
        elif config.lockstep:
            message = (f'lockstep: step {k}, t = {self.stamp(k) / 1e9:.3f} s, '
                       f'{window.achieved_rate if window.samples else 0.0:.1f} steps/s')
        else:
            message = f'realtime: {window.achieved_rate:.1f} Hz'
        return level, message, values


class RealtimeSampler:
    """Realtime: when the rig takes its samples and which it publishes, without ROS or threads.

    The plant follows the wall clock: every deadline start + n * period that has passed is a
    sample taken, one model step after the previous one with the command held at that moment,
    whether or not the loop had time for it (a late controller finds the valves holding its last
    command). The samples taken and not yet published wait in a backlog and leave oldest first,
    late, as a DAQ board's samples wait in the serial line for a late driver: the loop sees every
    sample, as it was, after the stall. At most `backlog` + 1 wait (this deadline's and `backlog`
    overdue ones): after a longer stall the oldest are dropped (missed samples: a gap in the
    sample counter; a dropped sample that was never taken is only a model step). Sample n is
    stamped start_ns + n * period (ns, the node clock). Times in s on one monotonic clock."""

    def __init__(self, core: SimCore, period: float, start: float, start_ns: int, backlog: int):
        self.core = core
        self.period, self.start = period, start
        self.period_ns = period * 1e9
        self.start_ns = start_ns
        self.limit = backlog + 1
        self.waiting: deque[tuple[float, SimSample | None]] = deque()  # (deadline s, sample)
        self._n = 0               # the index of the next deadline to take
        self._missed = 0          # dropped since the last sample handed out
        self._dropped_lateness = 0.0   # s, the oldest of those: the stall they were in

    def wait(self, now: float) -> float:
        """s to sleep before the next sample is due (0: one is waiting or due now)."""
        return 0.0 if self.waiting else max(self._deadline(self._n) - now, 0.0)

    def _deadline(self, n: int) -> float:
        """s, deadline n on the monotonic clock."""
        return self.start + n * self.period

    def next(self, now: float) -> tuple[SimSample | None, float, int] | None:
        """The next sample to publish at `now` (None: not finite, suppressed), its lateness (s
        after its deadline, or the lateness of the oldest sample dropped since the last one if
        that is more: the stall) and the samples missed since the last one; None if none is
        due."""
        deadline = self._deadline(self._n)
        due = int((now - deadline) // self.period) + 1 if deadline <= now else 0
        if due:
            taken = min(due, self.limit)
            dropped = max(len(self.waiting) + taken - self.limit, 0)
            if dropped:                                   # the oldest waiting ones
                self._dropped_lateness = max(self._dropped_lateness, now - self.waiting[0][0])
            for _ in range(dropped):
                self.waiting.popleft()
            skipped = due - taken
            if skipped and not dropped:
                self._dropped_lateness = max(self._dropped_lateness, now - deadline)
            self._missed += dropped + skipped
            first = self._n + skipped
            deadlines = [self._deadline(first + i) for i in range(taken)]
            samples = self.core.realtime_samples(
                skipped, [self.start_ns + round((first + i) * self.period_ns)
                          for i in range(taken)])
            self.waiting.extend(zip(deadlines, samples, strict=True))
            self._n += due
        if not self.waiting:
            return None
        deadline, sample = self.waiting.popleft()
        missed, self._missed = self._missed, 0
        lateness, self._dropped_lateness = max(now - deadline, self._dropped_lateness), 0.0
        return sample, lateness, missed
