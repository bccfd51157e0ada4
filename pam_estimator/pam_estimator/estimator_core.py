"""EstimatorCore: what ukf_node does with each message, with no ROS in it.

* a valve command (V) is held as u(k-1) for the next pressure sample (non-finite voltages read as
  0 V, out-of-range ones are clipped: the valves do the same);
* a pressure sample (Pa abs, stamp in ns) advances the filter one step and yields an estimate;
  a sample whose stamp equals the last one is a duplicate (a lockstep simulator re-publishing
  its sample for a late joiner): the filter does not step, the last estimate is given again
  (so a controller that missed it can answer), counted; a stamp older than
  the last one means time went backwards (a bag looping, a simulator restarted): the filter is
  reset to its initial state and covariance, then the sample is processed;
* a sample counter that jumps by n > 1 (samples the rig missed, or lost on the way) makes the
  filter coast through the n - 1 missing periods first (a prediction with the held command, no
  update: PamUkf.coast), so its model stays on the plant's time instead of falling n - 1 steps
  behind; up to MAX_COAST samples (a longer gap is a restart of the stream: one step, as
  without counters), counted;
* a supply pressure reading (Pa abs, stamp in ns; only with use_supply) is held and used as
  P_tank of the steps whose sample stamp is within SUPPLY_STALE of its stamp; a reading that is
  older (or newer by as much: time went backwards), missing or not finite gives the model's
  P_tank (counted, the reason in supply_fallback);
* statistics for the diagnostics: input rate, step time, NIS, covariance trace, rejections.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from pam_model.rest import REST_COMMAND
from pam_model.valve_voltage import sanitise_command

from .pam_ukf import PamUkf, UkfOutput

RATE_WINDOW = 1000          # samples over which the input rate and step times are measured
SUPPLY_STALE = 0.1          # s, a supply reading further from the sample's stamp is not used
MAX_COAST = 100             # missing samples the filter coasts through (0.1 s at 1 kHz)


@dataclass
class CoreEvent:
    """What happened to one pressure sample: 'estimate', 'duplicate' (output: the last estimate,
    again) or 'reset'."""

    kind: str
    output: UkfOutput | None = None
    message: str = ''


class EstimatorCore:
    """Feeds a PamUkf from timestamped messages and keeps the numbers the diagnostics report."""

    def __init__(self, ukf: PamUkf, initial_command=REST_COMMAND, use_supply: bool = False):
        self.ukf = ukf
        self.use_supply = use_supply
        self.supply: tuple[float, int] | None = None    # last reading (Pa abs, stamp ns)
        self.supply_used = 0          # steps with the measured supply pressure
        self.supply_fallbacks = 0     # steps with the model's P_tank although use_supply
        self.supply_fallback = ''     # why the last step fell back ('' if it did not)
        self.initial_command = tuple(float(u) for u in initial_command)
        self.u_prev = np.array(self.initial_command)
        self.last_stamp_ns: int | None = None
        self.last_sample: int | None = None   # the rig's sample counter of the last sample
        self.coasted = 0              # missing periods the filter coasted through
        self.samples = 0
        self.duplicates = 0
        self.time_resets = 0
        self.commands = 0
        self.bad_commands = 0
        self.last_output: UkfOutput | None = None
        self._arrivals = deque(maxlen=RATE_WINDOW)      # monotonic receive times (s)
        self._step_times = deque(maxlen=RATE_WINDOW)    # s
        self.last_command_time: float | None = None

    def on_command(self, u1: float, u2: float) -> bool:
        """Hold a new valve command; returns False if it had to be sanitised."""
        (a, pa), (b, pb) = sanitise_command(u1), sanitise_command(u2)
        self.u_prev = np.array([a, b])
        self.commands += 1
        self.last_command_time = time.monotonic()
        if pa or pb:
            self.bad_commands += 1
            return False
        return True

    def on_supply(self, pressure: float, stamp_ns: int) -> None:
        """Hold a supply pressure reading (Pa abs) stamped stamp_ns."""
        self.supply = (float(pressure), int(stamp_ns))

    def supply_for(self, stamp_ns: int) -> float | None:
        """The supply pressure (Pa abs) for the sample stamped stamp_ns, None for the model's
        P_tank (counted with its reason when use_supply)."""
        self.supply_fallback = ''
        if not self.use_supply:
            return None
        if self.supply is None:
            self.supply_fallback = 'no supply pressure received yet'
        else:
            value, stamp = self.supply
            age = (stamp_ns - stamp) * 1e-9
            if not (math.isfinite(value) and value > 0.0):
                self.supply_fallback = f'supply pressure {value!r} Pa not usable'
            elif abs(age) > SUPPLY_STALE:
                self.supply_fallback = (f'supply pressure {age:.3f} s from the sample '
                                        f'(> {SUPPLY_STALE:g} s)')
            else:
                self.supply_used += 1
                return value
        self.supply_fallbacks += 1
        return None

    def reset(self, x0=None, P0=None) -> None:
        """Restart the filter (from its configured initial state unless given)."""
        self.ukf.reset(x0, P0)
        self.last_stamp_ns = None
        self.last_sample = None
        self.last_output = None

    def on_pressures(self, p1: float, p2: float, stamp_ns: int,
                     sample: int | None = None) -> CoreEvent:
        """One pressure sample (with the rig's sample counter if known): the filter step, or
        why there was none."""
        now = time.monotonic()
        message = ''
        kind = 'estimate'
        if self.last_stamp_ns is not None:
            if stamp_ns == self.last_stamp_ns:
                self.duplicates += 1
                return CoreEvent('duplicate', self.last_output,
                                 'duplicate stamp: last estimate repeated')
            if stamp_ns < self.last_stamp_ns:
                self.time_resets += 1
                back = (self.last_stamp_ns - stamp_ns) * 1e-9
                self.reset()
                kind = 'reset'
                message = (f'time went backwards by {back:.3f} s (bag looping or rig restarted): '
                           'filter reset to its initial state')
        self._arrivals.append(now)
        supply = self.supply_for(stamp_ns)
        missing = (sample - self.last_sample - 1 if sample is not None and kind != 'reset'
                   and self.last_sample is not None else 0)
        start = time.perf_counter()
        if 0 < missing <= MAX_COAST:
            for _ in range(missing):
                self.ukf.coast(self.u_prev, supply)
            self.coasted += missing
        output = self.ukf.step((p1, p2), self.u_prev, supply)
        self._step_times.append(time.perf_counter() - start)
        self.last_stamp_ns = stamp_ns
        self.last_sample = sample
        self.samples += 1
        self.last_output = output
        return CoreEvent(kind, output, message)

    # --- numbers for /diagnostics ------------------------------------------------------------

    def input_rate(self) -> float:
        """Pressure samples per second over the last RATE_WINDOW arrivals (Hz)."""
        if len(self._arrivals) < 2:
            return 0.0
        span = self._arrivals[-1] - self._arrivals[0]
        return (len(self._arrivals) - 1) / span if span > 0 else 0.0

    def largest_input_gap(self) -> float:
        """Longest time between two pressure arrivals over the window (s): late inputs."""
        if len(self._arrivals) < 2:
            return 0.0
        return float(np.max(np.diff(np.fromiter(self._arrivals, dtype=float))))

    def seconds_since_input(self) -> float:
        """Time since the last pressure sample arrived (s); inf before the first."""
        return time.monotonic() - self._arrivals[-1] if self._arrivals else math.inf

    def step_time_stats(self) -> tuple[float, float]:
        """(median, max) of the filter step time over the window (s)."""
        if not self._step_times:
            return 0.0, 0.0
        times = np.fromiter(self._step_times, dtype=float)
        return float(np.median(times)), float(times.max())
