"""ThrottledLog: the first occurrence at once, then one line per period saying how many were
left out; every occurrence counted."""

import logging

import pytest

from pam_common.throttled_log import SUPPRESSED_KEY, ThrottledLog, ThrottledLogs


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


@pytest.fixture
def lines():
    class Logger:
        def __init__(self):
            self.lines = []

        def warning(self, text):
            self.lines.append(('warning', text))

        def error(self, text):
            self.lines.append(('error', text))
    return Logger()


def test_a_flood_gives_one_line_per_period(lines):
    clock = Clock()
    log = ThrottledLog(lines, period=1.0, clock=clock)
    for i in range(100):                     # 100 in 7 ms
        clock.t = i * 7e-5
        log(f'event {i}')
    assert lines.lines == [('warning', 'event 0')]
    assert (log.count, log.suppressed) == (100, 99)
    clock.t = 1.5
    assert log('event 100')
    assert lines.lines[-1] == ('warning', 'event 100 (99 more like this in the last 1.5 s, '
                                          'not logged)')
    clock.t = 1.6
    assert not log('event 101')
    clock.t = 3.0
    assert log('event 102')
    assert lines.lines[-1][1].startswith('event 102 (1 more like this')
    assert len(lines.lines) == 3


def test_a_nodes_logs_and_their_report(lines):
    logs = ThrottledLogs(lines, period=60.0)
    a, b = logs.new('error'), logs.new()
    for _ in range(3):
        a('a')
        b('b')
    assert lines.lines == [('error', 'a'), ('warning', 'b')]
    assert logs.report() == ('OK', '', {SUPPRESSED_KEY: 4})


def test_works_with_a_standard_logger(caplog):
    log = ThrottledLog(logging.getLogger('throttled'), period=60.0)
    with caplog.at_level(logging.WARNING):
        for _ in range(10):
            log('flood')
    assert [r.getMessage() for r in caplog.records] == ['flood']


def test_bad_period():
    with pytest.raises(ValueError, match='period'):
        ThrottledLog(logging.getLogger('x'), period=0.0)


def test_two_levels_on_one_rclpy_logger():
    """A node's 'error' and 'warning' logs share its rclpy logger: rclpy refused the second
    ('Logger severity cannot be changed between calls') while both were logged from one line."""
    from rclpy.logging import get_logger
    logs = ThrottledLogs(get_logger('throttled_levels'), period=60.0)
    a, b, c = logs.new('error'), logs.new(), logs.new('debug')
    assert a('a') and b('b') and c('c')
    assert logs.report() == ('OK', '', {SUPPRESSED_KEY: 0})


def test_unknown_level():
    with pytest.raises(ValueError, match='level'):
        ThrottledLog(logging.getLogger('x'), level='loud')
