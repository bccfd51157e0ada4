"""pi_node: sensor-less PI control of the joint angle or torque, a thin wrapper over ControlLoop.

Run `pi_node --help` for the parameters. Topics resolve under the node namespace ('/pam'):

    estimate          pam_interfaces/JointEstimate     subscribed: the feedback (default)
    joint_measured    pam_interfaces/JointMeasurement  subscribed instead when feedback:=measured
                                                       (comparison runs only)
    reference         pam_interfaces/Reference         subscribed: mode ANGLE (rad) / TORQUE (N m)
    valve_command     pam_interfaces/ValveCommand      published once per feedback sample, with
                                                       the feedback's stamp
    controller_state  pam_interfaces/ControllerState   published with every command while a
                                                       subscription matches (not built else)
    /diagnostics      diagnostic_msgs/DiagnosticArray  about 1 Hz; with the estimate's sample
                                                       counter: samples lost (WARN over
                                                       lost_samples_warn_ratio in the period)
Service ~/enable (std_srvs/SetBool): false sends the valves to safe_command and holds them there.
No feedback for feedback_timeout s (wall clock) also sends safe_command, and /diagnostics says
so. Gains, limits and the anti-windup scheme can be changed at run time (ros2 param set); bad
values (negative, NaN, u_min >= u_max, beta outside the limits) are rejected with a reason and
leave the running ones untouched: the on-set callback only checks, the post-set callback applies
(ControlLoop.set_gains).
A reference outside the rig's envelope (control_loop.ENVELOPE) is clamped to it, counted and
reported (WARN); a non-finite one is ignored. Nothing non-finite is published (FiniteGuard: a
command -> safe_command, a state field -> 0, u1/u2 -> safe_command; counted on /diagnostics).
At DEBUG (`--ros-args --log-level pam.pi_node:=debug`): the output going into saturation and out
of it (with the anti-windup at work), and reference changes (at most one line a second).
"""

from __future__ import annotations

import math
import sys
import time

from rcl_interfaces.msg import SetParametersResult
from rclpy.logging import LoggingSeverity
from std_msgs.msg import Header
from std_srvs.srv import SetBool

from pam_common.diagnostics import OK, WARN, DiagnosticsPublisher
from pam_common.fast_messages import builder
from pam_common.finite_guard import FiniteGuard
from pam_common.links import LinkedNode
from pam_common.node_params import ConfigError, usage_text
from pam_common.node_skeleton import Component, component_main, parameter_values
from pam_common.qos import SAMPLE_QOS
from pam_common.realtime_knobs import RealtimeKnobs
from pam_common.sample_gaps import SampleGaps
from pam_common.stamps import stamp_ns
from pam_common.throttled_log import ThrottledLogs
from pam_common.topics import (
    CONTROLLER_STATE,
    DEFAULT_NAMESPACE,
    ESTIMATE,
    JOINT_MEASURED,
    REFERENCE,
    VALVE_COMMAND,
)
from pam_interfaces.msg import (
    ControllerState,
    JointEstimate,
    JointMeasurement,
    Reference,
    ValveCommand,
)

from .control_loop import ANGLE, MODE_NAMES
from .pi_config import NODE_NAME, PARAMETERS, SUMMARY, PiConfig

build_header, build_command = builder(Header), builder(ValveCommand)


class PiNode(LinkedNode):
    """One valve command per feedback sample."""

    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.config = parameter_values(self, PARAMETERS, check=PiConfig.from_values)
        self.loop = self.config.make_loop()
        # the knobs of the 1 kHz path (pam_common.realtime_knobs): this thread is the executor's
        self.realtime = RealtimeKnobs(self.get_logger(), self.config.realtime)
        self.realtime.apply_to_executor()
        self.gaps = SampleGaps()              # of the estimates' sample counter
        self.logs = ThrottledLogs(self.get_logger(), 1.0)
        self._log_reference = self.logs.new()
        self.guard = FiniteGuard(self.get_logger())
        safe = dict(zip(('u1', 'u2'), self.loop.safe_command, strict=True))
        self.command_pub = self.guard.wrap(
            self.create_publisher(ValveCommand, VALVE_COMMAND, SAMPLE_QOS), safe=safe, whole=True)
        self.state_pub = self.guard.wrap(      # for the outside: only while subscribed
            self.create_publisher(ControllerState, CONTROLLER_STATE, SAMPLE_QOS), safe=safe,
            subscribed_only=True)
        if self.config.feedback == 'estimate':
            self.create_subscription(JointEstimate, ESTIMATE, self._on_estimate, SAMPLE_QOS)
        else:
            self.create_subscription(JointMeasurement, JOINT_MEASURED, self._on_measured,
                                     SAMPLE_QOS)
            self.get_logger().warn('feedback from joint_measured: a comparison run, not '
                                   'sensor-less control')
        self.create_subscription(Reference, REFERENCE, self._on_reference, SAMPLE_QOS)
        self.create_service(SetBool, '~/enable', self._on_enable)
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self.diagnostics = DiagnosticsPublisher(self, 'PI controller',
                                                self.config.hardware_id, self._report)
        self.diagnostics.add_check(self.guard.report)
        self.diagnostics.add_check(self._clamp_report)
        self.diagnostics.add_check(
            lambda: self.gaps.report(self.config.lost_samples_warn_ratio))
        self.diagnostics.add_check(self.logs.report)
        self.diagnostics.add_check(self.realtime.report)
        self.create_timer(0.05, self._watchdog)
        self._last_feedback = None            # monotonic time of the last feedback
        self._stale = False
        self.commands = 0
        self.saturated = 0
        self._was_saturated = False           # the last command's (DEBUG lines at the edges)
        self._saturated_since = 0             # self.saturated when it went into saturation
        self._reported_clamps = 0
        self.get_logger().info(self.config.describe())

    # --- messages -------------------------------------------------------------------------------
    def _on_estimate(self, msg: JointEstimate) -> None:
        self.gaps.update(msg.sample)
        value = msg.angle if self.loop.mode == ANGLE else msg.torque
        self._control(value, msg.header)

    def _on_measured(self, msg: JointMeasurement) -> None:
        value = msg.angle if self.loop.mode == ANGLE else msg.torque
        self._control(value, msg.header)

    def _control(self, value: float, header) -> None:
        self._last_feedback = time.monotonic()
        if self._stale:
            self._stale = False
            self.get_logger().info('feedback is back: control resumed')
        out = self.loop.on_feedback(value, stamp_ns(header.stamp))
        if out.saturated != self._was_saturated:      # an edge: rare, checked per sample
            self._was_saturated = out.saturated
            if self.get_logger().is_enabled_for(LoggingSeverity.DEBUG):
                self._debug_saturation(out)
        self._publish(out, header.stamp, value)

    def _publish(self, out, stamp, feedback: float) -> None:
        command = build_command(build_header(stamp, self.config.frame_id), float(out.u1),
                                float(out.u2))
        self.command_pub.publish(command)
        self.commands += 1
        self.saturated += int(out.saturated)
        if not self.state_pub.wanted():
            return
        state = ControllerState(mode=self.loop.mode, reference=float(self.loop.reference or 0.0),
                                feedback=float(feedback) if math.isfinite(feedback) else 0.0,
                                error=out.error, p_term=out.p_term, i_term=out.i_term,
                                u1=out.u1, u2=out.u2, saturated=out.saturated)
        state.header = command.header
        self.state_pub.publish(state)

    def _debug_saturation(self, out) -> None:
        """DEBUG: the output went into saturation, or came out of it."""
        if out.saturated:
            self._saturated_since = self.saturated
            how = ('the integral frozen while the error pushes further'
                   if self.config.anti_windup == 'conditional' else
                   f'the integral pulled back (tracking_time {self.config.tracking_time:g} s)')
            limits = self.config.angle
            self.get_logger().debug(
                f'saturated: u1 {out.u1:.3f} V, u2 {out.u2:.3f} V at the limits '
                f'[{limits.u_min:g}, {limits.u_max:g}] V (error {out.error:.4g}, '
                f'P {out.p_term:.3f} V, I {out.i_term:.3f} V); anti-windup: {how}')
        else:
            self.get_logger().debug(
                f'out of saturation after {self.saturated - self._saturated_since} samples: '
                f'u1 {out.u1:.3f} V, u2 {out.u2:.3f} V, I {out.i_term:.3f} V')

    def _on_reference(self, msg: Reference) -> None:
        previous = self.loop.reference
        message = self.loop.set_reference(msg.mode, msg.value)
        if message.startswith('mode'):
            self.get_logger().info(message)
        elif message:
            self._log_reference(message)
        if self.loop.reference != previous and self.get_logger().is_enabled_for(
                LoggingSeverity.DEBUG):
            # a profile changes it at every message (reference_node: 100 Hz): one line a second
            before = 'none' if previous is None else f'{previous:g}'
            self.get_logger().debug(
                f'{MODE_NAMES[self.loop.mode]} reference {before} -> {self.loop.reference:g} '
                '(changes within 1 s of a logged one are not logged)', throttle_duration_sec=1.0)

    def _on_enable(self, request, response):
        self.loop.set_enabled(request.data)
        response.success = True
        response.message = 'control enabled' if request.data else \
            f'control disabled: valves at safe_command {list(self.loop.safe_command)} V'
        self.get_logger().info(response.message)
        if not request.data:
            self._publish(self.loop.safe_output(), self.get_clock().now().to_msg(), math.nan)
        return response

    def _watchdog(self) -> None:
        if self._last_feedback is None or self._stale:
            return
        if time.monotonic() - self._last_feedback > self.config.feedback_timeout:
            self._stale = True
            self.get_logger().warn(
                f'no feedback for {self.config.feedback_timeout:g} s: valves to safe_command '
                f'{list(self.loop.safe_command)} V')
            self._publish(self.loop.safe_output(), self.get_clock().now().to_msg(), math.nan)

    # --- run-time parameters: on-set checks, post-set applies ------------------------------------
    def _proposed(self, params) -> PiConfig:
        """The configuration after `params`, checked as at start (a ConfigError, ValueError or
        TypeError naming the problem)."""
        return self.config.changed({p.name: p.value for p in params})

    def _check_parameters(self, params) -> SetParametersResult:
        """rclpy's on-set callback: accept or reject with a reason; nothing changes here."""
        try:
            self._proposed(params)
        except (ConfigError, ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, params) -> None:
        """rclpy's post-set callback: the accepted values reach the running controllers."""
        config = self._proposed(params)
        self.loop.set_gains(config.angle, config.torque, config.anti_windup,
                            config.tracking_time)
        self.config = config
        self.get_logger().info('parameters changed: ' + ', '.join(
            f'{p.name}={p.value}' for p in params))

    def _clamp_report(self):
        """The references clamped to the envelope: WARN while some were in the last period."""
        clamped = self.loop.clamped_references - self._reported_clamps
        self._reported_clamps += clamped
        problem = (f"{clamped} references outside the rig's envelope clamped to it in the last "
                   'period') if clamped else ''
        return WARN, problem, {'references clamped to the envelope':
                               self.loop.clamped_references}

    def _report(self):
        age = (time.monotonic() - self._last_feedback) if self._last_feedback else math.inf
        values = {'mode': MODE_NAMES[self.loop.mode], 'enabled': self.loop.enabled,
                  'reference': self.loop.reference if self.loop.reference is not None else 'none',
                  'commands published': self.commands, 'saturated commands': self.saturated,
                  'integral term (V)': self.loop.controller.i_term,
                  'time since feedback (s)': age, 'implausible dt (skipped)': self.loop.bad_dt,
                  'non-finite feedback': self.loop.bad_feedback,
                  'feedback source': self.config.feedback}
        if not self.loop.enabled:
            return WARN, 'disabled: valves at safe_command', values
        if self._last_feedback is None:
            return WARN, 'waiting for feedback', values
        if self._stale:
            return WARN, f'no feedback for {age:.2f} s: valves at safe_command', values
        return OK, 'controlling', values


#: The node as a component of a composed process (pam_container, pam-bringup --composed).
COMPONENT = Component(NODE_NAME, PiNode)


def main(args=None) -> int:
    return component_main(COMPONENT, usage_text(NODE_NAME, SUMMARY, PARAMETERS, examples=[
        f'{NODE_NAME} --ros-args -p mode:=torque -p kp_torque:=3.0',
        'ros2 param set /pam/pi_node kp_angle 30.0']), args)

if __name__ == '__main__':
    sys.exit(main())
