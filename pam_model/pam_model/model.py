"""PamModel: one configured model of the joint (parameters, valve map, friction law, force model,
free or locked joint) with the scalar and vectorised step, and the measured outputs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from . import physics, physics_vectorised
from .model_choices import ForceModel, FrictionLaw
from .parameters import Parameters, load_parameters
from .valve_map import ValveMap, load_valve_map

T_S = 1.0e-3  # s, sample period of the rig (1 kHz)


class KernelModel(NamedTuple):
    """A configured model as the compiled (numba) kernels take it, in one record: step h (s),
    the Parameters record array (1,), the valve map's nodes kappa_u (V) and kappa_alpha (-),
    the friction law's and force model's codes, and whether the joint is locked."""

    h: float
    p_array: np.ndarray
    kappa_u: np.ndarray
    kappa_alpha: np.ndarray
    friction_law: int
    force_model: int
    locked: bool


@dataclass(frozen=True)
class PamModel:
    """The antagonistic PAM joint model of MODEL.md section 2.

    params: Table II; valve_map: kappa(u); friction: a FrictionLaw, its name or its value; force:
    a ForceModel, its name or its value (both kept as the name: 'proposed'); locked: joint held at
    its current angle (torque experiments); h: step (s). Anything else is a ValueError listing the
    names. Derived: friction_law, force_model (the members) and friction_code, force_code (their
    plain integers, what the numba kernels take).
    """

    params: Parameters = field(default_factory=load_parameters)
    valve_map: ValveMap = field(default_factory=load_valve_map)
    friction: FrictionLaw | str = str(FrictionLaw.PROPOSED)
    force: ForceModel | str = str(ForceModel.PROPOSED)
    locked: bool = False
    h: float = T_S

    def __post_init__(self):
        object.__setattr__(self, 'params_array', self.params.as_record_array())
        friction_law = FrictionLaw.coerce(self.friction)
        force_model = ForceModel.coerce(self.force)
        for name, value in (('friction', str(friction_law)), ('force', str(force_model)),
                            ('friction_law', friction_law), ('force_model', force_model),
                            ('friction_code', int(friction_law)),
                            ('force_code', int(force_model))):
            object.__setattr__(self, name, value)
        if not (np.isfinite(self.h) and self.h > 0.0):
            raise ValueError(f'step h must be > 0 s, got {self.h!r}')

    def kernel_model(self, p_array: np.ndarray | None = None) -> KernelModel:
        """This model as the kernels take it; `p_array` replaces params_array (e.g. a copy whose
        P_tank a step writes)."""
        return KernelModel(float(self.h), self.params_array if p_array is None else p_array,
                           self.valve_map.u, self.valve_map.alpha, int(self.friction_code),
                           int(self.force_code), bool(self.locked))

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
                                            self.friction_law, self.force_model, self.locked)

    def outputs_at(self, x) -> tuple[float, float, float]:
        """outputs() of one state x (4,) as plain floats (F1 N, F2 N, tau N m): one compiled
        call, for the per-sample paths (the simulated rig, the estimator's reset)."""
        return physics.outputs_array(np.asarray(x, dtype=float), self.params_array,
                                     self.force_code)

    def outputs(self, X):
        """Forces and torque at states X (..., 4): (F1 N, F2 N, tau N m), eq. (6)-(8)."""
        X = np.asarray(X, dtype=float)
        F1, F2 = physics_vectorised.muscle_forces(X[..., 0], X[..., 2], X[..., 3], self.params,
                                                  self.force_model)
        return F1, F2, physics_vectorised.joint_torque(X[..., 0], F1, F2, self.params)
