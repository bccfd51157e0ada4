"""pi_node as a real process fed by the test's probe: one command per estimate with its stamp,
run-time gain changes (valid accepted, invalid rejected), the enable service, the feedback
timeout, a reference switching the mode; a huge reference clamped to the envelope, nothing
non-finite published."""

import math
import time

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from std_srvs.srv import SetBool

from pam_common.diagnostics import WARN, status_values
from pam_common.stamps import ns_stamp
from pam_common.testing import diagnostic_statuses, feed_until_answered, wait_until
from pam_interfaces.msg import ControllerState, JointEstimate, Reference, ValveCommand


def call(probe, srv_type, name, request):
    client = probe.client(srv_type, name)
    assert client.wait_for_service(timeout_sec=20.0), name
    future = client.call_async(request)
    assert wait_until(future.done, 10.0), name
    return future.result()


def double_param(name, value):
    return Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                     double_value=value))


def start_pi_node(node_process, probe, *params):
    """pi_node with `-p` params, the probe's subscriptions and publishers, and feed(n, angle,
    torque, start): n estimates 1 ms apart from stamp `start` (s). Returns once a command and a
    controller state have answered an estimate (pam_common.testing.feed_until_answered), with
    both collectors cleared; the tests' own estimates start at stamp 1 s."""
    pi = node_process('pi_node', 'pam_controller', *params)
    commands = probe.subscribe(ValveCommand, '/pam/valve_command')
    states = probe.subscribe(ControllerState, '/pam/controller_state')
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics')
    estimates = probe.publisher(JointEstimate, '/pam/estimate')
    references = probe.publisher(Reference, '/pam/reference')
    # both ways, as far as the probe can see: its publishers matched pi_node's subscriptions,
    # its subscriptions pi_node's publishers (pi_node's side of the match it cannot see: see
    # feed_until_answered)
    assert wait_until(lambda: estimates.get_subscription_count() > 0
                      and references.get_subscription_count() > 0
                      and commands.subscription.get_publisher_count() > 0
                      and states.subscription.get_publisher_count() > 0, 60.0), pi.stderr

    def feed(n, angle=0.0, torque=0.0, start=1.0):
        for k in range(n):
            msg = JointEstimate(angle=angle, torque=torque)
            t = start + k * 0.001
            msg.header.stamp = ns_stamp(round(t * 1e9))
            estimates.publish(msg)
            time.sleep(0.001)
    # stamps below 1 s for the whole timeout (0.02 s apart in time, 1 ms in stamp)
    feed_until_answered(lambda k: feed(1, start=0.01 + k * 0.001), (commands, states))
    return pi, commands, states, diagnostics, references, feed


def test_pi_node_commands_gains_enable_timeout(node_process, probe):
    pi, commands, states, _, references, feed = start_pi_node(
        node_process, probe, '-p', 'initial_reference:=0.1', '-p', 'feedback_timeout:=0.2')

    feed(50)
    pi.wait_for(lambda: len(commands) >= 50, 20.0, '50 commands')
    last = commands.messages()[-1]
    assert last.header.stamp.sec == 1 and last.u1 > 5.5 > last.u2     # e > 0 raises u1
    assert abs(last.u1 + last.u2 - 11.0) < 1e-9
    state = states.messages()[-1]
    assert state.error == 0.1 and state.p_term == 40.0 * 0.1 and not state.saturated

    assert last.header.frame_id == 'pam_joint'

    bad = call(probe, SetParameters, '/pam/pi_node/set_parameters',
               SetParameters.Request(parameters=[double_param('kp_angle', -1.0)]))
    assert not bad.results[0].successful
    bad = call(probe, SetParameters, '/pam/pi_node/set_parameters',
               SetParameters.Request(parameters=[double_param('u_min', 9.9),
                                                 double_param('u_max', 5.0)]))
    assert not any(result.successful for result in bad.results)
    bad = call(probe, SetParametersAtomically, '/pam/pi_node/set_parameters_atomically',
               SetParametersAtomically.Request(parameters=[double_param('kp_angle', 20.0),
                                                           double_param('u_min', 9.9),
                                                           double_param('u_max', 5.0)]))
    assert not bad.result.successful and 'u_min' in bad.result.reason
    commands.clear()                                   # the running gains are untouched
    feed(20, start=1.5)
    pi.wait_for(lambda: len(commands) >= 20, 20.0, 'commands after the rejected changes')
    assert math.isclose(states.messages()[-1].p_term, 40.0 * 0.1)
    good = call(probe, SetParameters, '/pam/pi_node/set_parameters',
                SetParameters.Request(parameters=[double_param('kp_angle', 10.0)]))
    assert good.results[0].successful
    commands.clear()
    feed(20, start=2.0)
    pi.wait_for(lambda: len(commands) >= 20, 20.0, 'commands with the new gain')
    assert math.isclose(states.messages()[-1].p_term, 10.0 * 0.1)

    commands.clear()                                   # no feedback for 0.2 s -> safe command
    pi.wait_for(lambda: len(commands) >= 1, 5.0, 'the safe command after the timeout')
    assert (commands.messages()[-1].u1, commands.messages()[-1].u2) == (5.5, 5.5)

    assert call(probe, SetBool, '/pam/pi_node/enable', SetBool.Request(data=False)).success
    commands.clear()
    feed(10, start=3.0)
    pi.wait_for(lambda: len(commands) >= 10, 20.0, 'commands while disabled')
    assert all((c.u1, c.u2) == (5.5, 5.5) for c in commands.messages())
    assert call(probe, SetBool, '/pam/pi_node/enable', SetBool.Request(data=True)).success

    references.publish(Reference(mode=Reference.TORQUE, value=1.0))
    pi.wait_for(lambda: 'integral reset' in pi.stderr + pi.stdout, 10.0, 'the mode switch log')
    states.clear()
    feed(10, torque=0.5, start=4.0)
    pi.wait_for(lambda: len(states) >= 10, 20.0, 'torque-mode states')
    state = states.messages()[-1]
    assert state.mode == Reference.TORQUE and state.error == 0.5
    assert pi.alive()


def test_a_huge_reference_is_clamped_and_nothing_non_finite_is_published(node_process, probe):
    """The issue: with back-calculation, one reference of 1e308 gave (nan, nan) commands until
    ~/enable false -> true, and /diagnostics said OK. Now the reference is clamped to the
    rig's envelope (+-25 deg), counted on /diagnostics (WARN), and every field stays finite."""
    pi, commands, states, diagnostics, references, feed = start_pi_node(
        node_process, probe, '-p', 'anti_windup:=back_calculation', '-p',
        'initial_reference:=0.1', '-p', 'frame_id:=joint2')
    def clamped() -> int:
        statuses = diagnostic_statuses(diagnostics, 'pi_node')
        return int(status_values(statuses[-1])['references clamped to the envelope']) \
            if statuses else 0

    feed(20, start=1.0)
    pi.wait_for(lambda: len(commands) >= 20, 20.0, 'commands before the huge reference')
    for n, (start, huge) in enumerate(((2.0, 1e308), (3.0, 5e306)), 1):
        references.publish(Reference(mode=Reference.ANGLE, value=huge))
        # by /diagnostics (about 1 Hz): the clamp's log line is throttled, and the first one
        # stays in the output, so the log cannot tell the second clamp from the first
        pi.wait_for(lambda n=n: clamped() >= n, 10.0, f'clamp {n} on /diagnostics')
        feed(100, start=start)
    references.publish(Reference(mode=Reference.ANGLE, value=0.05))     # a sane one again
    feed(300, start=4.0)
    pi.wait_for(lambda: len(states) >= 420, 20.0, 'every command and state')
    fields = ('reference', 'feedback', 'error', 'p_term', 'i_term', 'u1', 'u2')
    for state in states.messages():
        assert all(math.isfinite(getattr(state, f)) for f in fields), state
    assert all(math.isfinite(c.u1) and math.isfinite(c.u2) for c in commands.messages())
    assert {c.header.frame_id for c in commands.messages()} == {'joint2'}   # the parameter
    assert max(s.reference for s in states.messages()) == math.radians(25.0)
    last = states.messages()[-1]
    assert last.reference == 0.05 and last.error == 0.05 and pi.alive()

    warned = [s for s in diagnostic_statuses(diagnostics, 'pi_node')
              if s.level == WARN and 'envelope' in s.message]
    assert [status_values(s)['references clamped to the envelope'] for s in warned][-1] == '2'
