"""ThrottledLog: one kind of log line on a fast (1 kHz) path, throttled and counted.

    bad_command = ThrottledLog(node.get_logger(), period=1.0)
    ...
    bad_command(f'valve command {u} V out of range')     # in the 1 kHz callback

The first occurrence is logged at once; later ones at most once per `period` seconds (monotonic
clock), each logged line saying how many were left out since the previous one:
'... (37 more like this in the last 1.0 s, not logged)'. `count` (all occurrences) and
`suppressed` (those not logged) are for /diagnostics: a node makes its throttled logs from one
ThrottledLogs, whose report() (a check for DiagnosticsPublisher.add_check) sums them.
Thread-safe (a sampling thread and the executor may both log). No ROS in here: the logger is
anything with debug/info/warning/error methods (rclpy's RcutilsLogger, logging.Logger). Each
level is logged from a line of its own (_emit): rclpy refuses two severities from one line of
code ("Logger severity cannot be changed between calls"), so a node's 'error' and 'warning'
ThrottledLogs on one rclpy logger would otherwise fail at the second.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

#: The /diagnostics key of suppressed_total().
SUPPRESSED_KEY = 'log lines suppressed (throttled)'
LEVELS = ('debug', 'info', 'warning', 'error')


def _emit(logger, level: str, text: str) -> None:
    """One call site per severity (see the module docstring)."""
    if level == 'debug':
        logger.debug(text)
    elif level == 'info':
        logger.info(text)
    elif level == 'warning':
        logger.warning(text)
    else:
        logger.error(text)


class ThrottledLog:
    """Logs the first occurrence, then at most one line per period with the count left out."""

    def __init__(self, logger, period: float = 1.0, level: str = 'warning',
                 clock: Callable[[], float] = time.monotonic):
        if not period > 0.0:
            raise ValueError(f'throttle period must be > 0 s, got {period!r}')
        if level not in LEVELS:
            raise ValueError(f'level must be one of {LEVELS}, got {level!r}')
        self._logger, self._level = logger, level
        self.period = period
        self._clock = clock
        self._lock = threading.Lock()
        self._last: float | None = None     # clock time of the last line logged
        self._left_out = 0                  # occurrences not logged since that line
        self.count = 0
        self.suppressed = 0

    def __call__(self, text: str) -> bool:
        """One occurrence; True if it was logged."""
        with self._lock:
            now = self._clock()
            self.count += 1
            if self._last is not None and now - self._last < self.period:
                self._left_out += 1
                self.suppressed += 1
                return False
            if self._left_out:
                text += (f' ({self._left_out} more like this in the last '
                         f'{now - self._last:.1f} s, not logged)')
            self._last, self._left_out = now, 0
        _emit(self._logger, self._level, text)
        return True


class ThrottledLogs:
    """A node's throttled logs: new() makes one; report() gives the lines they left out."""

    def __init__(self, logger, period: float = 1.0):
        self._logger = logger
        self.period = period
        self.logs: list[ThrottledLog] = []

    def new(self, level: str = 'warning') -> ThrottledLog:
        log = ThrottledLog(self._logger, self.period, level)
        self.logs.append(log)
        return log

    @property
    def suppressed(self) -> int:
        return sum(log.suppressed for log in self.logs)

    def report(self) -> tuple:
        """(level, problem, values) for DiagnosticsPublisher.add_check: never a problem."""
        return 'OK', '', {SUPPRESSED_KEY: self.suppressed}
