"""reference_node: publishes a built-in reference profile on `reference` (pam_interfaces/Reference).

Profiles (time t from the node's first tick, on the node clock: simulated time with
use_sim_time):
    steps     paper-style steps within +-amplitude, held `hold` s each, from `seed`
              (pam_model.profiles.step_reference_profile; the first hold is at 0)
    ramp      triangle between -amplitude and +amplitude with period `period`, from 0 rising
    sine      amplitude sin(2 pi t / period)
    constant  offset
Every profile adds `offset`. mode 'angle' values are in rad, 'torque' in N m. After `duration`
the profile repeats if `repeat`, else holds its last value. Run `reference_node --help`.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np
from std_msgs.msg import Header

from pam_common.diagnostics import OK, DiagnosticsPublisher
from pam_common.fast_messages import builder
from pam_common.finite_guard import FiniteGuard
from pam_common.links import LinkedNode
from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    NodeConfig,
    ParamSpec,
    check_all,
    fail,
    usage_text,
)
from pam_common.node_skeleton import Component, component_main, parameter_values
from pam_common.qos import LATEST_QOS
from pam_common.realtime_knobs import (
    REALTIME_PARAMS,
    RealtimeKnobs,
    RealtimeRequest,
    check_realtime,
)
from pam_common.topics import DEFAULT_NAMESPACE, REFERENCE
from pam_interfaces.msg import Reference

from .control_loop import ENVELOPE, MODE_NAMES

build_header, build_reference = builder(Header), builder(Reference)

NODE_NAME = 'reference_node'
PROFILES = ('steps', 'ramp', 'sine', 'constant')
LIMITS = {MODE_NAMES[mode]: limit for mode, limit in ENVELOPE.items()}   # rad, N m

PARAMETERS = (
    ParamSpec('mode', 'angle', 'string', '', 'angle (rad) or torque (N m).',
              choices=('angle', 'torque')),
    ParamSpec('profile', 'steps', 'string', '', 'Reference profile.', choices=PROFILES),
    ParamSpec('amplitude', math.radians(20.0), 'double', 'rad or N m',
              'Largest excursion (steps: levels within +-amplitude).', range=(0.0, 10.0)),
    ParamSpec('offset', 0.0, 'double', 'rad or N m', 'Added to every profile.',
              range=(-10.0, 10.0)),
    ParamSpec('hold', 8.0, 'double', 's', 'steps: duration of each level.', range=(0.1, 3600.0)),
    ParamSpec('period', 10.0, 'double', 's', 'ramp and sine: period.', range=(0.1, 3600.0)),
    ParamSpec('duration', 64.0, 'double', 's', 'Length of the profile.', range=(0.1, 86400.0)),
    ParamSpec('repeat', False, 'bool', '', 'Start over after duration (else hold the last value).'),
    ParamSpec('seed', 0, 'integer', '', 'steps: seed of the levels.', range=(0, 2 ** 31 - 1)),
    ParamSpec('rate', 100.0, 'double', 'Hz', 'Publishing rate.', range=(0.1, 1000.0)),
    HARDWARE_ID_PARAM,
    *REALTIME_PARAMS,
)
SUMMARY = ['Reference profiles for pi_node (pam_controller): publishes reference '
           '(pam_interfaces/Reference) at `rate`. Default namespace /pam.']


@dataclass(frozen=True)
class ReferenceConfig(NodeConfig):
    """reference_node's checked parameters (the table above: units, ranges, defaults)."""

    mode: str
    profile: str
    amplitude: float
    offset: float
    hold: float
    period: float
    duration: float
    repeat: bool
    seed: int
    rate: float
    hardware_id: str
    thread_priority: int
    cpu_affinity: tuple[int, ...]
    lock_memory: bool

    @property
    def realtime(self) -> RealtimeRequest:
        return RealtimeRequest(self.thread_priority, self.cpu_affinity, self.lock_memory)


def profile_value(config: ReferenceConfig, steps: np.ndarray | None, t: float) -> float:
    """The reference (rad or N m) at time t (s) of the configured profile."""
    duration = config.duration
    if t >= duration:
        t = t % duration if config.repeat else duration - 1e-9
    a, kind = config.amplitude, config.profile
    if kind == 'steps':
        value = steps[min(int(t / config.hold), len(steps) - 1)]
    elif kind == 'ramp':
        phase = (t / config.period + 0.25) % 1.0        # a triangle from 0, rising first
        value = a * (1.0 - 4.0 * abs(phase - 0.5))
    elif kind == 'sine':
        value = a * math.sin(2.0 * math.pi * t / config.period)
    else:
        value = 0.0
    return float(value) + config.offset


def step_levels(config: ReferenceConfig) -> np.ndarray:
    """The levels of the steps profile, one per hold."""
    from pam_model.profiles import ANGLE_STEP_MAX, TORQUE_STEP_MAX, step_reference_profile
    ref = step_reference_profile(config.mode, config.seed, config.duration, config.hold,
                                 Ts=config.hold)
    limit = ANGLE_STEP_MAX if config.mode == 'angle' else TORQUE_STEP_MAX
    return ref.value * (config.amplitude / limit)


def build_config(values: dict) -> ReferenceConfig:
    """Check the values (the table's ranges and choices, the rig's envelope); ConfigError names
    the parameter."""
    check_all(PARAMETERS, values)
    check_realtime(values)
    limit = LIMITS[values['mode']]
    if values['amplitude'] + abs(values['offset']) > limit:
        fail('amplitude', f"amplitude + |offset| exceeds the rig's envelope {limit:g} "
                          f"({'rad' if values['mode'] == 'angle' else 'N m'})")
    return ReferenceConfig.from_values(values)


class ReferenceNode(LinkedNode):
    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.config = config = parameter_values(self, PARAMETERS, check=build_config)
        # the stack's knobs (pam_common.realtime_knobs): the executor it shares when composed
        self.realtime = RealtimeKnobs(self.get_logger(), config.realtime)
        self.realtime.apply_to_executor()
        self.mode = Reference.ANGLE if config.mode == 'angle' else Reference.TORQUE
        self.steps = step_levels(config) if config.profile == 'steps' else None
        self.guard = FiniteGuard(self.get_logger())
        self.publisher = self.guard.wrap(self.create_publisher(Reference, REFERENCE, LATEST_QOS),
                                         hold=True)
        self.start: int | None = None       # ns on the node clock, the first tick
        self.published = 0
        # with the in-process links, run by the sample loop when one drives the process
        self.create_loop_timer(1.0 / config.rate, self._tick)
        diagnostics = DiagnosticsPublisher(self, 'reference profile', config.hardware_id,
                                           self._report)
        diagnostics.add_check(self.guard.report)
        diagnostics.add_check(self.realtime.report)
        unit = 'rad' if self.mode == Reference.ANGLE else 'N m'
        self.get_logger().info(
            f'{config.profile} profile, {config.mode} mode, amplitude {config.amplitude:g} '
            f'{unit}, offset {config.offset:g} {unit}, {config.duration:g} s'
            f"{' repeated' if config.repeat else ''}, on {self.resolve_topic_name(REFERENCE)} at "
            f'{config.rate:g} Hz')

    def _tick(self) -> None:
        now = self.get_clock().now()
        now_ns = now.nanoseconds
        if self.start is None:
            self.start = now_ns
        t = (now_ns - self.start) * 1e-9
        # built in one step (pam_common.fast_messages): this runs in the sample loop when linked
        msg = build_reference(build_header(now.to_msg(), ''), self.mode,
                              profile_value(self.config, self.steps, t))
        self.publisher.publish(msg)
        self.published += 1
        self.last_value = msg.value

    def _report(self):
        values = {'profile': self.config.profile, 'mode': self.config.mode,
                  'references published': self.published}
        if not self.published:
            return OK, 'starting', values
        return OK, f'{self.config.profile}: {self.last_value:.4g} ' \
                   f"{'rad' if self.mode == Reference.ANGLE else 'N m'}", values


#: The node as a component of a composed process (pam_container, pam-bringup --composed).
COMPONENT = Component(NODE_NAME, ReferenceNode)


def main(args=None) -> int:
    return component_main(COMPONENT, usage_text(NODE_NAME, SUMMARY, PARAMETERS, examples=[
        f'{NODE_NAME} --ros-args -p mode:=torque -p amplitude:=2.0 -p profile:=steps']), args)

if __name__ == '__main__':
    sys.exit(main())
