"""tracking_report as a real process fed by the test's probe: a run with no reference held long
enough to be a step ends with one line and an exit code, not a traceback (fault campaign: a
ValueError from max() of no steps)."""

import time

from pam_common.stamps import ns_stamp
from pam_common.testing import wait_until
from pam_interfaces.msg import JointMeasurement, Reference


def test_a_run_without_a_complete_step_reports_so(node_process, probe):
    report = node_process('tracking_report', 'pam_bringup', '-p', 'duration:=1.5')
    references = probe.publisher(Reference, '/pam/reference')
    truth = probe.publisher(JointMeasurement, '/pam/joint_measured')
    assert wait_until(lambda: references.get_subscription_count() > 0
                      and truth.get_subscription_count() > 0, 60.0), report.stderr
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
