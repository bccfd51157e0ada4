"""tracking_report as a real process fed by the test's probe: a run with no reference held long
enough to be a step ends with one line and an exit code, not a traceback (fault campaign: a
ValueError from max() of no steps); the estimation error over the whole record and after the
initial transient."""

import math
import re
import time

import pytest

from pam_common.stamps import ns_stamp
from pam_common.testing import wait_until
from pam_interfaces.msg import JointEstimate, JointMeasurement, Reference


def started_report(node_process, probe, *params):
    """tracking_report with -p params, and the probe's reference and joint_measured publishers
    once the report has subscribed to both: (report, references, truth)."""
    args = [a for param in params for a in ('-p', param)]
    report = node_process('tracking_report', 'pam_bringup', *args)
    references = probe.publisher(Reference, '/pam/reference')
    truth = probe.publisher(JointMeasurement, '/pam/joint_measured')
    assert wait_until(lambda: references.get_subscription_count() > 0
                      and truth.get_subscription_count() > 0, 60.0), report.stderr
    return report, references, truth


def test_a_run_without_a_complete_step_reports_so(node_process, probe):
    report, references, truth = started_report(node_process, probe, 'duration:=1.5')
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


def test_the_estimation_error_is_printed_whole_and_after_the_transient(node_process, probe):
    """3 s of one held reference; the estimate is 0.1 rad off for the first 20 ms, 0.01 rad
    after: the headline M is 0.1 rad (5.730 deg), the one after t >= 1 s is 0.01 rad (0.573 deg)."""
    report = node_process('tracking_report', 'pam_bringup', '-p', 'duration:=3.0',
                          '-p', 'transient:=1.0')
    references = probe.publisher(Reference, '/pam/reference')
    truth = probe.publisher(JointMeasurement, '/pam/joint_measured')
    estimates = probe.publisher(JointEstimate, '/pam/estimate')
    assert wait_until(lambda: references.get_subscription_count() > 0
                      and truth.get_subscription_count() > 0
                      and estimates.get_subscription_count() > 0, 60.0), report.stderr
    references.publish(Reference(mode=Reference.ANGLE, value=0.1))
    time.sleep(0.5)                                    # the reference is there before sample 0
    k = 0
    end = time.monotonic() + 60.0
    while report.alive() and time.monotonic() < end and k <= 3200:
        stamp = ns_stamp(1_000_000_000 + k * 1_000_000)
        angle = 0.05 + 0.1 * k / 3000.0                # varies: Q needs a measured range
        estimate = JointEstimate(angle=angle + (0.1 if k < 20 else 0.01))
        estimate.header.stamp = stamp
        estimates.publish(estimate)
        msg = JointMeasurement(angle=angle)
        msg.header.stamp = stamp
        truth.publish(msg)
        k += 1
        time.sleep(0.0005)
    assert report.wait_exit(30.0) == 0, report.stdout + report.stderr
    whole = re.search(r'estimation error \((\d+) samples\): I \S+ deg  M (\S+) deg', report.stdout)
    after = re.search(r'estimation error after t >= 1 s \((\d+) samples\): I \S+ deg  M (\S+) deg',
                      report.stdout)
    assert whole and after, report.stdout
    assert float(whole[2]) == pytest.approx(math.degrees(0.1), rel=1e-3), report.stdout
    assert float(after[2]) == pytest.approx(math.degrees(0.01), rel=1e-3), report.stdout
    assert int(after[1]) < int(whole[1]), report.stdout


def test_start_at_the_first_step_records_whole_holds(node_process, probe):
    """start:=step: the recording begins at the first change of the reference (1 s into the
    feed), not at the first reference: 2 s recorded are the hold at 0.2 from its first sample."""
    report, references, truth = started_report(node_process, probe, 'duration:=2.0',
                                               'start:=step', 'transient:=0.0')
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
        k += 1
        time.sleep(0.0005)
    assert report.wait_exit(30.0) == 0, report.stdout + report.stderr
    assert 'after the first change of the reference' in report.stderr, report.stderr
    steps = re.findall(r'^\s+(\d+\.\d)\s+(-?\d+\.\d+)deg', report.stdout, re.MULTILINE)
    assert steps == [('0.0', f'{math.degrees(0.2):.2f}')], report.stdout
