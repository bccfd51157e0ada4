"""pam_common.run_health: the real-time health judgement of a run (no ROS)."""

from __future__ import annotations

import json
import math

import pytest

from pam_common.run_health import NO_RIG, HealthLimits, counter_gaps, judge_run, number

#: a clean sim_node status as /diagnostics carries it (strings)
CLEAN = {'samples taken': '64001', 'late samples': '0', 'missed samples': '0',
         'worst stall (ms)': '0.9',
         'commands timed': '64000', 'commands after the next sample': '64',
         'latency p50 (ms)': '0.21', 'latency p99 (ms)': '0.48', 'latency p99.9 (ms)': '1.2',
         'latency max (ms)': '2.1', 'timing': 'realtime'}
DRIVER = {key: CLEAN[key] for key in ('commands timed', 'commands after the next sample',
                                      'latency p50 (ms)', 'latency p99 (ms)',
                                      'latency p99.9 (ms)', 'latency max (ms)')}


def test_a_clean_run_is_valid_and_says_so_in_one_line():
    health = judge_run(CLEAN, 64001, 64001)
    assert health.valid and health.reasons == () and health.notes == ()
    assert health.samples_lost == 0 and health.late_samples == 0
    assert health.worst_stall == pytest.approx(0.0009)
    assert health.latency_p99 == pytest.approx(0.00048)
    assert health.lines() == [
        'real-time health: 64001 of 64001 samples received (0 lost), rig: 0 late samples '
        '(0 missed) of 64001, worst stall 0.90 ms; sample -> command at the rig p50 0.21 / '
        'p99 0.48 / max 2.1 ms, 0.1 % after the next sample: VALID']


def test_numbers_are_taken_as_well_as_strings():
    numeric = {key: float(value) for key, value in CLEAN.items() if key != 'timing'}
    assert judge_run(numeric, 64001, 64001) == judge_run(CLEAN, 64001, 64001)


@pytest.mark.parametrize(('change', 'received', 'expected_reason'), [
    ({'late samples': '4000'}, 64001, '4000 of 64001 rig samples late (6.25 % > 5 %)'),
    ({'late samples': '100', 'missed samples': '100'}, 64001,
     '100 of 64001 rig samples missed (0.16 % > 0.1 %)'),
    ({'worst stall (ms)': '35'}, 64001, 'worst stall 35.0 ms > 20 ms'),
    ({'latency p99 (ms)': '5.5'}, 64001, 'sample -> command latency p99 5.5 ms > 5 ms'),
    ({'commands after the next sample': '6400'}, 64001,
     '6400 of 64000 commands after the next sample (10.00 % > 5 %)'),
    ({}, 63000, '1001 of 64001 samples lost at the report (1.56 % > 1 %)'),
])
def test_each_broken_threshold_gives_one_reason_with_figure_and_limit(change, received,
                                                                      expected_reason):
    health = judge_run({**CLEAN, **change}, received, 64001)
    assert not health.valid
    assert health.reasons == (expected_reason,)
    lost = 'lost at the report' in expected_reason
    assert health.incomplete is lost
    assert health.headline == ('the record is incomplete' if lost else
                               'the loop was not real time')
    assert health.lines()[0].endswith(': INVALID: ' + expected_reason), health.lines()


def test_the_limits_are_the_edges():
    at_limit = {**CLEAN, 'late samples': '3200.05', 'missed samples': '64.001',
                'worst stall (ms)': '20', 'latency p99 (ms)': '5',
                'commands after the next sample': '3200'}
    assert judge_run(at_limit, 64001 - 640, 64001).valid
    strict = HealthLimits(max_late_fraction=0.0, max_worst_stall=0.0005)
    health = judge_run(CLEAN, 64001, 64001, strict)
    assert health.reasons == ('worst stall 0.90 ms > 0.5 ms',)


def test_a_late_loop_that_also_lost_samples_was_not_real_time():
    health = judge_run({**CLEAN, 'worst stall (ms)': '35'}, 63000, 64001)
    assert health.incomplete and len(health.reasons) == 2
    assert health.headline == 'the loop was not real time'
    assert judge_run(CLEAN, 64001, 64001).headline == 'valid'


def test_no_rig_status_is_invalid():
    health = judge_run(None, 64001, 64001)
    assert not health.valid and health.reasons == (NO_RIG,)
    assert 'INVALID: no /diagnostics from the rig: real-time health unknown' in health.lines()[0]


def test_driver_node_keys_judge_the_latency_only_and_note_the_rest():
    health = judge_run(DRIVER, 64001, 64001)
    assert health.valid, health.reasons
    assert math.isnan(health.late_samples) and math.isnan(health.worst_stall)
    assert len(health.notes) == 3 and 'late samples' in health.notes[0], health.notes
    assert 'missed samples' in health.notes[1], health.notes
    assert any('not judged' in line and 'worst stall' in line for line in health.lines())
    bad = judge_run({**DRIVER, 'latency p99 (ms)': '9'}, 64001, 64001)
    assert bad.reasons == ('sample -> command latency p99 9.0 ms > 5 ms',)


def test_na_values_are_not_judged():
    status = {**CLEAN, 'latency p50 (ms)': 'n/a', 'latency p99 (ms)': 'n/a',
              'latency max (ms)': 'n/a', 'commands timed': '0'}
    health = judge_run(status, 100, 100)
    assert health.valid and math.isnan(health.latency_p99)
    assert len(health.notes) == 2, health.notes


def test_as_dict_is_strict_json():
    health = judge_run(DRIVER, 10, 12)
    data = health.as_dict()
    text = json.dumps(data, allow_nan=False)
    back = json.loads(text)
    assert back['valid'] is False and back['late_samples'] is None and back['samples_lost'] == 2
    assert back['reasons'] == ['2 of 12 samples lost at the report (16.67 % > 1 %)']
    assert back['commands_timed'] == 64000 and isinstance(back['reasons'], list)
    assert back['latency_p99'] == pytest.approx(0.00048)


def test_number_parses_safely():
    assert number({'a': '1.5'}, 'a') == 1.5
    for values in ({'a': 'n/a'}, {'a': None}, {'a': True}, {}, None, {'a': [1]}):
        assert math.isnan(number(values, 'a'))


@pytest.mark.parametrize('bad', [{'max_late_fraction': 1.5}, {'max_worst_stall': -0.1},
                                 {'max_latency_p99': math.nan}, {'max_lost_fraction': '0.1'}])
def test_bad_limits_are_refused(bad):
    with pytest.raises(ValueError, match='HealthLimits'):
        HealthLimits(**bad)


def test_a_run_without_any_estimate_is_invalid():
    """A clean rig but no estimate at all (the estimator never ran): not a result."""
    rig = {'samples taken': 30000, 'late samples': 0, 'worst stall (ms)': 0.5,
           'commands timed': 0, 'commands after the next sample': 0}
    health = judge_run(rig, received=0, expected=0)
    assert not health.valid
    assert any('no estimate received' in r for r in health.reasons), health.reasons


def test_counter_gaps_say_where_and_how_many_samples_are_missing():
    assert counter_gaps([]) == [] and counter_gaps([7]) == []
    assert counter_gaps(range(1, 1001)) == []
    # unordered, repeated: one gap of 3 after 4, one of 1 after 10
    assert counter_gaps([10, 1, 2, 3, 4, 8, 9, 12, 4, 9]) == [(4, 3), (10, 1)]
