"""The machine's own timer floor: how late a loop that does nothing but sleep to 1 kHz deadlines
wakes up, measured here and now, as the baseline a real-time run's timing is read against.

A run's late samples are the stack's and the machine's together: on the 2-core development VM a
bare Python loop at SCHED_FIFO priority 80 already woke more than one period late for 0.3-0.8 %
of its deadlines (its hypervisor), with a worst wake-up of 3-4 ms. Measuring that floor in the
same run, at the same priority, says how much of a run's lateness the stack added. No ROS here.
"""

from __future__ import annotations

import threading
import time
from dataclasses import asdict, dataclass

from .realtime import set_sched_fifo
from .timing import DeadlineSchedule

DEFAULT_RATE = 1000.0      # Hz, the rig's
DEFAULT_DURATION = 3.0     # s


@dataclass(frozen=True)
class TimerFloor:
    """A bare sleep loop's wake-ups: lateness after each deadline (s), as the rig counts it."""

    rate: float              # Hz
    deadlines: int
    late: int                # wake-ups more than one period after their deadline
    p99: float               # s, 99th percentile of the lateness
    worst: float             # s
    scheduling: str          # what the loop's thread ran with ('SCHED_FIFO 80' or why not)

    @property
    def late_fraction(self) -> float:
        return self.late / self.deadlines if self.deadlines else 0.0

    def line(self) -> str:
        return (f'a bare {self.rate:g} Hz sleep loop ({self.scheduling}, {self.deadlines} '
                f'deadlines): {100.0 * self.late_fraction:.2f} % of its wake-ups more than a '
                f'period late, lateness p99 {self.p99 * 1e3:.2f} ms, worst '
                f'{self.worst * 1e3:.1f} ms')

    def as_dict(self) -> dict:
        return {**asdict(self), 'late_fraction': self.late_fraction}


def measure_timer_floor(rate: float = DEFAULT_RATE, duration: float = DEFAULT_DURATION,
                        priority: int | None = None) -> TimerFloor:
    """Sleep to `duration` s of deadlines at `rate` Hz in a thread of its own (SCHED_FIFO
    `priority` if given and granted) and count how late each wake-up was; a deadline already
    past is taken at once (as sim_node takes every passed deadline), so a stall counts every
    period it covered."""
    if not (rate > 0.0 and duration > 0.0):
        raise ValueError(f'rate and duration must be > 0, got {rate!r} Hz, {duration!r} s')
    period, count = 1.0 / rate, max(1, round(duration * rate))
    result: dict = {}

    def loop() -> None:
        scheduling = 'SCHED_OTHER'
        if priority is not None:
            grant = set_sched_fifo(priority, 'timer_floor')
            scheduling = f'SCHED_FIFO {priority}' if grant.granted else \
                f'SCHED_OTHER: SCHED_FIFO {priority} refused'
        lateness = []
        schedule = DeadlineSchedule(period, time.monotonic() + period, max_catch_up=None)
        for _ in range(count):
            delay = schedule.deadline - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            now = time.monotonic()
            lateness.append(max(schedule.lateness(now), 0.0))
            schedule.advance(now)
        lateness.sort()
        result['floor'] = TimerFloor(rate=rate, deadlines=count,
                                     late=sum(1 for x in lateness if x > period),
                                     p99=lateness[min(count - 1, int(0.99 * count))],
                                     worst=lateness[-1], scheduling=scheduling)

    thread = threading.Thread(target=loop, name='timer_floor', daemon=True)
    thread.start()
    thread.join()
    return result['floor']
