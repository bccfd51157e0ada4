"""Wall-clock pacing of a fixed-rate loop and its statistics, with no ROS in them.

DeadlineSchedule keeps absolute deadlines start + n * period, so sleeping to each deadline does not
accumulate drift. A sample taken more than one period after its deadline is a *late step*.

Policy when deadlines have been missed (the loop woke up late, e.g. on a loaded machine): the
overdue samples are CAUGHT UP, taken back to back without sleeping. With `max_catch_up=None`
(the simulated rig, sim_node and pam-emulator: a plant never pauses) every overdue deadline is
caught up, however long the stall: the plant's time stays on the wall clock, the command of a
late controller is simply held over the stall (zero-order hold, as real valves hold it), and
the stall itself is counted and reported as what it is, a loop that was not real time. With an
integer `max_catch_up`, a longer backlog is not replayed: the schedule SKIPS AHEAD to the next
future deadline (keeping the phase) and counts the skipped periods; max_catch_up = 0 always
skips ahead. Every sample is exactly one model step after the previous one either way.

RateStatistics collects, per reporting window and since the start (or reset_totals()), the
number of samples, late steps, skipped periods and the maximum lateness (the worst stall), and
computes the achieved rate over the window.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass


class DeadlineSchedule:
    """Absolute deadlines of a loop with period `period` (s), the first one at `first` (s).

    Times are plain floats from one monotonic clock (e.g. time.monotonic()). Up to
    `max_catch_up` overdue periods are caught up; beyond that the schedule skips ahead; None:
    every overdue period is caught up (never skip).
    """

    def __init__(self, period: float, first: float, max_catch_up: int | None = 10):
        if not (math.isfinite(period) and period > 0.0):
            raise ValueError(f'period must be > 0 s, got {period!r}')
        if max_catch_up is not None and not (isinstance(max_catch_up, int)
                                             and max_catch_up >= 0):
            raise ValueError(f'max_catch_up must be None or an integer >= 0, got '
                             f'{max_catch_up!r}')
        self.period = float(period)
        self.max_catch_up = max_catch_up
        self._first = float(first)
        self._n = 0  # index of the current deadline: deadline = first + n * period

    @property
    def deadline(self) -> float:
        """The current deadline (s)."""
        return self._first + self._n * self.period

    def lateness(self, now: float) -> float:
        """How late `now` is for the current deadline (s; negative if early)."""
        return now - self.deadline

    def overdue(self, now: float) -> int:
        """How many deadlines after the current one have already passed at `now`."""
        return max(int((now - self.deadline) // self.period), 0)

    def advance(self, now: float) -> int:
        """Move to the next deadline after a sample taken at `now` for the current one.

        Returns the number of periods skipped: 0 while the backlog is at most max_catch_up
        periods (the next deadline may then already be due: catch up), else all overdue ones
        (the next deadline is then in the future).
        """
        overdue = self.overdue(now)
        if self.max_catch_up is not None and overdue > self.max_catch_up:
            self._n += overdue + 1
            while self.deadline <= now:  # floating-point edge: never land on a past deadline
                self._n += 1
                overdue += 1
            return overdue
        self._n += 1
        return 0


@dataclass(frozen=True)
class WindowReport:
    """Statistics of one reporting window (and totals since start)."""

    duration: float            # s, wall time covered by the window
    samples: int               # samples taken in the window
    achieved_rate: float       # Hz, samples / duration (nan for an empty window)
    late_steps: int            # steps in the window whose deadline was missed by > 1 period
    skipped_periods: int       # periods skipped in the window
    max_lateness: float        # s, largest lateness in the window (0 if none)
    total_samples: int
    total_late_steps: int
    total_skipped_periods: int
    max_lateness_total: float  # s, largest lateness since start


class RateStatistics:
    """Thread-safe counters of a paced loop: record() per sample, window() per report."""

    def __init__(self, period: float, start: float):
        self.period = float(period)
        self._lock = threading.Lock()
        self._window_start = float(start)
        self._samples = 0
        self._late = 0
        self._skipped = 0
        self._max_lateness = 0.0
        self._total_samples = 0
        self._total_late = 0
        self._total_skipped = 0
        self._max_lateness_total = 0.0

    def restart(self, start: float) -> None:
        """Start the window afresh at `start` (e.g. when the loop really starts); keeps totals."""
        with self._lock:
            self._window_start = float(start)

    def reset_totals(self) -> None:
        """Start the totals afresh (a node's ~/reset_statistics); the window goes on."""
        with self._lock:
            self._total_samples = 0
            self._total_late = 0
            self._total_skipped = 0
            self._max_lateness_total = 0.0

    def record(self, lateness: float, skipped: int = 0) -> bool:
        """One sample taken `lateness` s after its deadline; returns True if it was a late step."""
        late = lateness > self.period
        lateness = max(lateness, 0.0)
        with self._lock:
            self._samples += 1
            self._total_samples += 1
            self._skipped += skipped
            self._total_skipped += skipped
            if late:
                self._late += 1
                self._total_late += 1
            if lateness > self._max_lateness:
                self._max_lateness = lateness
            if lateness > self._max_lateness_total:
                self._max_lateness_total = lateness
        return late

    def window(self, now: float, reset: bool = True) -> WindowReport:
        """The statistics since the window started; starts a new window at `now` if reset."""
        with self._lock:
            duration = now - self._window_start
            rate = self._samples / duration if duration > 0.0 and self._samples else math.nan
            report = WindowReport(duration=duration, samples=self._samples, achieved_rate=rate,
                                  late_steps=self._late, skipped_periods=self._skipped,
                                  max_lateness=self._max_lateness,
                                  total_samples=self._total_samples,
                                  total_late_steps=self._total_late,
                                  total_skipped_periods=self._total_skipped,
                                  max_lateness_total=self._max_lateness_total)
            if reset:
                self._window_start = now
                self._samples = 0
                self._late = 0
                self._skipped = 0
                self._max_lateness = 0.0
        return report
