"""PamModel: one configured model of the joint (parameters, valve map, friction law, force model,
free or locked joint) with the scalar and vectorised step, and the measured outputs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import physics, physics_vectorised
from .parameters import Parameters, load_parameters
from .physics import FORCE_MODELS, FRICTION_LAWS
from .valve_map import ValveMap, load_valve_map

T_S = 1.0e-3  # s, sample period of the rig (1 kHz)


def law_code(name: str, choices: tuple[str, ...], what: str) -> int:
    """Index of a law name, with an error listing the choices."""
    if name not in choices:
        raise ValueError(f'unknown {what} {name!r}; choose one of: {", ".join(choices)}')
    return choices.index(name)


@dataclass(frozen=True)
class PamModel:
    """The antagonistic PAM joint model of MODEL.md section 2.

    params: Table II; valve_map: kappa(u); friction: a name of FRICTION_LAWS; force: a name of
    FORCE_MODELS; locked: joint held at its current angle (torque experiments); h: step (s).
    """

    params: Parameters = field(default_factory=load_parameters)
    valve_map: ValveMap = field(default_factory=load_valve_map)
    friction: str = 'proposed'
    force: str = 'proposed'
    locked: bool = False
    h: float = T_S

    def __post_init__(self):
        object.__setattr__(self, 'params_array', self.params.as_record_array())
        law_code(self.friction, FRICTION_LAWS, 'friction law')
        law_code(self.force, FORCE_MODELS, 'force model')
        if not (np.isfinite(self.h) and self.h > 0.0):
            raise ValueError(f'step h must be > 0 s, got {self.h!r}')

    @property
    def friction_code(self) -> int:
        return FRICTION_LAWS.index(self.friction)

    @property
    def force_code(self) -> int:
        return FORCE_MODELS.index(self.force)

    def openings(self, u) -> np.ndarray:
        """alpha = kappa(u) for voltages u (V), any shape."""
        return self.valve_map(u)

    def step(self, x, u):
        """Scalar path: x (4,) [rad, rad/s, Pa, Pa], u (2,) V held over the step.

        Returns (x_next (4,), T_f in N m, sigma in 1..18).
        """
        x_next = np.empty(4)
        T_f, sigma = physics.step_array(np.asarray(x, dtype=float), float(u[0]), float(u[1]),
                                        self.h, self.params_array, self.valve_map.u,
                                        self.valve_map.alpha, self.friction_code,
                                        self.force_code, self.locked, x_next)
        return x_next, T_f, sigma

    def step_many(self, X, u):
        """Vectorised path: states X (N, 4), voltages u (N, 2) or (2,) in V.

        Returns (X_next (N, 4), T_f (N,), sigma (N,)).
        """
        return physics_vectorised.rk4_steps(X, self.openings(u), self.h, self.params,
                                            self.friction_code, self.force_code, self.locked)

    def outputs(self, X):
        """Forces and torque at states X (..., 4): (F1 N, F2 N, tau N m), eq. (6)-(8)."""
        X = np.asarray(X, dtype=float)
        F1, F2 = physics_vectorised.muscle_forces(X[..., 0], X[..., 2], X[..., 3], self.params,
                                                  self.force_code)
        return F1, F2, physics_vectorised.joint_torque(X[..., 0], F1, F2, self.params)
