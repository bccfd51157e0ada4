"""Parameters of driver_node: the table, their validation, the --help text and the checked
DriverConfig built from them once (no ROS in here)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from pam_common.joint_states import check_joint_states, joint_state_params
from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    U_MAX,
    U_MIN,
    ConfigError,
    ParamSpec,
    check_all,
    check_array,
    check_command,
    fail,
    merge_overrides,
    usage_text as _usage_text,
    wants_help,
)
from pam_common.realtime_knobs import REALTIME_PARAMS, RealtimeRequest, check_realtime
from pam_driver.driver_core import SafetyConfig

if TYPE_CHECKING:
    from pam_driver.calibration import Calibration

__all__ = ['PARAMETERS', 'ConfigError', 'DriverConfig', 'LinkConfig', 'build_config',
           'usage_text', 'wants_help']

PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec('port', '/dev/ttyUSB0', 'string', '',
              'Serial device of the DAQ board (a pam-emulator --link path works too).'),
    ParamSpec('baud', 1000000, 'integer', 'baud',
              'Baud rate (ignored by USB CDC and ptys; 1 kHz samples need >= 230400). 1 Mbaud: '
              "exact on a 16 MHz AVR (the reference board's, pam_driver/firmware).",
              range=(9600, 12000000)),
    ParamSpec('calibration_file', 'default', 'string', '',
              "Calibration YAML (counts <-> SI units); 'default': the shipped "
              'config/driver_calibration.yaml.'),
    ParamSpec('watchdog_timeout', 0.05, 'double', 's',
              'No valid valve_command for this long -> safe_output, disarmed until ~/arm. '
              '0: no watchdog.', range=(0.0, 10.0)),
    ParamSpec('safe_output', [0.0, 0.0], 'double[]', 'V',
              'Valve voltages [u1, u2] of the safe state (default: vent both muscles).'),
    ParamSpec('valve_limits', [0.0, 10.0], 'double[]', 'V',
              'Commands are clipped to [min, max] (counted and reported).'),
    ParamSpec('arm_at_start', True, 'bool', '',
              'Start armed: the first valid command is applied. False: wait for ~/arm.'),
    ParamSpec('pressure_limits', [50000.0, 900000.0], 'double[]', 'Pa',
              'Plausible absolute pressures [min, max]; readings outside (or outside the '
              "sensor's valid voltages) for 5 samples in a row are a sensor fault -> safe "
              'output.'),
    ParamSpec('stuck_time', 0.5, 'double', 's',
              'A pressure ADC reading identical for this long is a stuck sensor -> safe '
              'output. 0: no check.', range=(0.0, 60.0)),
    ParamSpec('handshake_timeout', 0.5, 'double', 's',
              'Wait this long for HELLO_ACK after HELLO.', range=(0.01, 10.0)),
    ParamSpec('stream_timeout', 0.2, 'double', 's',
              'No sample for this long -> the device is lost: reconnect.', range=(0.01, 10.0)),
    ParamSpec('heartbeat_period', 0.05, 'double', 's',
              'A HEARTBEAT to the device after this long without a frame to it (any frame '
              "feeds the device's watchdog).", range=(0.005, 1.0)),
    ParamSpec('reconnect_backoff', [0.1, 2.0], 'double[]', 's',
              'Reconnect delays [first, max]: doubled after each failed attempt.'),
    ParamSpec('frame_id', 'pam_joint', 'string', '', 'frame_id of the published headers.'),
    *joint_state_params('joint_states', 'the encoder angle, its finite-difference velocity and '
                        'the torque meter (effort empty without one)',
                        "The board's sample rate is known at the handshake: above it, every "
                        'sample is published (a warning).'),
    HARDWARE_ID_PARAM,
    *REALTIME_PARAMS,
    ParamSpec('inject_internal_error', 0.0, 'double', 's',
              'Fault injection for tests: raise an internal error in the serial thread this long '
              'after the first valve_command reached the valves, once (exercises the safe output '
              'on an exception). 0: never.', range=(0.0, 3600.0)),
)

SUMMARY = (
    'Hardware driver of the PAM rig (pam_driver): the DAQ board over a serial port',
    "(pam_driver/PROTOCOL.md). Default namespace '/pam'. Same topics as sim_node:",
    '  publishes   pressures       pam_interfaces/Pressures         P1, P2 (Pa abs), per sample',
    '  publishes   joint_measured  pam_interfaces/JointMeasurement  encoder angle, torque meter '
    '(when fitted)',
    '  publishes   joint_states    sensor_msgs/JointState           the joint for the standard '
    'tools (encoder)',
    '  publishes   supply_pressure sensor_msgs/FluidPressure        P_tank (Pa abs), when the '
    'board has the transducer',
    '  subscribes  valve_command   pam_interfaces/ValveCommand      u1, u2 (V)',
    '  publishes   ~/applied_command pam_interfaces/ValveCommand    what the valves get',
    '  publishes   /diagnostics    diagnostic_msgs/DiagnosticArray  about 1 Hz',
    '  services    ~/arm, ~/estop  std_srvs/Trigger                 re-arm after a safe stop '
    '(and ARM to a 1.2 board: its latched faults); e-stop',
)


def usage_text(prog: str = 'driver_node') -> str:
    return _usage_text(prog, SUMMARY, PARAMETERS, examples=(
        f'{prog} --ros-args -p port:=/dev/ttyACM0',
        f'{prog} --ros-args --params-file <share>/pam_driver/config/driver_node.yaml',
    ))


@dataclass(frozen=True)
class LinkConfig:
    """The serial session's parameters (serial_session.SerialSession): the port and its baud
    rate, handshake_timeout s to wait for HELLO_ACK, stream_timeout s without a sample before
    the device counts as lost, heartbeat_period s between HEARTBEAT frames, reconnect_backoff
    (first, max) s between connection attempts (doubled after each failure)."""

    port: str
    baud: int
    handshake_timeout: float
    stream_timeout: float
    heartbeat_period: float
    reconnect_backoff: tuple[float, float]


@dataclass(frozen=True)
class DriverConfig:
    """The checked configuration of driver_node, built once by build_config (ConfigError naming
    the parameter otherwise): the serial link, the safety decisions' parameters, the
    calibration (counts <-> SI units), the published headers and JointState, the real-time
    request, and the fault injection of the tests (inject_internal_error s, 0: never)."""

    link: LinkConfig
    safety: SafetyConfig
    calibration: Calibration
    frame_id: str
    hardware_id: str
    joint_name: str
    joint_states_rate: float            # Hz, 0: not published
    realtime: RealtimeRequest
    inject_internal_error: float
    #: the checked parameter values it was built from (read-only)
    values: Mapping[str, Any] = field(repr=False, compare=False,
                                      default_factory=lambda: MappingProxyType({}))


def build_config(overrides: Mapping[str, Any] | None = None) -> DriverConfig:
    """Check the parameter values (defaults for those not given) and load the calibration.
    Raises ConfigError naming the parameter."""
    from pam_driver.calibration import CalibrationError, load
    values = check_all(PARAMETERS, merge_overrides(PARAMETERS, overrides))
    if not values['port'].strip():
        fail('port', 'empty')
    values['safe_output'] = check_command('safe_output', values['safe_output'])
    limits = check_command('valve_limits', values['valve_limits'])
    if limits[0] >= limits[1]:
        fail('valve_limits', f'need min < max, got {limits}')
    values['valve_limits'] = limits
    p = check_array('pressure_limits', values['pressure_limits'], 2, '[min Pa, max Pa]')
    if not 0.0 < p[0] < p[1]:
        fail('pressure_limits', f'need 0 < min < max, got {p}')
    values['pressure_limits'] = p
    b = check_array('reconnect_backoff', values['reconnect_backoff'], 2, '[first s, max s]')
    if not 0.0 < b[0] <= b[1] <= 60.0:
        fail('reconnect_backoff', f'need 0 < first <= max <= 60 s, got {b}')
    values['reconnect_backoff'] = b
    check_joint_states(values, None)      # the board's rate: checked at the handshake
    check_realtime(values)
    try:
        calibration = load(values['calibration_file'])
    except CalibrationError as exc:
        fail('calibration_file', str(exc))
    v = values
    try:
        safety = SafetyConfig.from_values(v)
    except ValueError as exc:
        raise ConfigError(str(exc)) from exc
    return DriverConfig(
        link=LinkConfig(v['port'], v['baud'], v['handshake_timeout'], v['stream_timeout'],
                        v['heartbeat_period'], (b[0], b[1])),
        safety=safety, calibration=calibration, frame_id=v['frame_id'],
        hardware_id=v['hardware_id'], joint_name=v['joint_name'],
        joint_states_rate=v['joint_states_rate'], realtime=RealtimeRequest.from_values(v),
        inject_internal_error=v['inject_internal_error'], values=MappingProxyType(values))


__all__ += ['SUMMARY', 'U_MAX', 'U_MIN']
