"""profile_player: drives the rig open loop through an input profile and reports what it saw.

For every pressure sample it publishes the profile's valve command for that sample (stamped with
the sample's stamp, so it also drives a lockstep simulator), records pressures, ground truth
(joint_measured) and estimates (estimate, when an estimator runs), and at the end logs a
summary at INFO (stderr and /rosout): rate, missing samples, ranges, and the online estimation
metrics I / M / Q of the angle (deg) and torque (N m) when estimates arrived. Optionally saves
the run in pam-simulate's format (.npz / .csv), which pam-evaluate reads.

Topics (relative, default namespace '/pam'): subscribes pressures, joint_measured, estimate;
publishes valve_command. Run `profile_player --help` for the parameters.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from rclpy.node import Node
from rclpy.task import Future

from pam_common.diagnostics import OK, WARN, DiagnosticsPublisher
from pam_common.finite_guard import FiniteGuard
from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    ConfigError,
    NodeConfig,
    ParamSpec,
    check_all,
    usage_text,
)
from pam_common.node_skeleton import node_main, parameter_values
from pam_common.qos import SAMPLE_QOS
from pam_common.topics import DEFAULT_NAMESPACE, ESTIMATE, JOINT_MEASURED, PRESSURES, VALVE_COMMAND
from pam_controller.run_recorder import RunRecorder
from pam_interfaces.msg import JointEstimate, JointMeasurement, Pressures, ValveCommand
from pam_model.valve_voltage import U_MIN

NODE_NAME = 'profile_player'
DRAIN_TIME = 0.5   # s, wait after the last command for the last estimates

PARAMETERS = (
    ParamSpec('profile', 'validation', 'string', '',
              "Input profile: 'validation' (the 130 s antagonistic profile shaped like the "
              "paper's Fig. 8); 'calibration_locked' (static holds then jumps of both valves, "
              'for pam-identify; joint locked, length len(voltages) x (hold + pair_hold) s, '
              '16 x by default); '
              "'calibration_free' (antagonistic ramps and steps at three co-contraction levels, "
              'for pam-identify; joint free).',
              choices=('validation', 'calibration_locked', 'calibration_free')),
    ParamSpec('duration', 130.0, 'double', 's',
              'Length of the profile (validation, calibration_free).', range=(0.01, 3600.0)),
    ParamSpec('hold', 10.0, 'double', 's',
              'calibration_locked: static hold per voltage (0: skip the static holds).',
              range=(0.0, 600.0)),
    ParamSpec('pair_hold', 3.0, 'double', 's',
              'calibration_locked: hold per voltage pair of the jump phase (0: skip it).',
              range=(0.0, 600.0)),
    ParamSpec('voltages', [0.0, 1.0, 2.0, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 6.5, 7.0, 7.5, 8.0,
                           9.0, 10.0], 'double[]', 'V',
              'calibration_locked: the hold voltages (at least 3, in 0..10 V; default: the '
              'nodes of the shipped valve-map table); fewer voltages make a shorter run, '
              'len(voltages) x (hold + pair_hold) s.'),
    ParamSpec('seed', 0, 'integer', '', 'Seed of the profile.', range=(0, 2 ** 31 - 1)),
    ParamSpec('rate', 1000.0, 'double', 'Hz', 'Sample rate of the rig (one command per sample).',
              range=(100.0, 10000.0)),
    ParamSpec('joint_mode', 'free', 'string', '',
              "'free' (the angle is evaluated) or 'locked' (the torque is); as the rig runs.",
              choices=('free', 'locked')),
    ParamSpec('save', '', 'string', '',
              "Save the recorded run here (.npz or .csv, pam-simulate's format); '': do not."),
    ParamSpec('wait_for_estimator', 0.0, 'double', 's',
              'Before starting, wait up to this long for an estimator to publish on estimate '
              '(so its metrics cover the whole profile); 0: start at once.',
              range=(0.0, 3600.0)),
    ParamSpec('startup_timeout', 30.0, 'double', 's',
              'Give up if no pressure sample arrives within this time.', range=(0.1, 3600.0)),
    HARDWARE_ID_PARAM,
)

SUMMARY = [
    'Open-loop profile player (pam_driver): publishes the input profile on valve_command, one',
    'command per pressure sample, records pressures, joint_measured and estimate, prints a',
    'summary with the online estimation metrics, and exits.',
]


@dataclass(frozen=True)
class PlayerConfig(NodeConfig):
    """profile_player's checked parameters (the table above: units, ranges, defaults)."""

    profile: str
    duration: float
    hold: float
    pair_hold: float
    voltages: tuple[float, ...]
    seed: int
    rate: float
    joint_mode: str
    save: str
    wait_for_estimator: float
    startup_timeout: float
    hardware_id: str


def build_config(values: dict) -> PlayerConfig:
    """Check the values against the table; ConfigError names the parameter."""
    return PlayerConfig.from_values(check_all(PARAMETERS, values))


def profile_inputs(config: PlayerConfig):
    """(N, 2) V: the chosen profile's valve voltages, one row per sample; ValueError if the
    profile's own checks reject the values."""
    from pam_model.calibration_profiles import free_calibration_profile, locked_calibration_profile
    from pam_model.profiles import validation_profile
    Ts = 1.0 / config.rate
    if config.profile == 'calibration_locked':
        return locked_calibration_profile(config.seed, config.hold, config.pair_hold,
                                          voltages=list(config.voltages), Ts=Ts).u
    if config.profile == 'calibration_free':
        return free_calibration_profile(config.seed, config.duration, Ts=Ts).u
    return validation_profile(config.seed, config.duration, Ts).u


class ProfilePlayer(Node):
    """Publishes one profile command per pressure sample until the profile ends."""

    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.config = config = parameter_values(self, PARAMETERS, check=build_config)
        try:
            self.U = profile_inputs(config)
        except ValueError as exc:
            raise ConfigError(f'profile {config.profile!r}: {exc}') from exc
        self.recorder = RunRecorder(len(self.U), locked=config.joint_mode == 'locked')
        self._wait_for_estimator = config.wait_for_estimator   # s; 0 once given up
        self.finished = Future()
        self.started = False
        self._created = self.get_clock().now()
        self._drain_timer = None
        self.guard = FiniteGuard(self.get_logger())      # non-finite -> 0 V (vent), as sim_node
        self.command_pub = self.guard.wrap(
            self.create_publisher(ValveCommand, VALVE_COMMAND, SAMPLE_QOS),
            safe={'u1': U_MIN, 'u2': U_MIN}, whole=True)
        self.create_subscription(Pressures, PRESSURES, self._on_pressures, SAMPLE_QOS)
        self.create_subscription(JointMeasurement, JOINT_MEASURED, self._on_truth, SAMPLE_QOS)
        self.create_subscription(JointEstimate, ESTIMATE, self._on_estimate, SAMPLE_QOS)
        self._startup_timer = self.create_timer(config.startup_timeout, self._on_timeout)
        self.diagnostics = DiagnosticsPublisher(self, 'profile player', config.hardware_id,
                                                self._report)
        self.diagnostics.add_check(self.guard.report)
        self.get_logger().info(
            f'playing the {config.profile} profile ({len(self.U) / config.rate:g} s, seed '
            f'{config.seed}) on {self.resolve_topic_name(VALVE_COMMAND)}, one command per '
            f'sample of {self.resolve_topic_name(PRESSURES)}')

    def _on_timeout(self) -> None:
        self.destroy_timer(self._startup_timer)
        if not self.started:
            self.get_logger().error(
                f"no pressure sample within {self.config.startup_timeout:g} s: is the rig "
                f"(sim_node or the driver) running on this ROS_DOMAIN_ID and namespace?")
            self.finished.set_result(1)

    def _on_pressures(self, msg: Pressures) -> None:
        if self.finished.done():
            return
        if not self.started:
            if not self._estimator_ready():
                return
            self.started = True
            self.get_logger().info('first pressure sample: profile started')
        j = self.recorder.add_pressures(msg.header.stamp, msg.p1, msg.p2)
        if j is None:
            return
        if j >= len(self.U):
            if self._drain_timer is None:   # let the last estimates arrive, then finish
                self._drain_timer = self.create_timer(DRAIN_TIME, self._finish_playing)
            return
        command = ValveCommand()
        command.header.stamp = msg.header.stamp
        command.header.frame_id = msg.header.frame_id
        command.u1, command.u2 = float(self.U[j, 0]), float(self.U[j, 1])
        self.recorder.set_command(j, command.u1, command.u2)
        self.command_pub.publish(command)

    def _finish_playing(self) -> None:
        self.destroy_timer(self._drain_timer)
        if not self.finished.done():
            self.finished.set_result(0)

    def _estimator_ready(self) -> bool:
        """True once an estimator publishes, or when not waiting (any more) for one."""
        wait = self._wait_for_estimator
        if wait <= 0.0 or self.count_publishers(self.resolve_topic_name(ESTIMATE)) > 0:
            return True
        waited = (self.get_clock().now() - self._created).nanoseconds * 1e-9
        if waited < wait:
            return False
        self.get_logger().warn(f'no estimator after {wait:g} s: starting without one')
        self._wait_for_estimator = 0.0
        return True

    def _on_truth(self, msg: JointMeasurement) -> None:
        self.recorder.add_truth(msg.header.stamp, msg.angle, msg.angular_velocity, msg.torque)

    def _on_estimate(self, msg: JointEstimate) -> None:
        self.recorder.add_estimate(msg.header.stamp, msg.angle, msg.torque)

    def _report(self):
        """/diagnostics: the profile, the samples played of all, the estimates received; WARN
        while waiting for the first pressure sample."""
        total = len(self.U)
        played = min(self.recorder.n, total)
        values = {'profile': self.config.profile, 'samples played': played,
                  'samples in the profile': total,
                  'progress (%)': 100.0 * played / total if total else 100.0,
                  'repeated samples': self.recorder.duplicates,
                  'estimates received': self.recorder.estimates_received}
        if not self.started:
            return WARN, 'waiting for the first pressure sample', values
        if played >= total:
            return OK, 'profile played', values
        return OK, f'playing: {played} of {total} samples', values

    def finish(self) -> int:
        """Log the summary at INFO (and save the run); returns the exit code."""
        if not self.started:
            return 1
        logger = self.get_logger()
        for line in self.recorder.summary(self.config.rate):
            logger.info(line)
        for topic, count in self.guard.counts.items():
            if count:
                logger.info(f'non-finite values substituted on {topic}: {count}')
        if self.config.save:
            path = self.recorder.save(self.config.save, 1.0 / self.config.rate)
            logger.info(f'saved the run to {path}')
        return 0


def main(args=None) -> int:
    return node_main(ProfilePlayer, NODE_NAME, usage_text(NODE_NAME, SUMMARY, PARAMETERS, examples=[
        f'{NODE_NAME} --ros-args -p duration:=30.0 -p save:=/tmp/run.npz',
        f'{NODE_NAME} --ros-args -p profile:=calibration_locked   # joint locked, bag_record on']),
        args)


if __name__ == '__main__':
    sys.exit(main())
