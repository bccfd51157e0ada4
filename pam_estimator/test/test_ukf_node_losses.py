"""ukf_node as a real process fed by the test's probe: samples lost on the way are counted from
Pressures.sample and reported on /diagnostics; a flood of warnings is throttled and counted."""

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from pam_common.diagnostics import status_values
from pam_common.stamps import ns_stamp
from pam_common.testing import diagnostic_statuses, feed_until_answered, wait_until
from pam_interfaces.msg import JointEstimate, Pressures

BURST = 20000


def pressures(sample: int, stamp_s: float) -> Pressures:
    msg = Pressures(p1=4.5e5, p2=4.5e5, sample=sample)
    msg.header.stamp = ns_stamp(round(stamp_s * 1e9))
    return msg


def start(node_process, probe):
    ukf = node_process('ukf_node', 'pam_estimator')
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=100)
    estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=1000)
    pub = probe.publisher(Pressures, '/pam/pressures')
    ukf.wait_for(lambda: pub.get_subscription_count() > 0 and len(diagnostics) > 0, 60.0,
                 'ukf_node matched and reporting')
    return ukf, diagnostics, estimates, pub


def ukf_values(diagnostics) -> dict:
    statuses = diagnostic_statuses(diagnostics, 'ukf_node')
    return status_values(statuses[-1]) if statuses else {}


def test_a_burst_lost_in_the_queue_is_reported(node_process, probe):
    """20000 samples as fast as the probe can publish them: ukf_node's keep-last 100 queue
    overflows. What reached the filter plus what /diagnostics reports lost is the whole burst,
    and the status goes WARN."""
    ukf, diagnostics, estimates, pub = start(node_process, probe)
    # samples without a counter one at a time until an estimate came back (each side of a
    # match is discovered on its own, and the probe sees only its side): ukf_node then takes
    # and answers sample 1 surely, and its count of the burst starts there
    fed = feed_until_answered(lambda k: pub.publish(pressures(0, 100.0 + k * 1e-3)),
                              [estimates], timeout=30.0)
    t0 = 100.0 + fed * 1e-3                  # the burst's stamps go on after the fed ones
    pub.publish(pressures(1, t0))
    ukf.wait_for(lambda: any(m.sample == 1 for m in estimates.messages()), 30.0,
                 'the estimate of sample 1')
    since = time.monotonic()
    for k in range(2, BURST + 1):
        pub.publish(pressures(k, t0 + (k - 1) * 1e-3))

    def settled():      # the burst: estimated (less the fed samples without a counter) + lost
        values = ukf_values(diagnostics)
        return values and (int(values['samples estimated']) - int(values['samples without counter'])
                           + int(values['samples lost'])) == BURST

    ukf.wait_for(settled, 60.0, 'samples estimated + samples lost == the burst; last: '
                 f'{ukf_values(diagnostics)}')
    values = ukf_values(diagnostics)
    lost = int(values['samples lost'])
    assert lost > 0, 'the burst was meant to overflow the queue'
    assert int(values['sample gaps']) > 0 and values['repeated samples'] == '0', values
    warned = [s for s in diagnostic_statuses(diagnostics, 'ukf_node')
              if s.level == DiagnosticStatus.WARN and 'samples lost:' in s.message]
    assert warned, 'a WARN about the loss'
    got = [m.sample for m in estimates.since(since)]
    assert got and got == sorted(got) and got[-1] == BURST, 'estimates carry the sample on'
    assert ukf.alive()


def test_time_going_backwards_100_times_logs_a_few_lines(node_process, probe):
    """100 samples with decreasing stamps within a few ms: each one resets the filter (counted on
    /diagnostics), but the log gets one line, not 100; the lines left out are counted."""
    ukf, diagnostics, _estimates, pub = start(node_process, probe)
    for k in range(100):
        pub.publish(pressures(0, 200.0 - k * 1e-3))

    def counted():
        values = ukf_values(diagnostics)
        return values and values['resets on time going backwards'] == '99'

    ukf.wait_for(counted, 30.0, f'99 resets on /diagnostics; last: {ukf_values(diagnostics)}')
    assert wait_until(lambda: int(ukf_values(diagnostics)['log lines suppressed (throttled)'])
                      >= 98, 5.0), ukf_values(diagnostics)
    log = ukf.stderr + ukf.stdout
    assert 1 <= log.count('time went backwards') <= 3, log
    assert ukf_values(diagnostics)['samples without counter'] == '100'
