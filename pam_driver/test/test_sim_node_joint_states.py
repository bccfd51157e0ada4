"""sim_node's sensor_msgs/JointState on /pam/joint_states (pam_common.joint_states), seen from
topics: joint_measured sample for sample, decimated by joint_states_rate, off at 0, and a bad
rate refused."""

from __future__ import annotations

import time

from sensor_msgs.msg import JointState

from pam_interfaces.msg import JointMeasurement, ValveCommand

STARTUP = 45.0          # s, first message from a fresh process (loaded machine)
STEPS = 45              # lockstep steps driven by the test
H_NS = 1_000_000        # ns, the model step at the default 1 kHz (lockstep stamps k * h)
EXIT_TIMEOUT = 30.0     # s, a bad configuration is refused before any sampling


def _by_stamp(helpers, collector) -> dict:
    return {helpers.stamp_ns(m.header.stamp): m for m in collector.messages()}


def _stepped(sim, probe, helpers, last_state: int, steps: int = STEPS):
    """Drive a lockstep sim_node `steps` steps; its joint_measured and joint_states by stamp
    (ns), once the joint_states of step `last_state` arrived. A lockstep sim_node re-publishes
    its current sample every lockstep_timeout: the first one on both topics shows both matched,
    before any step."""
    measured = probe.subscribe(JointMeasurement, '/pam/joint_measured', depth=1000)
    states = probe.subscribe(JointState, '/pam/joint_states', depth=1000)
    commands = probe.publisher(ValveCommand, '/pam/valve_command')
    sim.wait_for(lambda: len(measured) > 0 and len(states) > 0
                 and commands.get_subscription_count() > 0, STARTUP,
                 'joint_measured, joint_states and valve_command matched')
    for _ in range(steps):              # a zero stamp: "for the current step", one step each
        commands.publish(ValveCommand(u1=7.0, u2=4.0))
    sim.wait_for(lambda: steps * H_NS in _by_stamp(helpers, measured), STARTUP,
                 f'the joint_measured of step {steps}')
    sim.wait_for(lambda: last_state * H_NS in _by_stamp(helpers, states), 10.0,
                 f'the joint_states of step {last_state}')
    return _by_stamp(helpers, measured), _by_stamp(helpers, states)


def test_joint_states_are_joint_measured_sample_for_sample(sim_node, probe, helpers):
    sim = sim_node('-p', 'timing:=lockstep', '-p', 'lockstep_timeout:=0.1')
    measured, states = _stepped(sim, probe, helpers, STEPS)
    assert sorted(measured) == [k * H_NS for k in range(STEPS + 1)]
    assert sorted(states) == sorted(measured)
    for stamp, joint in measured.items():
        state = states[stamp]
        assert (list(state.position), list(state.velocity), list(state.effort)) == (
            [joint.angle], [joint.angular_velocity], [joint.torque]), stamp
        assert list(state.name) == ['seesaw_joint']         # the URDF's joint
        assert state.header.frame_id == joint.header.frame_id == 'pam_joint'
    assert abs(measured[STEPS * H_NS].angular_velocity) > 0.0, 'the joint did not move'


def test_joint_states_rate_decimates_by_the_sample_counter(sim_node, probe, helpers):
    """joint_states_rate 100 Hz at 1 kHz: samples 1, 11, 21, ... (the counter of step k is
    k + 1), with the joint name given."""
    sim = sim_node('-p', 'timing:=lockstep', '-p', 'lockstep_timeout:=0.1',
                   '-p', 'joint_states_rate:=100.0', '-p', 'joint_name:=left_seesaw')
    due = list(range(0, STEPS + 1, 10))
    measured, states = _stepped(sim, probe, helpers, due[-1])
    assert sorted(states) == [k * H_NS for k in due]
    for stamp in sorted(states):
        joint, state = measured[stamp], states[stamp]
        assert list(state.position) == [joint.angle] and list(state.effort) == [joint.torque]
        assert list(state.name) == ['left_seesaw']


def test_joint_states_in_realtime(sim_node, probe, helpers):
    """The default: every realtime sample, with joint_measured's stamps and values."""
    sim = sim_node()
    measured = probe.subscribe(JointMeasurement, '/pam/joint_measured', depth=1000)
    states = probe.subscribe(JointState, '/pam/joint_states', depth=1000)
    sim.wait_for(lambda: len(measured) > 0 and len(states) > 0, STARTUP,
                 'joint_measured and joint_states')
    start = time.monotonic()
    sim.wait_for(lambda: len(measured.since(start)) >= 1000, 30.0, '1000 more samples')
    by_stamp = _by_stamp(helpers, measured)
    window = [helpers.stamp_ns(m.header.stamp) for m in measured.since(start)][:-100]
    got = _by_stamp(helpers, states)
    missing = [s for s in window if s not in got]
    assert len(missing) <= 0.05 * len(window), f'{len(missing)} of {len(window)} not received'
    compared = 0
    for stamp, state in got.items():
        if stamp in by_stamp:
            joint = by_stamp[stamp]
            assert (state.position[0], state.velocity[0], state.effort[0]) == (
                joint.angle, joint.angular_velocity, joint.torque)
            compared += 1
    assert compared >= 0.9 * len(window)


def test_joint_states_rate_zero_publishes_none(sim_node, probe):
    sim = sim_node('-p', 'joint_states_rate:=0.0')
    measured = probe.subscribe(JointMeasurement, '/pam/joint_measured')
    sim.wait_for(lambda: len(measured) > 0, STARTUP, 'joint_measured')
    assert probe.node.count_publishers('/pam/pressures') == 1   # the graph knows sim_node's
    assert probe.node.count_publishers('/pam/joint_states') == 0


def test_a_bad_joint_states_rate_is_refused(sim_node):
    for args, words in (
            (('-p', 'joint_states_rate:=2000.0'),
             "parameter 'joint_states_rate': 2000 Hz is above the sample rate 1000 Hz"),
            (('-p', 'rate:=500.0', '-p', 'joint_states_rate:=600.0'),
             "parameter 'joint_states_rate': 600 Hz is above the sample rate 500 Hz"),
            (('-p', 'joint_states_rate:=-1.0'),
             "parameter 'joint_states_rate': -1.0 is out of range [0.0, 10000.0]"),
            (('-p', "joint_name:=''"), "parameter 'joint_name': empty")):
        sim = sim_node(*args)
        assert sim.wait_exit(EXIT_TIMEOUT) == 2, (args, sim.stderr)
        lines = sim.stderr.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], (args, sim.stderr)


def test_a_slower_rig_keeps_the_default_rate(sim_node, probe):
    """rate:=500 with the default joint_states_rate (1000 Hz) is not refused: every sample."""
    sim = sim_node('-p', 'rate:=500.0')
    states = probe.subscribe(JointState, '/pam/joint_states')
    sim.wait_for(lambda: len(states) > 0, STARTUP, 'joint_states')
    assert 'every sample' in sim.stderr + sim.stdout


def test_help_shows_the_joint_state_parameters(sim_node):
    sim = sim_node('--help', raw=True)
    assert sim.wait_exit(EXIT_TIMEOUT) == 0, sim.stderr
    assert "  joint_name (string) = 'seesaw_joint'" in sim.stdout
    assert '  joint_states_rate (double, Hz) = 1000.0  [0.0 .. 10000.0]' in sim.stdout
    assert '0: not published' in sim.stdout
