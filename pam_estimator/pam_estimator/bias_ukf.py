"""The UKF's bias states (docs/model_extensions.md, "Bias states"): an option of PamUkf, whose
kernels (pam_ukf.py) take the 7-state x below as they take the paper's 4.

State x = [psi, psi_dot, P1, P2, b1, b2, b_tau] (rad, rad/s, Pa, Pa, Pa, Pa, N m): the paper's
four plus random-walk biases for what the pressures alone cannot pin down:

* b1, b2 (Pa), the pressure sensors' offsets: the (extension-corrected) reading is
  y = [P1 + b1, P2 + b2] + v;
* b_tau (N m), a joint-torque bias: added to eq. (8)'s torque in the angle dynamics and to the
  torque output. It enters the step as opposite hysteresis-like forces +-b_tau / (2 r cos psi)
  on the two muscles (pam_model.effects_physics.step_with_effects), which adds exactly b_tau to
  r cos(psi) (F1 - F2) and leaves F1 + F2 (the friction law's load) unchanged.

Biases are random walks: b(k) = b(k-1) + w, w ~ N(0, q h) with q the BiasStates' rates
(Pa^2/s, (N m)^2/s). One step (pam_ukf.predict_correct_with_effects, estimate_outputs): Julier
sigma points (n = 7, kappa = 0), each advanced by step_with_effects with its own b_tau (the biases
carried unchanged), prior + Q, sigma points redrawn, update with g(x) = [P1 + b1, P2 + b2],
outputs at the posterior (torque + b_tau). A locked joint holds psi and psi_dot as the paper's
filter does. The valve lag, hysteresis memory and sensor gain/offset correction are
ukf_step_with_effects' own, the supply handling PamUkf's. Here: the options and the
torque-to-forces map.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from pam_model.physics import PSI_MAX

N_BIASED = 7
#: Smallest |cos psi| used to turn b_tau into muscle forces (the guard box keeps |psi| <= PSI_MAX).
MIN_COS = max(math.cos(PSI_MAX), 1e-3)


class BiasStates(NamedTuple):
    """Random-walk rates q (per second) and initial variances of the bias states.

    sensor_rate: Pa^2/s per channel; sensor_variance: Pa^2 (P(0) of b1, b2); torque_rate:
    (N m)^2/s; torque_variance: (N m)^2 (P(0) of b_tau), > 0. The defaults freeze b_tau at 0
    (rate 0, a negligible variance): a free torque bias trades off against the angle, which no
    sensor sees, and made the free joint's angle worse on the realistic rig (docs/
    model_extensions.md); TORQUE_BIAS_STATES lets it move."""

    sensor_rate: float = 1.0e4          # (100 Pa)^2 per second
    sensor_variance: float = 2.5e7      # (5 kPa)^2
    torque_rate: float = 0.0            # b_tau frozen ...
    torque_variance: float = 1.0e-9     # ... at 0 (3e-5 N m)

    def validate(self) -> BiasStates:
        for name in self._fields:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f'bias_states.{name} must be a finite number >= 0, got {value!r}')
        if self.sensor_variance <= 0.0 or self.torque_variance <= 0.0:
            raise ValueError('bias_states initial variances must be > 0')
        return self

    def q_diag(self, h: float) -> np.ndarray:
        """The biases' process-noise variances over one step of h (s)."""
        return np.array([self.sensor_rate, self.sensor_rate, self.torque_rate]) * h

    def p0_diag(self) -> np.ndarray:
        """The biases' initial variances."""
        return np.array([self.sensor_variance, self.sensor_variance, self.torque_variance])


#: The defaults above (SI units): the sensors' offsets move, b_tau stays at 0.
DEFAULT_BIAS_STATES = BiasStates()
#: The sensors' offsets and a moving torque bias: (0.1 N m)^2/s from (0.5 N m)^2.
TORQUE_BIAS_STATES = BiasStates(torque_rate=1.0e-2, torque_variance=0.25)


@njit(cache=True)
def torque_forces(psi, b_tau, p, F_h1, F_h2):
    """The muscle forces (N) that add b_tau (N m) to eq. (8)'s torque, plus F_h1, F_h2."""
    c = math.cos(psi)
    if abs(c) < MIN_COS:
        c = math.copysign(MIN_COS, c) if c != 0.0 else MIN_COS
    d = b_tau / (2.0 * p.r * c)
    return F_h1 + d, F_h2 - d
