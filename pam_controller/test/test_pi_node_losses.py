"""pi_node as a real process fed by the test's probe: estimates lost on the way (gaps in
JointEstimate.sample) are counted and reported on /diagnostics; repeats are not losses."""

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from pam_common.diagnostics import status_values
from pam_common.stamps import ns_stamp
from pam_common.testing import diagnostic_statuses, wait_until
from pam_interfaces.msg import JointEstimate


def test_gaps_in_the_estimates_sample_counter_are_reported(node_process, probe):
    pi = node_process('pi_node', 'pam_controller', '-p', 'feedback_timeout:=5.0')
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=100)
    estimates = probe.publisher(JointEstimate, '/pam/estimate')
    assert wait_until(lambda: estimates.get_subscription_count() > 0, 60.0), pi.stderr

    def publish(sample):
        msg = JointEstimate(sample=sample)
        t = 1.0 + 0.001 * (sample - 1)
        msg.header.stamp = ns_stamp(round(t * 1e9))
        estimates.publish(msg)

    def commands_published():
        statuses = diagnostic_statuses(diagnostics, 'pi_node')
        return int(status_values(statuses[-1])['commands published']) if statuses else 0

    # sample 1 until pi_node answers (what is published before it has matched the probe's
    # publisher is not delivered: the count starts at the first one it gets)
    end = time.monotonic() + 60.0
    while not commands_published():
        assert time.monotonic() < end and pi.alive(), pi.stderr
        publish(1)
        wait_until(commands_published, 0.2)
    # 2..100, 100 again (a repeated estimate), then 131..200: 30 samples lost
    counters = [*range(2, 101), 100, *range(131, 201)]
    for sample in counters:
        publish(sample)
        time.sleep(0.002)      # paced: pi_node's keep-last 100 queue must lose none itself

    def reported():
        statuses = diagnostic_statuses(diagnostics, 'pi_node')
        return [s for s in statuses if status_values(s).get('samples lost') == '30']

    assert wait_until(reported, 20.0), [(s.message, status_values(s)) for s in
                                        diagnostic_statuses(diagnostics, 'pi_node')[-1:]]
    status = reported()[0]
    values = status_values(status)
    assert values['sample gaps'] == '1' and int(values['repeated samples']) >= 1, values
    assert status.level == DiagnosticStatus.WARN and 'samples lost: 30 of' in status.message
