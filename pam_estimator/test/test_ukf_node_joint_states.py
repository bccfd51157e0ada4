"""ukf_node's estimate as sensor_msgs/JointState on /pam/estimate/joint_states, a real process fed
by the test's probe: the estimate's stamps and values, decimated by the sample counter, and a
bad rate refused."""

import subprocess

from sensor_msgs.msg import JointState

from pam_common.stamps import ns_stamp, stamp_ns
from pam_common.testing import executable
from pam_interfaces.msg import JointEstimate, Pressures

STARTUP = 60.0       # s, the first estimate of a fresh process (the kernel loads first)
SAMPLES = 60         # pressure samples the test sends once everything is matched
H_NS = 1_000_000     # ns, 1 kHz
EXIT_TIMEOUT = 60.0  # s, a bad configuration is refused before the filter runs


def _fed(node_process, probe, *params):
    """A ukf_node fed pressures with counters 1, 2, ... every 1 ms of stamps: warm-up samples
    until its estimate and estimate/joint_states both reach the probe, then SAMPLES more.
    Returns the process, the two collectors and the first and last counter of the SAMPLES."""
    ukf = node_process('ukf_node', 'pam_estimator', *params)
    est = probe.subscribe(JointEstimate, '/pam/estimate', depth=1000)
    states = probe.subscribe(JointState, '/pam/estimate/joint_states', depth=1000)
    pub = probe.publisher(Pressures, '/pam/pressures')
    ukf.wait_for(lambda: pub.get_subscription_count() > 0, STARTUP, 'pressures matched')
    counter = 0

    def send():
        nonlocal counter
        counter += 1
        msg = Pressures(p1=4.6e5 + 100.0 * counter, p2=4.4e5, sample=counter)
        msg.header.stamp = ns_stamp(10**12 + counter * H_NS)
        pub.publish(msg)

    def matched():                      # polled every 10 ms: a warm-up sample each time
        send()
        return len(est) > 0 and len(states) > 0
    ukf.wait_for(matched, STARTUP, 'estimate and estimate/joint_states')
    first = counter + 1
    for _ in range(SAMPLES):
        send()
    last_stamp = 10**12 + counter * H_NS
    ukf.wait_for(lambda: any(stamp_ns(m.header.stamp) == last_stamp for m in est.messages()),
                 30.0, 'the last estimate')
    return ukf, est, states, first, counter


def _by_stamp(collector) -> dict:
    return {stamp_ns(m.header.stamp): m for m in collector.messages()}


def test_estimate_joint_states_are_the_estimate(node_process, probe):
    ukf, est, states, first, last = _fed(node_process, probe)
    last_stamp = 10**12 + last * H_NS
    ukf.wait_for(lambda: last_stamp in _by_stamp(states), 10.0, 'the last joint state')
    estimates, got = _by_stamp(est), _by_stamp(states)
    sent = [10**12 + k * H_NS for k in range(first, last + 1)]
    assert set(sent) <= set(estimates) and set(sent) <= set(got)
    assert set(got) == set(estimates)
    for stamp in sent:
        e, s = estimates[stamp], got[stamp]
        assert (list(s.position), list(s.velocity), list(s.effort)) == (
            [e.angle], [e.angular_velocity], [e.torque]), stamp
        assert list(s.name) == ['seesaw_joint'] and s.header.frame_id == e.header.frame_id
    assert any(estimates[stamp].angle != 0.0 for stamp in sent), 'the estimate did not move'


def test_estimate_joint_states_rate_decimates(node_process, probe):
    """joint_states_rate 200 Hz: the samples with counter 1, 6, 11, ... (those a rig at the
    same rate publishes: the same stamps)."""
    ukf, est, states, first, last = _fed(node_process, probe, '-p', 'joint_states_rate:=200.0')
    due = [k for k in range(first, last + 1) if (k - 1) % 5 == 0]
    ukf.wait_for(lambda: 10**12 + due[-1] * H_NS in _by_stamp(states), 10.0,
                 'the last joint state due')
    estimates, got = _by_stamp(est), _by_stamp(states)
    assert {10**12 + k * H_NS for k in due} <= set(got)
    assert all((stamp - 10**12) // H_NS % 5 == 1 for stamp in got), sorted(got)
    for stamp, s in got.items():
        assert list(s.position) == [estimates[stamp].angle]
        assert list(s.effort) == [estimates[stamp].torque]


def test_a_bad_joint_states_rate_is_refused(node_process):
    for value, words in (('1500.0', '1500 Hz is above the sample rate 1000 Hz'),
                         ('20000.0', 'out of range [0.0, 10000.0]')):
        ukf = node_process('ukf_node', 'pam_estimator', '-p', f'joint_states_rate:={value}')
        assert ukf.wait_exit(EXIT_TIMEOUT) == 2, ukf.stderr
        lines = ukf.stderr.strip().splitlines()
        assert len(lines) == 1 and "parameter 'joint_states_rate'" in lines[0], ukf.stderr
        assert words in lines[0], ukf.stderr
    result = subprocess.run([executable('ukf_node', 'pam_estimator'), '--help'],
                            capture_output=True, text=True, timeout=EXIT_TIMEOUT)
    assert '  joint_states_rate (double, Hz) = 1000.0  [0.0 .. 10000.0]' in result.stdout
    assert 'estimate/joint_states' in result.stdout
