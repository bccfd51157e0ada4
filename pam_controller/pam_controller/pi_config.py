"""pi_node's configuration, without ROS: the parameter table (defaults, --help, checks) and the
frozen PiConfig built once from its values (pam_driver.driver_core.SafetyConfig is the pattern;
rosbag2's RecordOptions built from node parameters is the anchor). A run-time change of the
gains or limits builds a new PiConfig (PiConfig.changed), checked as at start-up, so the
running one is never half-changed.

Units: gains V/rad and V/(rad s) (angle) or V/(N m) and V/(N m s) (torque); voltages V; times s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    ConfigError,
    ParamSpec,
    check_all,
    check_command,
    defaults,
)
from pam_common.realtime_knobs import REALTIME_PARAMS, RealtimeRequest, check_realtime
from pam_common.sample_gaps import WARN_RATIO_PARAM
from pam_model.rest import BETA, REST_COMMAND

from .control_loop import ANGLE, MODE_NAMES, TORQUE, ControlLoop
from .pi import ANTI_WINDUP, PiGains, validate_gains

NODE_NAME = 'pi_node'
GAIN_RANGE = (0.0, 1.0e4)
RUNTIME = dict(read_only=False)

PARAMETERS = (
    ParamSpec('mode', 'angle', 'string', '',
              'Initial mode until a reference says otherwise.', choices=('angle', 'torque')),
    ParamSpec('initial_reference', 0.0, 'double', 'rad or N m',
              'Reference used until the first reference message.', range=(-10.0, 10.0)),
    ParamSpec('kp_angle', 40.0, 'double', 'V/rad', 'Proportional gain, angle mode.',
              range=GAIN_RANGE, **RUNTIME),
    ParamSpec('ki_angle', 50.0, 'double', 'V/(rad s)', 'Integral gain, angle mode.',
              range=GAIN_RANGE, **RUNTIME),
    ParamSpec('kp_torque', 6.0, 'double', 'V/(N m)', 'Proportional gain, torque mode.',
              range=GAIN_RANGE, **RUNTIME),
    ParamSpec('ki_torque', 8.0, 'double', 'V/(N m s)', 'Integral gain, torque mode.',
              range=GAIN_RANGE, **RUNTIME),
    ParamSpec('beta', BETA, 'double', 'V', 'Bias voltage of both valves.', range=(0.0, 10.0),
              **RUNTIME),
    ParamSpec('u_min', 0.0, 'double', 'V', 'Lower output limit.', range=(0.0, 10.0), **RUNTIME),
    ParamSpec('u_max', 10.0, 'double', 'V', 'Upper output limit.', range=(0.0, 10.0), **RUNTIME),
    ParamSpec('anti_windup', 'conditional', 'string', '',
              "'conditional' (freeze the integral while saturated further) or 'back_calculation'.",
              choices=ANTI_WINDUP, **RUNTIME),
    ParamSpec('tracking_time', 0.1, 'double', 's', 'Back-calculation time constant.',
              range=(1e-4, 100.0), **RUNTIME),
    ParamSpec('dt_max', 0.1, 'double', 's',
              'Largest plausible time between two feedback stamps; a larger (or non-positive) '
              'step does not update the integral.', range=(1e-4, 10.0)),
    ParamSpec('feedback', 'estimate', 'string', '',
              "'estimate' (sensor-less, the UKF's estimate) or 'measured' (joint_measured: "
              'comparison runs only).', choices=('estimate', 'measured')),
    ParamSpec('feedback_timeout', 0.1, 'double', 's',
              'No feedback for this long (wall clock): the valves go to safe_command.',
              range=(0.001, 60.0)),
    ParamSpec('safe_command', list(REST_COMMAND), 'double[]', 'V',
              'Valve voltages when disabled or without feedback: by default both valves at beta '
              '(equal co-contraction, the joint rests near 0 deg).'),
    ParamSpec('enabled', True, 'bool', '', 'Control at start (else: safe_command until enabled).'),
    ParamSpec('frame_id', 'pam_joint', 'string', '',
              'frame_id of the published headers (valve_command, controller_state).'),
    WARN_RATIO_PARAM,
    HARDWARE_ID_PARAM,
    *REALTIME_PARAMS,
)
SUMMARY = [
    'Sensor-less PI controller (pam_controller): u1 = beta + Kp e + I, u2 = beta - Kp e - I on',
    'the estimate, saturated to [u_min, u_max] with anti-windup. Default namespace /pam.',
    '  subscribes  estimate (JointEstimate) or joint_measured, reference (Reference)',
    '  publishes   valve_command (ValveCommand), controller_state (ControllerState), /diagnostics',
    'Service ~/enable (std_srvs/SetBool).',
]


@dataclass(frozen=True)
class PiConfig:
    """What pi_node runs with, checked (ConfigError naming the parameter otherwise).

    mode: ANGLE or TORQUE until a reference says otherwise; initial_reference: rad or N m;
    angle, torque: each mode's gains and limits (pi.PiGains); anti_windup: 'conditional' or
    'back_calculation'; tracking_time: s; dt_max: s, the largest plausible feedback step;
    feedback: 'estimate' or 'measured'; feedback_timeout: s of wall clock; safe_command:
    (u1, u2) V; enabled: control at start; frame_id; hardware_id; lost_samples_warn_ratio;
    realtime: the 1 kHz path's knobs.
    """

    mode: int
    initial_reference: float
    angle: PiGains
    torque: PiGains
    anti_windup: str
    tracking_time: float
    dt_max: float
    feedback: str
    feedback_timeout: float
    safe_command: tuple[float, float]
    enabled: bool
    frame_id: str
    hardware_id: str
    lost_samples_warn_ratio: float
    realtime: RealtimeRequest
    #: the checked parameter values it was built from (read-only; for changed())
    values: Mapping[str, Any] = field(repr=False, compare=False,
                                      default_factory=lambda: MappingProxyType({}))

    def __post_init__(self):
        try:
            validate_gains(self.angle)
            validate_gains(self.torque)
        except ValueError as exc:
            raise ConfigError(f'gains/limits: {exc}') from exc

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> PiConfig:
        """From the node's parameter values (every row of PARAMETERS)."""
        v = check_realtime(check_all(PARAMETERS, dict(values)))
        safe = check_command('safe_command', v['safe_command'])
        return cls(
            mode=ANGLE if v['mode'] == 'angle' else TORQUE,
            initial_reference=v['initial_reference'],
            angle=PiGains(v['kp_angle'], v['ki_angle'], v['beta'], v['u_min'], v['u_max']),
            torque=PiGains(v['kp_torque'], v['ki_torque'], v['beta'], v['u_min'], v['u_max']),
            anti_windup=v['anti_windup'], tracking_time=v['tracking_time'], dt_max=v['dt_max'],
            feedback=v['feedback'], feedback_timeout=v['feedback_timeout'],
            safe_command=(safe[0], safe[1]), enabled=v['enabled'], frame_id=v['frame_id'],
            hardware_id=v['hardware_id'], lost_samples_warn_ratio=v['lost_samples_warn_ratio'],
            realtime=RealtimeRequest.from_values(v), values=MappingProxyType(v))

    @classmethod
    def default(cls) -> PiConfig:
        """The table's defaults."""
        return cls.from_values(defaults(PARAMETERS))

    def changed(self, changes: Mapping[str, Any]) -> PiConfig:
        """A new PiConfig with `changes` (parameter name -> value) applied, checked as at start
        (ConfigError, ValueError or TypeError naming the problem); this one is untouched."""
        return PiConfig.from_values({**self.values, **changes})

    def make_loop(self) -> ControlLoop:
        """The ROS-free core that makes every decision."""
        return ControlLoop(self.angle, self.torque, self.anti_windup, self.tracking_time,
                           self.dt_max, self.safe_command, self.mode, self.initial_reference,
                           self.enabled)

    def describe(self) -> str:
        """The start-up log line."""
        a, t = self.angle, self.torque
        return (f'{MODE_NAMES[self.mode]} mode, feedback {self.feedback}; gains angle kp {a.kp:g} '
                f'V/rad ki {a.ki:g} V/(rad s), torque kp {t.kp:g} V/(N m) ki {t.ki:g} V/(N m s); '
                f'beta {a.beta:g} V, limits [{a.u_min:g}, {a.u_max:g}] V, anti-windup '
                f"{self.anti_windup}; {'enabled' if self.enabled else 'disabled'}")
