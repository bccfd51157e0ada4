"""Step-response metrics of a tracking run (controller issue, section 5), no ROS.

For each hold of a piecewise-constant reference: the steady-state error |reference - y| averaged
over the last second of the hold, as a percentage of the reference range `span` (40 deg = 0.698
rad for angle, 4 N m for torque, as in the paper); the settling time (after the step, the time
from which |reference - y| stays within SETTLING_BAND of the span until the hold ends); the
overshoot past the new reference in the step's direction (% of the step); and the peak-to-peak of
y over the last second (% of the span: a sustained oscillation shows there).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

SETTLING_BAND = 0.05        # fraction of the span (2 deg, 0.2 N m)
LAST_SECOND = 1.0           # s

#: Reference ranges of the paper's step experiments.
ANGLE_SPAN = np.radians(40.0)   # rad
TORQUE_SPAN = 4.0               # N m


class StepStats(NamedTuple):
    t_start: float           # s
    reference: float         # rad or N m
    steady_error: float      # % of span
    settling_time: float     # s (inf if it never settles)
    overshoot: float         # % of the step size (0 for the first hold)
    ripple: float            # % of span, peak-to-peak over the last second


class StepReport(NamedTuple):
    steps: list

    @property
    def worst_error(self) -> float:
        return max(s.steady_error for s in self.steps)

    @property
    def worst_settling(self) -> float:
        return max(s.settling_time for s in self.steps)

    @property
    def worst_overshoot(self) -> float:
        return max(s.overshoot for s in self.steps)

    @property
    def worst_ripple(self) -> float:
        return max(s.ripple for s in self.steps)

    def lines(self, unit_scale: float = 1.0, unit: str = '') -> list[str]:
        rows = [f'{"t (s)":>7} {"reference":>11} {"ss error":>9} {"settling":>9} '
                f'{"overshoot":>10} {"ripple":>7}']
        for s in self.steps:
            rows.append(f'{s.t_start:7.1f} {s.reference * unit_scale:9.2f}{unit:>2} '
                        f'{s.steady_error:8.2f}% {s.settling_time:8.2f}s {s.overshoot:9.1f}% '
                        f'{s.ripple:6.2f}%')
        rows.append(f'worst: steady-state error {self.worst_error:.2f} % of range, settling '
                    f'{self.worst_settling:.2f} s, overshoot {self.worst_overshoot:.1f} %, '
                    f'ripple {self.worst_ripple:.2f} %')
        return rows


def step_report(t, reference, y, span: float, hold_min: float = 2.0) -> StepReport:
    """Metrics of every hold of the reference at least hold_min s long (others are skipped).

    Durations come from the time stamps `t` (s), not from sample counts: a run with samples
    missing or taken in a burst (a real-time loop catching up, a recorder starved for a moment)
    measures its holds, settling times and last seconds in time. A hold lasts from its first
    sample to the next hold's first sample (the last one: its last sample plus one median
    sample period)."""
    t, reference, y = (np.asarray(a, dtype=float) for a in (t, reference, y))
    edges = np.flatnonzero(np.diff(reference) != 0.0) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [len(t)]])
    h = float(np.median(np.diff(t))) if len(t) > 1 else 1e-3
    steps = []
    previous = None
    for a, b in zip(starts, ends, strict=True):
        t_end = t[b] if b < len(t) else t[-1] + h
        if t_end - t[a] < hold_min:
            previous = reference[a]
            continue
        r = reference[a]
        err = np.abs(r - y[a:b])
        last = slice(max(a, int(np.searchsorted(t, t_end - LAST_SECOND))), b)
        outside = np.flatnonzero(err > SETTLING_BAND * span)
        settling = 0.0 if len(outside) == 0 else (
            np.inf if outside[-1] == b - a - 1 else float(t[a + outside[-1] + 1] - t[a]))
        overshoot = 0.0
        if previous is not None and r != previous:
            direction = np.sign(r - previous)
            overshoot = max(0.0, float(np.max(direction * (y[a:b] - r)))) / abs(r - previous)
        steady = 100.0 * float(np.mean(np.abs(r - y[last]))) / span
        ripple = 100.0 * float(np.ptp(y[last])) / span
        steps.append(StepStats(t[a], r, steady, settling, 100.0 * overshoot, ripple))
        previous = r
    return StepReport(steps)
