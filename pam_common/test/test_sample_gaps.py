"""SampleGaps: lost, repeated, late and restarted samples counted from the rig's sample counter;
the WARN of the last diagnostics period."""

import pytest

from pam_common.sample_gaps import RESTART_DISTANCE, SampleGaps, loss_summary


def fed(counters):
    gaps = SampleGaps()
    for c in counters:
        gaps.update(c)
    return gaps


def test_in_order_loses_nothing():
    gaps = fed(range(5, 1005))
    assert (gaps.lost, gaps.gaps, gaps.repeats, gaps.late, gaps.restarts) == (0, 0, 0, 0, 0)
    assert gaps.received == 1000


def test_gaps_count_the_missing_samples():
    gaps = SampleGaps()
    assert [gaps.update(c) for c in (1, 2, 5, 6, 10)] == [0, 0, 2, 0, 3]
    assert (gaps.lost, gaps.gaps) == (5, 2)


def test_a_burst_through_a_keep_last_queue():
    """What a subscriber whose queue overflowed receives: the first ones, then every 3rd."""
    received = list(range(1, 101)) + list(range(104, 20001, 3))
    assert received[-1] == 20000
    gaps = fed(received)
    assert gaps.lost == 20000 - len(received)
    assert gaps.lost + gaps.received == received[-1]


def test_repeats_are_not_losses():
    gaps = fed([1, 2, 2, 2, 3, 3, 4])
    assert (gaps.lost, gaps.repeats) == (0, 3)


def test_a_late_sample_is_taken_back_out_of_the_lost_ones():
    gaps = fed([1, 2, 4, 5, 3, 6])
    assert (gaps.lost, gaps.late, gaps.repeats) == (0, 1, 0)
    again = fed([1, 2, 4, 5, 3, 3, 2])       # 3 again, then 2: repeats of older samples
    assert (again.lost, again.late, again.repeats) == (0, 1, 2)


def test_late_samples_split_a_gap():
    gaps = fed([1, 10, 5, 3, 9, 11])
    assert (gaps.lost, gaps.late) == (8 - 3, 3)


@pytest.mark.parametrize('back_to', [1, 3000 - RESTART_DISTANCE - 1])
def test_restart_of_the_rig(back_to):
    """A bag replayed again, a new simulator: the count goes on from the new counter."""
    gaps = fed(list(range(1, 3001)) + list(range(back_to, back_to + 10)))
    assert (gaps.restarts, gaps.lost, gaps.repeats) == (1, 0, 0)


def test_zero_is_not_counted():
    gaps = fed([0, 0, 0])
    assert (gaps.uncounted, gaps.received, gaps.lost, gaps.repeats) == (3, 0, 0, 0)


def test_problem_is_about_the_last_period_only():
    gaps = fed(range(1, 1001))
    assert gaps.problem(0.001) == ''
    for c in [1003, *range(1004, 2000)]:     # 2 lost out of 999 due: 0.2 %
        gaps.update(c)
    message = gaps.problem(0.001)
    assert message.startswith('samples lost: 2 of 999 in the last period')
    assert gaps.problem(0.001) == ''               # nothing new since
    gaps.update(2001)                              # 1 lost out of 2 due
    assert gaps.problem(0.6) == ''
    assert gaps.problem(0.0) == ''                 # period already taken
    gaps.update(2003)
    assert gaps.problem(0.0).startswith('samples lost: 1 of 2')
    assert gaps.values()['samples lost'] == 4
    gaps.update(2010)
    level, problem, values = gaps.report(0.5)
    assert (level, values['samples lost'], values['sample gaps']) == ('WARN', 10, 4)
    assert problem == 'samples lost: 6 of 7 in the last period (10 since start)'


def test_loss_summary_for_the_benchmarks():
    gaps = fed([1, 2, 5, 5, 0])
    assert loss_summary(gaps.values()) == ('samples lost 2 in 1 gaps, repeated 1, late 0, '
                                           'without counter 1')
    assert loss_summary({'samples lost': '3', 'sample gaps': '1', 'repeated samples': '0',
                         'late samples (reordered)': '0', 'samples without counter': '0'}
                        ).startswith('samples lost 3 in 1 gaps')
    assert loss_summary({}) == 'no sample counter reported'
