"""Parameters of sim_node: the table they are declared from, their validation and the --help text.

No ROS in here: build_config() turns a plain mapping of parameter values into a checked SimConfig
(the pam_model objects the node wraps) or raises ConfigError with a message that names the
parameter. The generic parts (ParamSpec, checks, usage text) are pam_common.node_params, shared
with the other PAM nodes. Only pam_model.model_choices (standard library only) is imported up
front; the rest of pam_model lazily, so that `sim_node --help` stays instant.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from pam_common.joint_states import (
    DEFAULT_RATE,
    above_sample_rate,
    check_joint_states,
    every_nth_sample,
    joint_state_params,
)
from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    U_MAX,
    U_MIN,
    ConfigError,
    ParamSpec,
    check_all,
    check_command,
    check_state,
    defaults as _defaults,
    fail,
    merge_overrides,
    usage_text as _usage_text,
    wants_help,
)
from pam_common.realtime_knobs import REALTIME_PARAMS, RealtimeRequest, check_realtime
from pam_model.model_choices import ForceModel, FrictionLaw
from pam_model.rest import REST_COMMAND, REST_STATE

if TYPE_CHECKING:   # imported lazily at run time (sim_node --help stays instant)
    from pam_model.mismatch import MismatchScenario
    from pam_model.model import PamModel
    from pam_model.parameters import Parameters
    from pam_model.rig import SimulatedRig
    from pam_model.sensor import PressureSensor

__all__ = [
    'PARAMETERS',
    'U_MAX',
    'U_MIN',
    'ConfigError',
    'SimConfig',
    'build_config',
    'defaults',
    'describe',
    'usage_text',
    'wants_help',
]

#: Choices of the string parameters (friction_law and force_model: the names of FrictionLaw and
#: ForceModel).
JOINT_MODES = ('free', 'locked')
TIMINGS = ('realtime', 'lockstep')

RATE_RANGE = (100.0, 10000.0)   # Hz
CLOCK_RATE_RANGE = (1.0, 10000.0)  # Hz
BITS_RANGE = (-1, 32)
SEED_RANGE = (0, 2 ** 31 - 1)
NOISE_RANGE = (-1.0, 1.0e6)     # Pa
TIMEOUT_RANGE = (0.0, 3600.0)   # s
CATCH_UP_RANGE = (0, 1000)      # periods


PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec('plant_parameters', 'default', 'string', '',
              "Table II parameter set of the simulated plant: 'default' (PAM2's p_w2 corrected to "
              "+15.75 N), 'printed' (as printed in the paper) or the path of a Table II YAML "
              'file.'),
    ParamSpec('scenario', '', 'string', '',
              "Plant scenario (parameter mismatch and unmodelled effects) applied to "
              "plant_parameters: '' (none), 'mild', 'strong', 'realistic', 'other_forms' or the "
              'path of a scenario YAML file. A scenario also brings its pressure sensor model.',
              aliases=('mismatch',)),
    ParamSpec('valve_map', 'default', 'string', '',
              "Valve map kappa(u) of the plant: 'default' (shipped table) or the path of a "
              'voltage_V,alpha CSV file.'),
    ParamSpec('friction_law', str(FrictionLaw.PROPOSED), 'string', '',
              'Friction law of the plant.', choices=FrictionLaw.names()),
    ParamSpec('force_model', str(ForceModel.PROPOSED), 'string', '',
              'Muscle force model of the plant.', choices=ForceModel.names()),
    ParamSpec('joint_mode', 'free', 'string', '',
              "'free' joint, or 'locked' at its initial angle (torque experiments: the torque "
              'meter holds the joint).', choices=JOINT_MODES),
    ParamSpec('initial_state', list(REST_STATE), 'double[]',
              'rad, rad/s, Pa, Pa',
              'Initial true state [psi, psi_dot, P1, P2]; pressures are absolute.'),
    ParamSpec('initial_command', list(REST_COMMAND), 'double[]', 'V',
              'Valve voltages [u1, u2] held until the first valve_command arrives, in [0, 10].'),
    ParamSpec('pressure_noise_std', -1.0, 'double', 'Pa',
              'Standard deviation of the white noise on each pressure reading; negative: from '
              'the scenario, or 0 (ideal) if none.', range=NOISE_RANGE),
    ParamSpec('quantisation_bits', -1, 'integer', 'bits',
              'ADC resolution of the pressure sensors over their range; 0: no quantisation; -1: '
              'from the scenario, or ideal if none.', range=BITS_RANGE),
    ParamSpec('seed', 0, 'integer', '',
              'Seed of the sensor noise generator (same seed + same commands in lockstep give '
              'bit-identical pressures).', range=SEED_RANGE),
    ParamSpec('timing', 'realtime', 'string', '',
              "'realtime': one sample per 1/rate s of wall clock, stamped with the node clock. "
              "'lockstep': sample k is stamped t_k = k/rate and the plant steps only when a "
              'command for step k arrives.', choices=TIMINGS),
    ParamSpec('rate', 1000.0, 'double', 'Hz',
              'Sample rate; the model step is h = 1/rate.', range=RATE_RANGE),
    ParamSpec('max_catch_up', 10, 'integer', 'periods',
              'Realtime only: the simulated rig never pauses; when its sampling thread wakes up '
              'late, the plant has stepped through every passed deadline with the held command '
              'and up to this many overdue samples wait and are published in order, late (a '
              "board's samples waiting in the serial line for a late driver); after a longer "
              'stall the oldest are dropped (missed samples: a gap in the sample counter). '
              'Either way the run was not real time, and the rig says so on /diagnostics. A '
              'longer backlog is more work for a process that is already late '
              '(docs/realtime.md).',
              range=CATCH_UP_RANGE),
    ParamSpec('publish_supply_pressure', False, 'bool', '',
              "Publish supply_pressure (sensor_msgs/FluidPressure, Pa abs): the plant's supply "
              'tank pressure P_tank of every sample (with the droop and ripple of the '
              "scenario's effects, if any; else nominal) through the pressure sensor model, "
              'stamped like pressures: a supply-pressure transducer.'),
    ParamSpec('publish_clock', False, 'bool', '',
              'Publish /clock (rosgraph_msgs/Clock) with the stamp of the samples (simulated time '
              't_k in lockstep), at clock_rate.'),
    ParamSpec('clock_rate', DEFAULT_RATE, 'double', 'Hz',
              'With publish_clock: /clock with 1 sample in round(rate / clock_rate) (the '
              'default: every sample); at most the sample rate. A node on simulated time pays '
              "for every /clock message (rclpy's default executor: about 250 us of CPU each) and "
              'needs it only as often as its timers fire: 100 for reference_node at 100 Hz.',
              range=CLOCK_RATE_RANGE),
    ParamSpec('lockstep_timeout', 0.5, 'double', 's',
              'Lockstep only: while waiting for a command, re-publish the current sample after '
              'this long so a late-joining controller can start; 0: never.',
              range=TIMEOUT_RANGE),
    ParamSpec('frame_id', 'pam_joint', 'string', '',
              'frame_id of the published headers.'),
    *joint_state_params('joint_states', 'the true joint, as joint_measured'),
    HARDWARE_ID_PARAM,
    *REALTIME_PARAMS,
)

PARAMETERS_BY_NAME = {spec.name: spec for spec in PARAMETERS}


def defaults() -> dict[str, Any]:
    """The default value of every parameter."""
    return _defaults(PARAMETERS)


SUMMARY = (
    'Simulated antagonistic PAM rig (pam_driver): the plant of pam_model stepped at a fixed',
    "rate. Default namespace '/pam'. Topics (reliable, keep last 100):",
    '  publishes   pressures       pam_interfaces/Pressures         measured P1, P2 (Pa abs)',
    '  publishes   joint_measured  pam_interfaces/JointMeasurement  true angle, velocity, '
    'torque',
    '  subscribes  valve_command   pam_interfaces/ValveCommand      u1, u2 (V), held',
    '  publishes   joint_states    sensor_msgs/JointState           joint_measured for the '
    'standard tools',
    '  publishes   /diagnostics    diagnostic_msgs/DiagnosticArray  about 1 Hz',
    '  publishes   /clock          rosgraph_msgs/Clock              if publish_clock (clock_rate)',
    '  publishes   supply_pressure sensor_msgs/FluidPressure        P_tank (Pa abs), if '
    'publish_supply_pressure',
)


def usage_text(prog: str = 'sim_node') -> str:
    """The --help text: what the node does and every parameter with type, unit and default."""
    return _usage_text(prog, SUMMARY, PARAMETERS, examples=(
        f'{prog} --ros-args -p timing:=lockstep -p scenario:=mild -p seed:=3',
        f'{prog} --ros-args --params-file <share>/pam_driver/config/sim_node_mild.yaml',
    ))


@dataclass(frozen=True)
class SimConfig:
    """The checked configuration of sim_node and the pam_model objects made from it, built once
    by build_config (ConfigError naming the parameter otherwise). Units: rate Hz, initial_state
    [psi rad, psi_dot rad/s, P1 Pa, P2 Pa], initial_command [u1 V, u2 V], lockstep_timeout s,
    max_catch_up periods, joint_states_rate Hz (0: not published)."""

    timing: str                         # 'realtime' or 'lockstep'
    rate: float
    initial_state: tuple[float, ...]
    initial_command: tuple[float, float]
    seed: int
    lockstep_timeout: float
    max_catch_up: int
    publish_clock: bool
    clock_every: int                    # /clock with the samples k = 0, n, 2n, ... (n >= 1)
    publish_supply_pressure: bool
    joint_mode: str                     # 'free' or 'locked'
    plant_parameters: str
    scenario_name: str                  # the scenario parameter ('' none)
    frame_id: str
    hardware_id: str
    joint_name: str
    joint_states_rate: float
    realtime: RealtimeRequest
    parameters: Parameters              # of the plant (the scenario applied)
    scenario: MismatchScenario | None
    sensor: PressureSensor
    model: PamModel
    sensor_source: str = ''
    summary: tuple[str, ...] = ()
    #: the checked parameter values it was built from (read-only)
    values: Mapping[str, Any] = field(repr=False, compare=False,
                                      default_factory=lambda: MappingProxyType({}))

    @property
    def h(self) -> float:
        """s, the model step (1 / rate)."""
        return self.model.h

    @property
    def lockstep(self) -> bool:
        return self.timing == 'lockstep'

    def make_rig(self) -> SimulatedRig:
        """A fresh pam_model SimulatedRig in the initial state."""
        from pam_model.rig import SimulatedRig
        return SimulatedRig(self.model, self.initial_state, sensor=self.sensor,
                            seed=self.seed, u0=self.initial_command,
                            effects=self.scenario.effects if self.scenario is not None else None)


def build_config(overrides: Mapping[str, Any] | None = None) -> SimConfig:
    """Check the parameter values (defaults for those not given) and build the plant.

    Raises ConfigError naming the parameter; file problems carry pam_model's ParameterError text.
    """
    values = check_all(PARAMETERS, merge_overrides(PARAMETERS, overrides))
    values['initial_state'] = check_state('initial_state', values['initial_state'])
    values['initial_command'] = check_command('initial_command', values['initial_command'])
    if not values['plant_parameters'].strip():
        fail('plant_parameters', "empty; use 'default', 'printed' or a YAML path")
    if not values['valve_map'].strip():
        fail('valve_map', "empty; use 'default' or a CSV path")
    check_joint_states(values, values['rate'])
    if above_sample_rate(values['clock_rate'], values['rate']):
        fail('clock_rate', f"{values['clock_rate']:g} Hz is above the sample rate "
             f"{values['rate']:g} Hz (at most one /clock per sample)")
    check_realtime(values)

    from pam_model.mismatch import load_scenario
    from pam_model.model import PamModel
    from pam_model.parameters import ParameterError, load_parameters
    from pam_model.sensor import PressureSensor
    from pam_model.valve_map import load_valve_map

    try:
        nominal = load_parameters(values['plant_parameters'])
    except (ParameterError, ValueError) as exc:
        fail('plant_parameters', str(exc))
    scenario = None
    params = nominal
    if values['scenario'].strip():
        try:
            scenario = load_scenario(values['scenario'])
        except (ParameterError, ValueError) as exc:
            fail('scenario', str(exc))
        try:
            params = scenario.apply(nominal)
        except (ParameterError, ValueError) as exc:
            fail('scenario', f'applied to {values["plant_parameters"]!r}: {exc}')
    try:
        valve_map = load_valve_map(values['valve_map'])
    except (ValueError, OSError) as exc:
        fail('valve_map', str(exc))

    base = scenario.sensor if scenario is not None else PressureSensor()
    noise = values['pressure_noise_std']
    bits = values['quantisation_bits']
    origin = f"scenario '{scenario.name}'" if scenario is not None else 'ideal'
    noise_from = origin if noise < 0.0 else 'parameter'
    bits_from = origin if bits < 0 else 'parameter'
    try:
        sensor = PressureSensor(noise_std=base.noise_std if noise < 0.0 else noise,
                                bits=base.bits if bits < 0 else bits,
                                range_min=base.range_min, range_max=base.range_max)
    except ValueError as exc:
        fail('pressure_noise_std' if 'noise' in str(exc) else 'quantisation_bits', str(exc))

    try:
        model = PamModel(params=params, valve_map=valve_map, friction=values['friction_law'],
                         force=values['force_model'], locked=values['joint_mode'] == 'locked',
                         h=1.0 / values['rate'])
    except ValueError as exc:
        raise ConfigError(f'cannot build the plant model: {exc}') from exc

    sensor_text = (f'noise std {sensor.noise_std:g} Pa ({noise_from}), '
                   + (f'{sensor.bits}-bit ADC over [{sensor.range_min:g}, {sensor.range_max:g}] Pa'
                      if sensor.bits else f'no quantisation, range [{sensor.range_min:g}, '
                      f'{sensor.range_max:g}] Pa')
                   + f' ({bits_from}), seed {values["seed"]}')
    v = values
    config = SimConfig(
        timing=v['timing'], rate=v['rate'], initial_state=tuple(v['initial_state']),
        initial_command=(v['initial_command'][0], v['initial_command'][1]), seed=v['seed'],
        lockstep_timeout=v['lockstep_timeout'], max_catch_up=v['max_catch_up'],
        publish_clock=v['publish_clock'],
        clock_every=every_nth_sample(v['clock_rate'], v['rate']),
        publish_supply_pressure=v['publish_supply_pressure'],
        joint_mode=v['joint_mode'], plant_parameters=v['plant_parameters'],
        scenario_name=v['scenario'], frame_id=v['frame_id'], hardware_id=v['hardware_id'],
        joint_name=v['joint_name'], joint_states_rate=v['joint_states_rate'],
        realtime=RealtimeRequest.from_values(v), parameters=params, scenario=scenario,
        sensor=sensor, model=model, sensor_source=sensor_text, values=MappingProxyType(values))
    try:
        config.make_rig()  # the last checks (state shape) live in SimulatedRig
    except ValueError as exc:
        raise ConfigError(f'cannot build the simulated rig: {exc}') from exc
    return dataclasses.replace(config, summary=tuple(describe(config)))


def describe(config: SimConfig) -> list[str]:
    """The start-up log lines: what runs."""
    v = config.values
    if config.scenario is None:
        scenario = 'scenario: none (plant = nominal parameters)'
    else:
        s = config.scenario
        changes = [f'{k} x{f:g}' for k, f in s.factors.items()]
        changes += [f'{k} {o:+g}' for k, o in s.offsets.items()]
        source = '' if v['scenario'] == s.name else f" ({v['scenario']})"
        scenario = (f"scenario: '{s.name}'{source}: "
                    + (', '.join(changes) if changes else 'no parameter change')
                    + f'; unmodelled effects: {s.effects.describe()}')
    state = v['initial_state']
    lines = [
        f"plant: parameters {v['plant_parameters']!r}, valve map {v['valve_map']!r}, friction "
        f"law {v['friction_law']!r}, force model {v['force_model']!r}",
        scenario,
        f"joint mode: {v['joint_mode']}; initial state psi {state[0]:g} rad, psi_dot "
        f"{state[1]:g} rad/s, P1 {state[2]:g} Pa, P2 {state[3]:g} Pa; initial command "
        f"u1 {v['initial_command'][0]:g} V, u2 {v['initial_command'][1]:g} V",
    ]
    timing = (f"timing: {v['timing']} at {v['rate']:g} Hz (model step h = {1e3 / v['rate']:g} ms)"
              + (('; /clock published with every sample' if config.clock_every == 1 else
                  f'; /clock published with 1 sample in {config.clock_every}')
                 if v['publish_clock'] else ''))
    if v['timing'] == 'realtime':
        timing += (f"; the plant never pauses: up to {v['max_catch_up']} overdue samples wait "
                   'and are published late, older ones are dropped (missed)')
    if v['timing'] == 'lockstep':
        timing += (f"; re-publish after {v['lockstep_timeout']:g} s without a command"
                   if v['lockstep_timeout'] > 0 else '; never re-publish')
    lines.append(timing)
    lines.append(f'sensor: {config.sensor_source}')
    if v['publish_supply_pressure']:
        droop = config.scenario is not None and config.scenario.effects.supply_varies
        lines.append(f'supply pressure: published, P_tank {config.parameters.P_tank:g} Pa abs '
                     + ("with the scenario's droop/ripple/tank" if droop else '(constant)')
                     + ' through the same sensor model (its own noise draws)')
    return lines
