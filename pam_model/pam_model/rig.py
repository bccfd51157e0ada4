"""SimulatedRig: the plant a simulator node wraps, one sample at a time, with no ROS in it.

It holds the true state, the last valve command (held between samples like real valves), the
pressure sensor and its random generator, and counts the commands it had to sanitise. With
unmodelled effects on (pam_model.effects) it steps through an EffectsPlant, which
carries their internal states; with every effect off it steps the paper's model exactly as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .effects import Effects, EffectsPlant
from .model import PamModel
from .sensor import PressureSensor
from .valve_voltage import U_MIN, sanitise_command

__all__ = ['RigSample', 'SimulatedRig', 'sanitise_command']


@dataclass(frozen=True)
class RigSample:
    """One sample: time (s), true state [rad, rad/s, Pa, Pa], measured pressures (Pa abs), true
    torque (N m) and muscle forces (N), and the command (V) applied over the step that follows."""

    t: float
    x: np.ndarray
    p_measured: np.ndarray
    torque: float
    force: tuple[float, float]
    u: tuple[float, float]


class SimulatedRig:
    """The simulated joint: step() advances one sample period h of the model."""

    def __init__(self, model: PamModel, x0, sensor: PressureSensor | None = None, seed: int = 0,
                 u0=(U_MIN, U_MIN), effects: Effects | None = None):
        x0 = np.asarray(x0, dtype=float)
        if x0.shape != (4,) or not np.all(np.isfinite(x0)):
            raise ValueError(f'initial state must be 4 finite numbers [rad, rad/s, Pa, Pa], '
                             f'got {list(np.ravel(x0))}')
        self.model = model
        self.sensor = sensor or PressureSensor()
        self._rng = np.random.default_rng(seed)
        self.x = x0.copy()
        if model.locked:
            self.x[1] = 0.0
        self.k = 0
        self.non_finite_commands = 0
        self.out_of_range_commands = 0
        self.u = (U_MIN, U_MIN)
        self.set_command(*u0)
        self.plant = (EffectsPlant(model, effects, self.x, self.u)
                      if effects is not None and effects.active else None)

    @property
    def t(self) -> float:
        """Simulated time of the current sample (s)."""
        return self.k * self.model.h

    @property
    def bad_commands(self) -> int:
        return self.non_finite_commands + self.out_of_range_commands

    def set_command(self, u1: float, u2: float) -> bool:
        """Hold (u1, u2) (V) from now on, sanitised; returns False if it had to be changed."""
        safe = []
        ok = True
        for u in (u1, u2):
            value, problem = sanitise_command(u)
            if problem == 'non-finite':
                self.non_finite_commands += 1
            elif problem:
                self.out_of_range_commands += 1
            ok = ok and not problem
            safe.append(value)
        self.u = (safe[0], safe[1])
        return ok

    def sample(self) -> RigSample:
        """What the sensors read now (draws sensor noise)."""
        if self.plant is None:
            F1, F2, tau = self.model.outputs_at(self.x)
            P_meas = self.sensor.measure(self.x[2:], self._rng)
        else:
            F1, F2, tau = self.plant.outputs(self.x)
            P_meas = self.sensor.measure(self.plant.sensed_pressures(), self._rng)
        return RigSample(t=self.t, x=self.x.copy(), p_measured=P_meas, torque=float(tau),
                         force=(float(F1), float(F2)), u=self.u)

    def step(self) -> None:
        """Advance one period h with the held command."""
        self.step_full()

    def step_full(self):
        """step(), returning the friction torque T_f (N m) and sigma of the step."""
        if self.plant is None:
            self.x, T_f, sigma = self.model.step(self.x, self.u)
        else:
            self.x, T_f, sigma = self.plant.step(self.x, self.u, self.t)
        self.k += 1
        return T_f, sigma
