"""Sample -> command latency at the rig, with no ROS in it.

The rig (sim_node, driver_node) stamps each pressure sample; pi_node stamps its valve command with
the stamp of the sample it answers. When the command reaches the rig, its latency is the rig's
clock now minus that stamp (one clock: no synchronisation involved), and the command is *late*
when the rig has already taken a newer sample than the one it answers: the plant then ran one
period or more on the previous command.

LatencyHistogram keeps every latency in logarithmic bins (2 % wide, 1 us to 100 s), so recording
costs one logarithm and one increment, memory is fixed (a thousand counters), and any percentile
is read back to within 2 %. reset() starts a new measurement (a benchmark resets after the
start-up transient).
"""

from __future__ import annotations

import math
import threading

LOWEST = 1e-6           # s, the first bin's lower edge; smaller latencies count in bin 0
RATIO = 1.02            # width of a bin: its upper edge / its lower edge
BINS = math.ceil(math.log(1e2 / LOWEST) / math.log(RATIO)) + 1   # up to 100 s; the last is open


#: the /diagnostics keys of LatencyHistogram.summary() (read by pam_common.run_health)
COMMANDS_TIMED = 'commands timed'
COMMANDS_LATE = 'commands after the next sample'
LATENCY_P50_MS = 'latency p50 (ms)'
LATENCY_P99_MS = 'latency p99 (ms)'
LATENCY_P999_MS = 'latency p99.9 (ms)'
LATENCY_MAX_MS = 'latency max (ms)'

class LatencyHistogram:
    """Latencies (s) in logarithmic bins; thread-safe. percentile() returns a bin's upper edge
    (at most 2 % above the true value), except that it never exceeds the largest latency seen."""

    def __init__(self):
        self._lock = threading.Lock()
        self._scale = 1.0 / math.log(RATIO)
        self.reset()

    def reset(self) -> None:
        with self._lock:
            self._counts = [0] * BINS
            self.count = 0
            self.late = 0
            self.max = 0.0

    def record(self, latency: float, late: bool = False) -> None:
        """One latency in s (non-finite values are ignored); `late`: it came after the next
        sample."""
        if not math.isfinite(latency):
            return
        k = 0 if latency <= LOWEST else min(int(math.log(latency / LOWEST) * self._scale) + 1,
                                           BINS - 1)
        with self._lock:
            self._counts[k] += 1
            self.count += 1
            if late:
                self.late += 1
            if latency > self.max:
                self.max = latency

    def percentile(self, q: float) -> float:
        """The q-th percentile (0 < q <= 100) in s; nan when nothing was recorded."""
        with self._lock:
            if not self.count:
                return math.nan
            rank = math.ceil(q / 100.0 * self.count)
            seen = 0
            for k, n in enumerate(self._counts):
                seen += n
                if seen >= rank:    # the last bin is open: its latencies are up to max
                    return self.max if k == BINS - 1 else min(LOWEST * RATIO ** k, self.max)
            return self.max

    def summary(self) -> dict[str, float | int]:
        """The figures a report prints: count, late, p50/p99/p99.9/max in ms."""
        return {COMMANDS_TIMED: self.count, COMMANDS_LATE: self.late,
                LATENCY_P50_MS: self.percentile(50.0) * 1e3,
                LATENCY_P99_MS: self.percentile(99.0) * 1e3,
                LATENCY_P999_MS: self.percentile(99.9) * 1e3,
                LATENCY_MAX_MS: self.max * 1e3 if self.count else math.nan}


class CommandTiming:
    """The rig's side of the latency (sim_node, driver_node): on_sample(stamp) for every sample
    taken, on_command(stamp, now) for every valve command received, both in ns of one clock;
    `histogram` holds the figures. A command without a stamp (0) is not timed."""

    def __init__(self):
        self.histogram = LatencyHistogram()
        self._last_sample_ns = 0

    def on_sample(self, stamp_ns: int) -> None:
        self._last_sample_ns = stamp_ns

    def on_command(self, stamp_ns: int, now_ns: int) -> None:
        if stamp_ns:
            self.histogram.record((now_ns - stamp_ns) * 1e-9,
                                  late=stamp_ns < self._last_sample_ns)

    def reset_callback(self, logger):
        """The callback of a node's `~/reset_statistics` service (std_srvs/Trigger): starts the
        figures afresh, says so in the response and at INFO."""
        def on_reset(request, response):
            self.histogram.reset()
            response.success = True
            response.message = 'sample -> command latency statistics reset'
            logger.info(response.message)
            return response
        return on_reset
