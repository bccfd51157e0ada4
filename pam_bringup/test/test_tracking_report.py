"""tracking_report as a real process fed by the test's probe: a run with no reference held long
enough to be a step ends with one line and an exit code, not a traceback (fault campaign: a
ValueError from max() of no steps); the estimation error over the whole record and after the
initial transient; the real-time health judged from a rig status the probe publishes as
/pam/sim_node's: a clean one gives a valid report, one with many late samples an INVALID run
(exit 1, marked, the JSON still written)."""

import json
import math
import re
import threading
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray

from pam_common.diagnostics import make_status
from pam_common.stamps import ns_stamp
from pam_common.testing import wait_until
from pam_interfaces.msg import JointEstimate, JointMeasurement, Reference, ValveCommand

#: a clean rig status, as sim_node publishes it since its ~/reset_statistics
CLEAN_RIG = {'samples taken': 3200, 'late samples': 0, 'missed samples': 0,
             'worst stall (ms)': 0.4,
             'commands timed': 3200, 'commands after the next sample': 3,
             'latency p50 (ms)': 0.2, 'latency p99 (ms)': 0.5, 'latency max (ms)': 1.1}


class FakeRig:
    """Publishes `values` as /pam/sim_node's /diagnostics status every 0.2 s until closed."""

    def __init__(self, probe, values: dict):
        self._pub = probe.publisher(DiagnosticArray, '/diagnostics')
        self._values = values
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        while not self._stop.wait(0.2):
            self._pub.publish(DiagnosticArray(status=[make_status(
                '/pam/sim_node: simulated rig', '/pam', 'OK', 'running', self._values)]))

    def close(self):
        self._stop.set()
        self._thread.join(5.0)


def loop_publishers(probe) -> tuple:
    """The probe's publishers of what tracking_report records: (references, truth, estimates,
    commands)."""
    return (probe.publisher(Reference, '/pam/reference'),
            probe.publisher(JointMeasurement, '/pam/joint_measured'),
            probe.publisher(JointEstimate, '/pam/estimate'),
            probe.publisher(ValveCommand, '/pam/valve_command'))


def subscribed(report, publishers) -> None:
    """Wait until the report has subscribed to every one of `publishers`."""
    assert wait_until(lambda: all(p.get_subscription_count() > 0 for p in publishers),
                      60.0), report.stderr


def started_report(node_process, probe, *params):
    """tracking_report with -p params, and the probe's publishers (loop_publishers) once the
    report has subscribed to them all: (report, references, truth, estimates)."""
    args = [a for param in params for a in ('-p', param)]
    report = node_process('tracking_report', 'pam_bringup', *args)
    publishers = loop_publishers(probe)
    subscribed(report, publishers)
    return report, *publishers[:3]


def test_a_run_without_a_complete_step_reports_so(node_process, probe):
    report, references, truth, _ = started_report(node_process, probe, 'duration:=1.5')
    k = 0
    end = time.monotonic() + 60.0
    while report.alive() and time.monotonic() < end:    # 1.5 s of stamps, one reference: < 2 s
        if k % 100 == 0:
            references.publish(Reference(mode=Reference.ANGLE, value=0.1))
        msg = JointMeasurement(angle=0.05)
        msg.header.stamp = ns_stamp(1_000_000_000 + k * 1_000_000)
        truth.publish(msg)
        k += 1
        time.sleep(0.0005)
    assert report.wait_exit(10.0) == 1, report.stdout + report.stderr
    assert 'no step to report' in report.stdout, report.stdout
    assert 'Traceback' not in report.stdout + report.stderr, report.stderr


def feed_held_reference(node_process, probe, tmp_path, rig: dict, missing=range(0)):
    """tracking_report over 3 s of one held reference, the estimate 0.1 rad off for the first
    20 ms, 0.01 rad after, every estimate with its sample counter except those of the samples
    `missing` (k, from 0), the rig status `rig` published meanwhile: (report, its exit code, its
    summary JSON or None)."""
    summary = tmp_path / 'summary.json'
    report = node_process('tracking_report', 'pam_bringup', '-p', 'duration:=3.0',
                          '-p', 'transient:=1.0', '-p', f'summary:={summary}')
    publishers = loop_publishers(probe)
    references, truth, estimates, _ = publishers
    subscribed(report, publishers)
    fake_rig = FakeRig(probe, rig)
    try:
        references.publish(Reference(mode=Reference.ANGLE, value=0.1))
        time.sleep(0.5)                                # the reference is there before sample 0
        k = 0
        end = time.monotonic() + 60.0
        while report.alive() and time.monotonic() < end and k <= 3200:
            stamp = ns_stamp(1_000_000_000 + k * 1_000_000)
            angle = 0.05 + 0.1 * k / 3000.0            # varies: Q needs a measured range
            estimate = JointEstimate(angle=angle + (0.1 if k < 20 else 0.01), sample=k + 1)
            estimate.header.stamp = stamp
            if k not in missing:
                estimates.publish(estimate)
            msg = JointMeasurement(angle=angle)
            msg.header.stamp = stamp
            truth.publish(msg)
            k += 1
            time.sleep(0.0005)
        code = report.wait_exit(30.0)
    finally:
        fake_rig.close()
    return report, code, json.loads(summary.read_text()) if summary.is_file() else None


def test_the_estimation_error_is_printed_whole_and_after_the_transient(node_process, probe,
                                                                       tmp_path):
    """The headline M is 0.1 rad (5.730 deg), the one after t >= 1 s is 0.01 rad (0.573 deg);
    the rig's status is clean: a valid run."""
    report, code, summary = feed_held_reference(node_process, probe, tmp_path, CLEAN_RIG)
    assert code == 0, report.stdout + report.stderr
    whole = re.search(r'estimation error \((\d+) samples\): I \S+ deg  M (\S+) deg', report.stdout)
    after = re.search(r'estimation error after t >= 1 s \((\d+) samples\): I \S+ deg  M (\S+) deg',
                      report.stdout)
    assert whole and after, report.stdout
    assert float(whole[2]) == pytest.approx(math.degrees(0.1), rel=1e-3), report.stdout
    assert float(after[2]) == pytest.approx(math.degrees(0.01), rel=1e-3), report.stdout
    assert int(after[1]) < int(whole[1]), report.stdout
    assert 'INVALID' not in report.stdout, report.stdout
    assert re.search(r'^  real-time health: \d+ of \d+ samples received \(0 lost\), rig: 0 late '
                     r'samples \(0 missed\) of 3200, .*: VALID$', report.stdout,
                     re.MULTILINE), report.stdout
    assert summary['valid'] is True and summary['health']['valid'] is True, summary
    assert summary['health']['samples_lost'] == 0 and summary['health']['samples_sent'] > 2900


def test_a_run_whose_rig_was_late_is_invalid(node_process, probe, tmp_path):
    """The rig says 10 % of its samples were late and it stalled 45 ms: INVALID, exit 1, the
    first line says the figures are not results, the JSON is written with valid false."""
    late = {**CLEAN_RIG, 'late samples': 320, 'worst stall (ms)': 45.0}
    report, code, summary = feed_held_reference(node_process, probe, tmp_path, late)
    assert code == 1, report.stdout + report.stderr
    assert report.stdout.startswith('tracking_report: INVALID run: the loop was not real time '
                                    '(320 of 3200 rig samples late (10.00 % > 5 %); worst '
                                    'stall 45.0 ms > 20 ms); the figures below are NOT '
                                    'results\n'), report.stdout
    assert ': INVALID: ' in report.stdout and 'estimation error' in report.stdout
    assert summary['valid'] is False and summary['health']['valid'] is False, summary
    assert len(summary['health']['reasons']) == 2, summary['health']


def test_samples_lost_at_the_report_make_the_run_invalid_and_say_where(node_process, probe,
                                                                     tmp_path):
    """100 estimates of the samples 1.5 s into the record never come: 100 of 3001 counters lost
    (3.3 % > 1 %), INVALID, and the report says it was one gap, 100 samples, after 1.50 s."""
    report, code, summary = feed_held_reference(node_process, probe, tmp_path, CLEAN_RIG,
                                                missing=range(1500, 1600))
    assert code == 1, report.stdout + report.stderr
    assert 'INVALID run: the record is incomplete (100 of 3001 samples lost at the report' \
        in report.stdout, report.stdout
    assert re.search(r'^  samples lost at the report in 1 gap\(s\); the longest: 100 samples '
                     r'after 1\.50 s of the record$', report.stdout, re.MULTILINE), report.stdout
    assert summary['health']['samples_lost'] == 100, summary['health']


def test_start_at_the_first_step_records_whole_holds(node_process, probe):
    """start:=step: the recording begins at the first change of the reference (1 s into the
    feed), not at the first reference: 2 s recorded are the hold at 0.2 from its first sample."""
    report, references, truth, estimates = started_report(node_process, probe, 'duration:=2.0',
                                                          'start:=step', 'transient:=0.0')
    fake_rig = FakeRig(probe, CLEAN_RIG)
    k = 0
    end = time.monotonic() + 60.0
    while report.alive() and time.monotonic() < end and k <= 3500:
        stamp = ns_stamp(1_000_000_000 + k * 1_000_000)
        if k % 10 == 0:                                # 100 Hz, stamped like reference_node
            value = 0.0 if k < 1000 else 0.2
            ref = Reference(mode=Reference.ANGLE, value=value)
            ref.header.stamp = stamp
            references.publish(ref)
        msg = JointMeasurement(angle=0.0 if k < 1000 else 0.2 - 0.1 * math.exp(-(k - 1000) / 50))
        msg.header.stamp = stamp
        truth.publish(msg)
        estimate = JointEstimate(angle=msg.angle, sample=k + 1)
        estimate.header.stamp = stamp
        estimates.publish(estimate)
        k += 1
        time.sleep(0.0005)
    code = report.wait_exit(30.0)
    fake_rig.close()
    assert code == 0, report.stdout + report.stderr
    assert 'after the first change of the reference' in report.stderr, report.stderr
    steps = re.findall(r'^\s+(\d+\.\d)\s+(-?\d+\.\d+)deg', report.stdout, re.MULTILINE)
    assert steps == [('0.0', f'{math.degrees(0.2):.2f}')], report.stdout


def test_the_record_starts_once_the_loop_publishes(node_process, probe):
    """Reference and measurements come 1 s before the estimator and the controller publish (a
    discovery that took its time): the record starts once estimate and valve_command have a
    publisher, so that every sample recorded has its estimate; the log says what it waited for.
    """
    report = node_process('tracking_report', 'pam_bringup', '-p', 'duration:=2.0',
                          '-p', 'transient:=0.0')
    references, truth = (probe.publisher(Reference, '/pam/reference'),
                         probe.publisher(JointMeasurement, '/pam/joint_measured'))
    subscribed(report, (references, truth))
    fake_rig = FakeRig(probe, CLEAN_RIG)
    late = None
    k = 0
    end = time.monotonic() + 60.0
    while report.alive() and time.monotonic() < end and k <= 6000:
        if k == 2000:                       # about 1 s in: the loop's publishers appear
            late = loop_publishers(probe)[2:]
            subscribed(report, late)
        stamp = ns_stamp(1_000_000_000 + k * 1_000_000)
        if k % 10 == 0:
            ref = Reference(mode=Reference.ANGLE, value=0.1)
            ref.header.stamp = stamp
            references.publish(ref)
        msg = JointMeasurement(angle=0.05 + 0.1 * k / 6000.0)
        msg.header.stamp = stamp
        truth.publish(msg)
        if late is not None:
            estimate = JointEstimate(angle=msg.angle + 0.01, sample=k + 1)
            estimate.header.stamp = stamp
            late[0].publish(estimate)
        k += 1
        time.sleep(0.0005)
    code = report.wait_exit(30.0)
    fake_rig.close()
    assert code == 0, report.stdout + report.stderr
    assert 'waiting for a publisher of /pam/estimate, /pam/valve_command (up to 10 s) before ' \
        'recording' in report.stderr, report.stderr
    recorded = int(re.search(r'2\.0 s, (\d+) samples', report.stdout)[1])
    estimated = int(re.search(r'estimation error \((\d+) samples\)', report.stdout)[1])
    assert estimated == recorded == 2001, report.stdout
