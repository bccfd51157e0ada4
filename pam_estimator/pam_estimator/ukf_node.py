"""ukf_node: the sensor-less joint estimator, a thin ROS wrapper around EstimatorCore / PamUkf.

Run `ukf_node --help` for the parameters. Topics resolve under the node namespace ('/pam' unless
remapped with `--ros-args -r __ns:=/other`):

    pressures      pam_interfaces/Pressures        subscribed: one filter step per sample
    valve_command  pam_interfaces/ValveCommand     subscribed: held as u(k-1)
    supply_pressure  sensor_msgs/FluidPressure     subscribed with use_supply_pressure only:
                                                   P_tank (Pa abs) of the prediction (a reading
                                                   over 0.1 s from the sample's stamp or not
                                                   finite: the model's P_tank, counted, WARN)
    estimate       pam_interfaces/JointEstimate    published for every sample, with the sample's
                                                   stamp and counter (sample), covariance and
                                                   filter health
    estimate/joint_states  sensor_msgs/JointState  the estimate for the standard tools: one joint
                                                   (joint_name), position = angle (rad), velocity
                                                   = angular velocity (rad/s), effort = torque
                                                   (N m), the estimate's stamps; every sample, or
                                                   fewer (joint_states_rate)
    /diagnostics   diagnostic_msgs/DiagnosticArray about 1 Hz: input rate, staleness, NIS,
                                                   covariance trace, rejected samples, step time,
                                                   samples lost (gaps in Pressures.sample; WARN
                                                   over lost_samples_warn_ratio in the period)
Service ~/reset (std_srvs/Trigger) restarts the filter from initial_state and P(0).
QoS: reliable, keep last 100 (a 1 kHz stream across processes loses nothing with that depth).
The compiled filter kernel is loaded (and compiled on the very first run) before the
subscriptions are created, so the first samples are not stalled.
Warnings on the 1 kHz path (bad commands, unusable samples, time going backwards) are throttled
to one line a second each (pam_common.throttled_log), the lines left out counted on /diagnostics.
At DEBUG (`--ros-args --log-level pam.ukf_node:=debug`: the node's logger, namespace.name) every
filter reset and every rejected sample (NIS gate or invalid) is one line, unthrottled.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from rclpy.logging import LoggingSeverity
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Header
from std_srvs.srv import Trigger

from pam_common.diagnostics import ERROR, OK, WARN, DiagnosticsPublisher
from pam_common.fast_messages import builder
from pam_common.finite_guard import FiniteGuard
from pam_common.joint_states import JointStates
from pam_common.links import LinkedNode
from pam_common.node_skeleton import Component, component_main, parameter_values
from pam_common.qos import SAMPLE_QOS
from pam_common.realtime_knobs import RealtimeKnobs
from pam_common.sample_gaps import SampleGaps
from pam_common.stamps import stamp_ns
from pam_common.throttled_log import ThrottledLogs
from pam_common.topics import (
    DEFAULT_NAMESPACE,
    ESTIMATE,
    ESTIMATE_JOINT_STATES,
    PRESSURES,
    SUPPLY_PRESSURE,
    VALVE_COMMAND,
)
from pam_interfaces.msg import JointEstimate, Pressures, ValveCommand

from .estimator_core import EstimatorCore
from .ukf_config import PARAMETERS, build_config, usage_text

NODE_NAME = 'ukf_node'
LOG_THROTTLE = 1.0   # s
build_header, build_estimate = builder(Header), builder(JointEstimate)


class UkfNode(LinkedNode):
    """Subscribes pressures and valve commands, publishes one JointEstimate per sample."""

    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        config = parameter_values(self, PARAMETERS, check=build_config)
        # the knobs of the 1 kHz path (pam_common.realtime_knobs): this thread is the executor's
        self.realtime = RealtimeKnobs(self.get_logger(), config.realtime)
        self.realtime.apply_to_executor()
        self.core = EstimatorCore(config.ukf, config.initial_command,
                                  config.use_supply_pressure)
        self.frame_id = config.frame_id
        self.stale_timeout = config.stale_timeout
        lost_warn_ratio = config.lost_samples_warn_ratio
        self.gaps = SampleGaps()
        self.logs = ThrottledLogs(self.get_logger(), LOG_THROTTLE)
        (self._log_command, self._log_reset, self._log_rejected,
         self._log_supply) = (self.logs.new() for _ in range(4))
        for line in config.summary:
            self.get_logger().info(line)
        self._warm_up()
        self.guard = FiniteGuard(self.get_logger())      # non-finite -> the last finite value
        self.estimate_pub = self.guard.wrap(
            self.create_publisher(JointEstimate, ESTIMATE, SAMPLE_QOS), hold=True)
        # the estimate as JointState, from the message after its guard (pam_common.joint_states)
        rate = config.joint_states_rate
        self.joint_states = JointStates(
            self.guard.wrap(self.create_publisher(JointState, ESTIMATE_JOINT_STATES, SAMPLE_QOS))
            if rate else None, JointState(), config.joint_name, self.frame_id, rate,
            1.0 / config.ukf.model.h)          # one filter step per sample
        self.create_subscription(ValveCommand, VALVE_COMMAND, self._on_command, SAMPLE_QOS)
        self.create_subscription(Pressures, PRESSURES, self._on_pressures, SAMPLE_QOS)
        if self.core.use_supply:
            self.create_subscription(FluidPressure, SUPPLY_PRESSURE, self._on_supply, SAMPLE_QOS)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.diagnostics = DiagnosticsPublisher(self, 'UKF estimator',
                                                config.hardware_id, self._report)
        self.diagnostics.add_check(self.guard.report)
        self.diagnostics.add_check(lambda: self.gaps.report(lost_warn_ratio))
        self.diagnostics.add_check(self.logs.report)
        self.diagnostics.add_check(self.realtime.report)
        self.get_logger().info(
            f'estimating: {self.resolve_topic_name(PRESSURES)} + '
            f'{self.resolve_topic_name(VALVE_COMMAND)} -> {self.resolve_topic_name(ESTIMATE)}'
            + (f', {self.joint_states.describe()}' if rate else '')
            + (f', P_tank from {self.resolve_topic_name(SUPPLY_PRESSURE)}'
               if self.core.use_supply else ''))

    def _warm_up(self) -> None:
        """Run the compiled kernels once (loads numba's cache or compiles) on a throw-away copy:
        with use_supply_pressure, both paths (a reading, none)."""
        ukf = self.core.ukf
        x, P = ukf.x.copy(), ukf.P.copy()
        ukf.step(ukf.x[2:4], self.core.u_prev)
        if self.core.use_supply:
            ukf.step(ukf.x[2:4], self.core.u_prev, ukf.model.params.P_tank)
        ukf.reset(x, P)

    def _on_command(self, msg: ValveCommand) -> None:
        if not self.core.on_command(msg.u1, msg.u2):
            self._log_command(f'valve command ({msg.u1}, {msg.u2}) V outside [0, 10] or not '
                              f'finite: used sanitised ({self.core.u_prev[0]:g}, '
                              f'{self.core.u_prev[1]:g}) V ({self.core.bad_commands} so far)')

    def _on_supply(self, msg: FluidPressure) -> None:
        self.core.on_supply(msg.fluid_pressure, stamp_ns(msg.header.stamp))

    def _on_pressures(self, msg: Pressures) -> None:
        self.gaps.update(msg.sample)
        event = self.core.on_pressures(msg.p1, msg.p2, stamp_ns(msg.header.stamp),
                                        msg.sample or None)   # 0: no counter
        if event.output is None:
            return
        if self.core.supply_fallback:
            self._log_supply(f'{self.core.supply_fallback}: nominal P_tank used '
                             f'({self.core.supply_fallbacks} samples so far)')
        if event.kind == 'reset':
            self._log_reset(event.message)
            if self.get_logger().is_enabled_for(LoggingSeverity.DEBUG):
                self._debug_reset(msg, event.message)
        out = event.output
        if out.update_skipped:
            if self.core.ukf.rejected_samples:
                self._log_rejected(f'pressure sample ({msg.p1}, {msg.p2}) Pa not usable: '
                                   f'update skipped ({self.core.ukf.rejected_samples} rejected '
                                   'so far)')
            if self.get_logger().is_enabled_for(LoggingSeverity.DEBUG):
                self._debug_skipped(msg, out.nis)
        # built in one step (pam_common.fast_messages): 0.9 us, the generated constructor's 5.1
        angle, velocity, p1, p2 = out.x[:4].tolist()
        est = build_estimate(
            header=build_header(msg.header.stamp, self.frame_id),
            angle=angle, angular_velocity=velocity, torque=float(out.torque), p1=p1, p2=p2,
            force1=float(out.force1), force2=float(out.force2),
            covariance=out.P[:4, :4].flatten(),       # a copy, without the bias states
            torque_variance=float(out.torque_variance), subsystem=int(out.subsystem),
            nis=float(out.nis),
            rejected_samples=self.core.ukf.rejected_samples + self.core.ukf.gated_samples,
            update_skipped=bool(out.update_skipped), sample=msg.sample)
        self.estimate_pub.publish(est)
        self.joint_states.publish(est.header.stamp, est.sample, est.angle,
                                  est.angular_velocity, est.torque)

    # DEBUG lines (--log-level debug): every decision, unthrottled; the caller checks the level
    # first, so nothing is formatted on the 1 kHz path while DEBUG is off
    def _debug_reset(self, msg: Pressures, why: str) -> None:
        self.get_logger().debug(
            f'filter reset at sample {msg.sample} (stamp {stamp_ns(msg.header.stamp)} ns): {why} '
            f'({self.core.time_resets} resets so far)')

    def _debug_skipped(self, msg: Pressures, nis: float) -> None:
        ukf = self.core.ukf
        if ukf.nis_gate > 0.0 and nis > ukf.nis_gate:
            why = (f'rejected by the NIS gate: NIS {nis:.1f} > nis_gate {ukf.nis_gate:g} '
                   f'({ukf.gated_samples} gated so far)')
        else:
            why = (f'rejected as invalid (outside [{ukf.y_range[0]:g}, {ukf.y_range[1]:g}] Pa or '
                   f'not finite; {ukf.rejected_samples} so far)')
        self.get_logger().debug(f'sample {msg.sample}: pressures ({msg.p1:g}, {msg.p2:g}) Pa '
                                f'{why}: prediction only')

    def _on_reset(self, request, response):
        self.core.reset()
        response.success = True
        response.message = 'filter reset to initial_state and the initial covariance'
        self.get_logger().info(response.message)
        return response

    def _report(self):
        core, ukf = self.core, self.core.ukf
        median, worst = core.step_time_stats()
        age = core.seconds_since_input()
        out = core.last_output
        trace = float(np.trace(ukf.P))
        values = {
            'input rate (Hz)': core.input_rate(),
            'time since last pressure sample (s)': age,
            'largest input gap (ms)': core.largest_input_gap() * 1e3,
            'samples estimated': core.samples,
            'duplicate samples (estimate repeated)': core.duplicates,
            'missing samples coasted through': core.coasted,
            'resets on time going backwards': core.time_resets,
            'valve commands received': core.commands,
            'bad valve commands': core.bad_commands,
            'rejected samples (invalid)': ukf.rejected_samples,
            'rejected samples (NIS gate)': ukf.gated_samples,
            'covariance repairs': ukf.repairs,
            'last NIS': out.nis if out else 0.0,
            'covariance trace': trace,
            'step time median (us)': median * 1e6,
            'step time max (us)': worst * 1e6,
            'joint mode': 'locked' if ukf.model.locked else 'free',
            'model extensions': ukf.extensions.describe(),
        }
        if ukf.bias_states is not None:
            values['sensor offsets b1, b2 (kPa)'] = f'{ukf.x[4] / 1e3:.2f}, {ukf.x[5] / 1e3:.2f}'

        if core.use_supply:
            values['supply pressure (kPa abs)'] = (core.supply[0] / 1e3 if core.supply
                                                   else float('nan'))
            values['samples with the measured supply'] = core.supply_used
            values['samples with the nominal P_tank (supply stale or not finite)'] = (
                core.supply_fallbacks)
        if core.samples == 0:
            return WARN, 'waiting for pressures', values
        if not math.isfinite(trace):
            return ERROR, 'covariance not finite', values
        if age > self.stale_timeout:
            return WARN, f'input stale: no pressures for {age:.2f} s', values
        return OK, 'estimating', values


#: The node as a component of a composed process (pam_container, pam-bringup --composed).
COMPONENT = Component(NODE_NAME, UkfNode)


def main(args=None) -> int:
    return component_main(COMPONENT, usage_text(), args)

if __name__ == '__main__':
    sys.exit(main())
