"""Whether a real-time run was real time: the judgement a report makes before printing figures.

A closed-loop run on the 1 kHz rig (sim_node, or driver_node on the real rig) gives figures
(steady-state error, settling, estimation error) that mean something only if the loop ran in
time. On an overloaded machine the rig's sampling thread wakes up late, the controller answers
late, the report loses samples, and the figures describe a slower, degraded loop, not the
controller. judge_run() looks at the rig's own counters (its latest /diagnostics status, counted
since its start or its `~/reset_statistics` call) and at the samples the report received, and
says VALID or INVALID with one reason per broken threshold. No ROS here: the caller passes the
status' key/values (pam_common.diagnostics.status_values) and the two counts.

The thresholds (HealthLimits, SI units: seconds; fractions are plain ratios 0..1). They are set
where a run's figures stop being the loop's, measured on the 2-core development machine with the
composed identified stack on the `realistic` rig (docs/realtime.md, "When a run is real time"):
runs with 1.5-4.6 % late samples, stalls up to 13 ms and a p99 latency up to 4 ms gave the
deterministic batch loop's tracking figures (worst steady-state error 0.27-0.28 % against 0.26 %)
and estimation error (Q 0.36-0.42 %); with two CPU-bound processes beside it (11.5 % late, an
18 ms stall, samples missed) Q doubled (1.00 %). A bare Python loop that only sleeps to a 1 kHz
deadline at SCHED_FIFO priority 80 already has 0.3-0.8 % of its wake-ups more than a period late
on that machine (its hypervisor), so a 1 % limit would judge the machine, not the stack.

- max_late_fraction 0.05: the fraction of the rig's samples taken more than one period after
  their deadline ('late samples' / 'samples taken'). A late sample is taken with the command
  held since the previous one while the plant moved on; sporadic ones (one in twenty at most)
  delay a command by a period or two, a phase lag of under a degree at the PI loop's crossover
  (about 1 Hz); more means the loop is overloaded, not jittered.
- max_missed_fraction 0.001: the fraction of the rig's samples never published ('missed
  samples': after a stall longer than sim_node's max_catch_up the oldest of the samples taken
  meanwhile are dropped and the loop never sees them): each is a hole in the estimator's input.
- max_worst_stall 0.020 s: the longest lateness of the rig's sampling ('worst stall (ms)'). At
  1 kHz a stall of 20 ms is 20 samples held at the old command, a fifth of the valves' own time
  constant and less than half the driver's command watchdog (50 ms, which vents a real rig):
  past that the loop is open for a visible while.
- max_latency_p99 0.005 s: the 99th percentile of the sample -> command latency at the rig (the
  command's arrival minus the stamp of the sample it answers, 'latency p99 (ms)'). Five periods:
  one command in a hundred may come that late (a delay the gains tolerate, see above); above
  it the loop runs with a delay the batch analysis and the gains do not assume.
- max_late_command_fraction 0.05: the fraction of the timed commands that arrived after the rig
  had taken its next sample ('commands after the next sample' / 'commands timed'): each of those
  is one period applied with the previous command.
- max_lost_fraction 0.01: the fraction of the samples the rig sent during the record (from the
  sample counters) that the report did not receive: the report's figures would be computed over
  a thinned record, and lost samples mean the middleware (and so the loop) was starved too.

A key the rig does not publish is not judged, and the notes say so: driver_node publishes the
latency keys only ('commands timed', 'commands after the next sample', 'latency p50/p99/p99.9/
max (ms)'), not the sample-timing ones ('samples taken', 'late samples', 'missed samples',
'worst stall (ms)'): the board samples on its own clock.
No rig status at all (rig None) makes the run INVALID: its real-time health is unknown.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

from .latency import COMMANDS_LATE, COMMANDS_TIMED, LATENCY_MAX_MS, LATENCY_P50_MS, LATENCY_P99_MS

#: the rig's /diagnostics keys judge_run reads
SAMPLES_TAKEN = 'samples taken'
LATE_SAMPLES = 'late samples'
MISSED_SAMPLES = 'missed samples'
WORST_STALL_MS = 'worst stall (ms)'
NO_RIG = 'no /diagnostics from the rig: real-time health unknown'


@dataclass(frozen=True)
class HealthLimits:
    """The thresholds of a valid run (module docstring: why each one)."""

    max_late_fraction: float = 0.05          # late rig samples / samples taken
    max_missed_fraction: float = 0.001       # rig samples never published / samples taken
    max_worst_stall: float = 0.020           # s: 20 periods at 1 kHz
    max_latency_p99: float = 0.005           # s: sample -> command at the rig, 5 periods
    max_late_command_fraction: float = 0.05  # commands after the next sample / commands timed
    max_lost_fraction: float = 0.01          # samples lost at the report / samples sent

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value < 0.0:
                raise ValueError(f'HealthLimits.{f.name} must be a finite number >= 0, '
                                 f'got {value!r}')
            if f.name.endswith('fraction') and value > 1.0:
                raise ValueError(f'HealthLimits.{f.name} is a fraction in 0..1, got {value!r}')


def number(values: Mapping | None, key: str) -> float:
    """values[key] as a float; nan when missing, 'n/a' or not a number."""
    if values is None:
        return math.nan
    value = values.get(key)
    if isinstance(value, bool) or value is None:
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _known(x: float) -> bool:
    return math.isfinite(x)


@dataclass(frozen=True)
class RunHealth:
    """The figures of a run's real-time health and the judgement. Times in s; nan: not known."""

    samples_sent: int             # samples the rig sent during the record (sample counters)
    samples_received: int         # samples the report received
    samples_lost: int
    samples_taken: float          # by the rig, since its start or ~/reset_statistics
    late_samples: float
    missed_samples: float         # late samples never published (the plant stepped on)
    worst_stall: float            # s
    latency_p50: float            # s, sample -> command at the rig
    latency_p99: float            # s
    latency_max: float            # s
    commands_timed: float
    late_commands: float          # commands that arrived after the rig's next sample
    valid: bool
    reasons: tuple[str, ...] = ()  # one per broken threshold, with the figure and the limit
    notes: tuple[str, ...] = ()    # what could not be judged (not a reason to fail)
    incomplete: bool = False      # the report lost more samples than allowed (one of reasons)

    @property
    def headline(self) -> str:
        """What an INVALID run was, for the first line of a report: the loop was not real time
        (a reason of the rig's), or only the record is incomplete (samples lost at the report:
        a lockstep loop that ran whole, a report starved of CPU)."""
        if self.valid:
            return 'valid'
        return ('the record is incomplete' if self.incomplete and len(self.reasons) == 1
                else 'the loop was not real time')

    def as_dict(self) -> dict:
        """Plain data for strict JSON: nan -> None, counts as ints, tuples as lists."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, tuple):
                value = list(value)
            elif isinstance(value, float):
                value = None if not math.isfinite(value) else (
                    int(value) if f.name in _COUNTS and value.is_integer() else value)
            out[f.name] = value
        return out

    def lines(self) -> list[str]:
        """Human-readable: the headline (figures and VALID / INVALID: reasons), then the notes."""
        parts = [f'real-time health: {self.samples_received} of {self.samples_sent} samples '
                 f'received ({self.samples_lost} lost)']
        if _known(self.late_samples) or _known(self.worst_stall):
            missed = (f' ({_count(self.missed_samples)} missed)'
                      if _known(self.missed_samples) else '')
            parts.append(f'rig: {_count(self.late_samples)} late samples{missed} of '
                         f'{_count(self.samples_taken)}, worst stall {_ms(self.worst_stall)} ms')
        headline = ', '.join(parts)
        if _known(self.latency_p99):
            late = (100.0 * self.late_commands / self.commands_timed
                    if _known(self.late_commands) and self.commands_timed > 0 else math.nan)
            headline += (f'; sample -> command at the rig p50 {_ms(self.latency_p50)} / p99 '
                         f'{_ms(self.latency_p99)} / max {_ms(self.latency_max)} ms, '
                         f'{"n/a" if not _known(late) else f"{late:.1f}"} % after the next '
                         'sample')
        headline += ': VALID' if self.valid else ': INVALID: ' + '; '.join(self.reasons)
        return [headline] + [f'  (not judged: {note})' for note in self.notes]


_COUNTS = ('samples_taken', 'late_samples', 'missed_samples', 'commands_timed', 'late_commands')


def _ms(seconds: float) -> str:
    if not _known(seconds):
        return 'n/a'
    ms = seconds * 1e3
    return f'{ms:.2f}' if ms < 1.0 else f'{ms:.1f}'


def _count(x: float) -> str:
    return 'n/a' if not _known(x) else f'{x:.0f}'


def counter_gaps(counters) -> list[tuple[int, int]]:
    """The gaps in a set of the rig's sample counters: (the last counter before the gap, the
    number of counters missing), in counter order. Where a report lost its samples says why: one
    long gap is a stall of the receiving process (or of its machine) longer than its queues;
    many short ones, a receiver slower than the stream all along."""
    ordered = sorted({int(k) for k in counters})
    return [(a, b - a - 1) for a, b in itertools.pairwise(ordered) if b - a > 1]


def judge_run(rig: Mapping | None, received: int, expected: int,
              limits: HealthLimits = HealthLimits()) -> RunHealth:
    """The health of a run: `rig` the key/values of the rig node's latest /diagnostics status
    (strings or numbers; None: no status arrived), `expected` the samples the rig sent during
    the record (from the sample counters), `received` those the report got."""
    received, expected = int(received), int(expected)
    lost = max(expected - received, 0)
    taken, late = number(rig, SAMPLES_TAKEN), number(rig, LATE_SAMPLES)
    missed = number(rig, MISSED_SAMPLES)
    stall = number(rig, WORST_STALL_MS) * 1e-3
    p50, p99 = number(rig, LATENCY_P50_MS) * 1e-3, number(rig, LATENCY_P99_MS) * 1e-3
    worst_latency = number(rig, LATENCY_MAX_MS) * 1e-3
    timed, late_commands = number(rig, COMMANDS_TIMED), number(rig, COMMANDS_LATE)
    reasons, notes = [], []
    if rig is None:
        reasons.append(NO_RIG)
    incomplete = expected > 0 and lost / expected > limits.max_lost_fraction
    if expected > 0:
        if incomplete:
            reasons.append(f'{lost} of {expected} samples lost at the report '
                           f'({100.0 * lost / expected:.2f} % > '
                           f'{100.0 * limits.max_lost_fraction:g} %)')
    else:       # no estimate: the loop never ran, whatever the rig says
        reasons.append('no estimate received: the loop did not run')
    if rig is not None:
        fraction_checks = (
            (late, taken, limits.max_late_fraction, 'rig samples late',
             "the rig publishes no 'samples taken' / 'late samples': late samples"),
            (missed, taken, limits.max_missed_fraction, 'rig samples missed',
             "the rig publishes no 'missed samples': missed samples"),
            (late_commands, timed, limits.max_late_command_fraction,
             'commands after the next sample',
             'no command timed at the rig: commands after the next sample'))
        for part, whole, limit, what, missing in fraction_checks:
            if _known(whole) and whole > 0 and _known(part):
                if part / whole > limit:
                    reasons.append(f'{part:.0f} of {whole:.0f} {what} ({100.0 * part / whole:.2f}'
                                   f' % > {100.0 * limit:g} %)')
            else:
                notes.append(missing)
        time_checks = ((stall, limits.max_worst_stall, 'worst stall',
                        "the rig publishes no 'worst stall (ms)': worst stall"),
                       (p99, limits.max_latency_p99, 'sample -> command latency p99',
                        'no command latency at the rig: sample -> command latency'))
        for value, limit, what, missing in time_checks:
            if not _known(value):
                notes.append(missing)
            elif value > limit:
                reasons.append(f'{what} {_ms(value)} ms > {limit * 1e3:g} ms')
    return RunHealth(samples_sent=expected, samples_received=received, samples_lost=lost,
                     samples_taken=taken, late_samples=late, missed_samples=missed,
                     worst_stall=stall,
                     latency_p50=p50, latency_p99=p99, latency_max=worst_latency,
                     commands_timed=timed, late_commands=late_commands,
                     valid=not reasons, reasons=tuple(reasons), notes=tuple(notes),
                     incomplete=incomplete)
