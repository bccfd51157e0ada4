"""Unit tests of pam_common.timing (no ROS)."""

import math

import pytest

from pam_common.timing import DeadlineSchedule, RateStatistics

P = 1e-3


def test_on_time_deadlines_do_not_drift():
    schedule = DeadlineSchedule(P, 100.0)
    for _ in range(100000):
        assert schedule.advance(schedule.deadline + 50e-6) == 0   # 50 us late each time
    assert schedule.deadline == pytest.approx(100.0 + 100000 * P, abs=1e-9)


def test_small_lateness_keeps_phase():
    schedule = DeadlineSchedule(P, 0.0)
    assert schedule.advance(0.9 * P) == 0          # late by less than one period
    assert schedule.deadline == pytest.approx(P)    # next one is still due (catch up)


def test_small_backlog_is_caught_up():
    schedule = DeadlineSchedule(P, 10.0, max_catch_up=5)
    now = 10.0 + 3.4 * P                            # woke 3.4 periods late: 3 more are due
    assert schedule.advance(now) == 0
    served = 1
    while schedule.deadline <= now:                 # the loop takes them back to back
        assert schedule.advance(now) == 0
        served += 1
    assert served == 4                              # deadlines 0, 1, 2, 3 all served
    assert schedule.deadline == pytest.approx(10.0 + 4 * P)


def test_long_stall_skips_ahead_keeping_phase():
    schedule = DeadlineSchedule(P, 10.0, max_catch_up=5)
    now = 10.0 + 12.4 * P                           # 12 overdue > 5: skip them
    assert schedule.advance(now) == 12
    assert schedule.deadline > now
    assert schedule.deadline == pytest.approx(10.0 + 13 * P)
    assert schedule.advance(schedule.deadline) == 0


def test_zero_catch_up_always_skips():
    schedule = DeadlineSchedule(P, 0.0, max_catch_up=0)
    assert schedule.advance(1.5 * P) == 1
    assert schedule.deadline == pytest.approx(2 * P)
    assert schedule.advance(2 * P + 0.5 * P) == 0  # less than a period late: no skip
    assert schedule.deadline == pytest.approx(3 * P)


def test_never_skip_catches_up_every_overdue_period():
    """The simulated rig's policy (max_catch_up=None): a stall of 500 periods is replayed, the
    plant never pauses."""
    schedule = DeadlineSchedule(P, 10.0, max_catch_up=None)
    now = 10.0 + 500.4 * P
    served = 0
    while schedule.deadline <= now:
        assert schedule.advance(now) == 0
        served += 1
    assert served == 501
    assert schedule.deadline == pytest.approx(10.0 + 501 * P)


def test_totals_reset_keeps_the_window():
    stats = RateStatistics(P, 0.0)
    stats.record(5 * P)
    stats.record(0.0)
    stats.reset_totals()
    stats.record(2 * P)
    report = stats.window(1.0)
    assert (report.samples, report.late_steps) == (3, 2)
    assert (report.total_samples, report.total_late_steps) == (1, 1)
    assert report.max_lateness_total == pytest.approx(2 * P)
    assert report.max_lateness == pytest.approx(5 * P)


def test_overdue_count():
    schedule = DeadlineSchedule(P, 0.0)
    assert schedule.overdue(-1.0) == 0
    assert schedule.overdue(0.5 * P) == 0
    assert schedule.overdue(2.5 * P) == 2


def test_schedule_rejects_bad_period():
    for period in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError):
            DeadlineSchedule(period, 0.0)
    for bad in (-1, 1.5, '3'):
        with pytest.raises(ValueError):
            DeadlineSchedule(P, 0.0, max_catch_up=bad)


def test_statistics_window_rate_and_lateness():
    stats = RateStatistics(P, start=0.0)
    for _ in range(995):
        assert stats.record(0.0001) is False
    assert stats.record(2.5 * P, skipped=2) is True
    report = stats.window(now=1.0)
    assert report.samples == 996
    assert report.achieved_rate == pytest.approx(996.0)
    assert report.late_steps == 1
    assert report.skipped_periods == 2
    assert report.max_lateness == pytest.approx(2.5 * P)
    # a new window starts; totals go on
    stats.record(0.0002)
    second = stats.window(now=1.5)
    assert second.samples == 1
    assert second.achieved_rate == pytest.approx(2.0)
    assert second.late_steps == 0
    assert second.max_lateness == pytest.approx(0.0002)
    assert second.total_samples == 997
    assert second.total_late_steps == 1
    assert second.total_skipped_periods == 2
    assert second.max_lateness_total == pytest.approx(2.5 * P)


def test_statistics_empty_window_and_early_samples():
    stats = RateStatistics(P, start=5.0)
    report = stats.window(now=6.0)
    assert report.samples == 0 and math.isnan(report.achieved_rate)
    stats.record(-0.001)                            # early: counts as zero lateness
    assert stats.window(now=7.0, reset=False).max_lateness == 0.0
    stats.restart(8.0)
    assert stats.window(now=9.0).achieved_rate == pytest.approx(1.0)
