"""Parameters of ukf_node: the table, their checks and the --help text (no ROS in here)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from pam_common.joint_states import check_joint_states, joint_state_params
from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    ConfigError,
    ParamSpec,
    check_all,
    check_array,
    check_command,
    check_state,
    fail,
    merge_overrides,
    usage_text as _usage_text,
)
from pam_common.realtime_knobs import REALTIME_PARAMS, RealtimeRequest, check_realtime
from pam_common.sample_gaps import WARN_RATIO_PARAM
from pam_model.model_choices import ForceModel, FrictionLaw
from pam_model.rest import REST_COMMAND, REST_STATE

from .valid_readings import NIS_GATE_OFF, PRESSURE_MAX, PRESSURE_MIN

if TYPE_CHECKING:   # imported lazily at run time (ukf_node --help stays instant)
    from .pam_ukf import PamUkf

JOINT_MODES = ('free', 'locked')
TUNING_PRESETS = ('default', 'paper')

PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec('model_parameters', 'default', 'string', '',
              "Table II parameter set the filter's model assumes: 'default' (corrected), "
              "'printed' or the path of a Table II YAML file."),
    ParamSpec('valve_map', 'default', 'string', '',
              "Valve map kappa(u): 'default' (shipped table) or a voltage_V,alpha CSV path."),
    ParamSpec('model_extensions', '', 'string', '',
              "Path of an extensions.yaml (pam-identify writes it; docs/model_extensions.md): "
              "the filter's model carries its valve lag, dead volume, force hysteresis, sensor "
              "offset and gain; '' (the default): none, the paper's model."),
    ParamSpec('use_supply_pressure', False, 'bool', '',
              'Subscribe supply_pressure (sensor_msgs/FluidPressure, Pa abs) and predict with '
              'the latest reading as P_tank; one older than 0.1 s or not finite: the model\'s '
              'P_tank (counted on /diagnostics).'),
    ParamSpec('bias_states', False, 'bool', '',
              'Also estimate random-walk offsets b1, b2 (Pa) of the pressure sensors '
              '(pam_estimator.bias_ukf, default rates; docs/model_extensions.md "Bias states"); '
              'the published state, pressures and covariance stay the 4 of the paper.'),
    ParamSpec('friction_law', str(FrictionLaw.PROPOSED), 'string', '',
              "Friction law of the filter's model.", choices=FrictionLaw.names()),
    ParamSpec('force_model', str(ForceModel.PROPOSED), 'string', '',
              "Force model of the filter's model.", choices=ForceModel.names()),
    ParamSpec('joint_mode', 'free', 'string', '',
              "'free' joint, or 'locked' at the initial angle (torque experiments).",
              choices=JOINT_MODES),
    ParamSpec('tuning', 'default', 'string', '',
              "Preset of Q, R, P(0): 'default' (tuned on the simulated rig with the 'mild' "
              "mismatch) or 'paper' (Q = P(0) = diag(1e-5, 1e-4, 1e6, 1e6), R = diag(1e8, 1e8)).",
              choices=TUNING_PRESETS),
    ParamSpec('process_noise', [], 'double[]', 'rad^2, (rad/s)^2, Pa^2, Pa^2',
              'Diagonal of Q over [psi, psi_dot, P1, P2]; empty: from the tuning preset.'),
    ParamSpec('measurement_noise', [], 'double[]', 'Pa^2, Pa^2',
              'Diagonal of R over [P1, P2]; empty: from the tuning preset.'),
    ParamSpec('initial_covariance', [], 'double[]', 'rad^2, (rad/s)^2, Pa^2, Pa^2',
              'Diagonal of P(0); empty: from the tuning preset.'),
    ParamSpec('initial_state', list(REST_STATE), 'double[]', 'rad, rad/s, Pa, Pa',
              'Initial estimate [psi, psi_dot, P1, P2] (also the state a reset returns to).'),
    ParamSpec('initial_command', list(REST_COMMAND), 'double[]', 'V',
              'Valve voltages assumed held until the first valve_command arrives.'),
    ParamSpec('nis_gate', NIS_GATE_OFF, 'double', '',
              'Reject an update whose normalised innovation squared exceeds this (chi-square, '
              '2 degrees of freedom: 13.8 rejects 0.1 % of good samples); 0: no gate.',
              range=(0.0, 1.0e9)),
    ParamSpec('pressure_min', PRESSURE_MIN, 'double', 'Pa',
              'Pressure readings below this (absolute) are sensor faults: the update is skipped.',
              range=(0.0, 1.0e7)),
    ParamSpec('pressure_max', PRESSURE_MAX, 'double', 'Pa',
              'Pressure readings above this are sensor faults: the update is skipped.',
              range=(0.0, 1.0e8)),
    ParamSpec('stale_timeout', 0.1, 'double', 's',
              'Diagnostics report the input stale (WARN) after this long without pressures.',
              range=(0.001, 3600.0)),
    WARN_RATIO_PARAM,
    ParamSpec('frame_id', 'pam_joint', 'string', '', 'frame_id of the published estimates.'),
    *joint_state_params('estimate/joint_states', 'the estimate: angle, angular velocity, torque'),
    HARDWARE_ID_PARAM,
    *REALTIME_PARAMS,
)


SUMMARY = [
    'Sensor-less UKF of the antagonistic PAM joint (pam_estimator): joint angle and torque from',
    "the two muscle pressures (Shin et al. 2021). Default namespace '/pam'. Topics (reliable,",
    'keep last 100):',
    '  subscribes  pressures       pam_interfaces/Pressures        P1, P2 (Pa abs), one step each',
    '  subscribes  valve_command   pam_interfaces/ValveCommand     u1, u2 (V), held as u(k-1)',
    '  subscribes  supply_pressure sensor_msgs/FluidPressure       P_tank (Pa abs), with',
    '                                                              use_supply_pressure only',
    '  publishes   estimate        pam_interfaces/JointEstimate    per sample, with its stamp',
    '  publishes   estimate/joint_states  sensor_msgs/JointState   the estimate for the standard',
    '                                                              tools (joint_states_rate)',
    '  publishes   /diagnostics    diagnostic_msgs/DiagnosticArray about 1 Hz',
    'Service ~/reset (std_srvs/Trigger): restart from initial_state and the initial covariance.',
]


def usage_text(prog: str = 'ukf_node') -> str:
    return _usage_text(prog, SUMMARY, PARAMETERS, examples=[
        f'{prog} --ros-args -p joint_mode:=locked -p tuning:=paper',
        f'{prog} --ros-args --params-file <share>/pam_estimator/config/ukf_node.yaml'])


@dataclass(frozen=True)
class UkfConfig:
    """ukf_node's checked configuration and the filter built from it, once, by build_config
    (ConfigError naming the parameter otherwise). Units: initial_command [u1 V, u2 V],
    stale_timeout s, joint_states_rate Hz (0: not published)."""

    ukf: PamUkf
    initial_command: tuple[float, float]
    use_supply_pressure: bool
    frame_id: str
    hardware_id: str
    stale_timeout: float
    lost_samples_warn_ratio: float
    joint_name: str
    joint_states_rate: float
    realtime: RealtimeRequest
    summary: tuple[str, ...] = ()
    #: the checked parameter values it was built from (read-only)
    values: Mapping[str, Any] = field(repr=False, compare=False,
                                      default_factory=lambda: MappingProxyType({}))


def build_config(overrides: Mapping[str, Any] | None = None) -> UkfConfig:
    """Check the parameters and build the filter; ConfigError names the parameter."""
    values = check_all(PARAMETERS, merge_overrides(PARAMETERS, overrides))
    values['initial_state'] = check_state('initial_state', values['initial_state'])
    values['initial_command'] = check_command('initial_command', values['initial_command'])
    if values['pressure_min'] >= values['pressure_max']:
        fail('pressure_max', f"must exceed pressure_min ({values['pressure_min']} Pa)")

    from pam_model.model import PamModel
    from pam_model.model_extensions import load_extensions
    from pam_model.parameters import ParameterError, load_parameters
    from pam_model.valve_map import load_valve_map

    from .bias_ukf import DEFAULT_BIAS_STATES
    from .pam_ukf import TUNINGS, PamUkf, UkfTuning

    preset = TUNINGS[values['tuning']]
    diagonals = {}
    for name, diagonal, length in (('process_noise', 'Q', 4), ('measurement_noise', 'R', 2),
                                ('initial_covariance', 'P0', 4)):
        given = values[name]
        diagonals[diagonal] = (
            tuple(check_array(name, given, length, f'(diagonal, {length} values)'))
            if len(given) else getattr(preset, diagonal))
    tuning = UkfTuning(**diagonals)
    try:
        tuning.validate()
    except ValueError as exc:
        raise ConfigError(f'filter tuning: {exc}') from exc
    try:
        params = load_parameters(values['model_parameters'])
    except (ParameterError, ValueError) as exc:
        fail('model_parameters', str(exc))
    try:
        extensions = load_extensions(values['model_extensions'])
    except ParameterError as exc:
        fail('model_extensions', str(exc))
    try:
        valve_map = load_valve_map(values['valve_map'])
    except (ValueError, OSError) as exc:
        fail('valve_map', str(exc))
    model = PamModel(params=params, valve_map=valve_map, friction=values['friction_law'],
                     force=values['force_model'], locked=values['joint_mode'] == 'locked')
    check_joint_states(values, 1.0 / model.h)    # one filter step per sample of h
    check_realtime(values)
    ukf = PamUkf(model=model, tuning=tuning, x0=tuple(values['initial_state']),
                 nis_gate=values['nis_gate'],
                 y_range=(values['pressure_min'], values['pressure_max']),
                 extensions=extensions,
                 bias_states=DEFAULT_BIAS_STATES if values['bias_states'] else None)
    summary = [
        f"model: parameters {values['model_parameters']!r}, valve map {values['valve_map']!r}, "
        f"friction {values['friction_law']!r}, force {values['force_model']!r}, joint "
        f"{values['joint_mode']}",
        f"tuning {values['tuning']!r}: Q diag {list(tuning.Q)}, R diag {list(tuning.R)}, "
        f'P(0) diag {list(tuning.P0)}',
        f"model extensions: {extensions.describe()}"
        + (f" ({values['model_extensions']})" if values['model_extensions'] else '')
        + (', supply pressure: measured (supply_pressure)' if values['use_supply_pressure']
           else '')
        + (', bias states: sensor offsets b1, b2' if values['bias_states'] else ''),
        f"initial state {values['initial_state']}, NIS gate "
        f"{values['nis_gate'] if values['nis_gate'] > 0 else 'off'}, valid pressures "
        f"[{values['pressure_min']:g}, {values['pressure_max']:g}] Pa",
    ]
    v = values
    return UkfConfig(
        ukf=ukf, initial_command=(v['initial_command'][0], v['initial_command'][1]),
        use_supply_pressure=v['use_supply_pressure'], frame_id=v['frame_id'],
        hardware_id=v['hardware_id'], stale_timeout=v['stale_timeout'],
        lost_samples_warn_ratio=v['lost_samples_warn_ratio'], joint_name=v['joint_name'],
        joint_states_rate=v['joint_states_rate'], realtime=RealtimeRequest.from_values(v),
        summary=tuple(summary), values=MappingProxyType(values))
