"""The UKF with bias states (docs/model_extensions.md, "Bias states"): an option of PamUkf.

State x = [psi, psi_dot, P1, P2, b1, b2, b_tau] (rad, rad/s, Pa, Pa, Pa, Pa, N m): the paper's
four plus random-walk biases for what the pressures alone cannot pin down:

* b1, b2 (Pa), the pressure sensors' offsets: the (extension-corrected) reading is
  y = [P1 + b1, P2 + b2] + v;
* b_tau (N m), a joint-torque bias: added to eq. (8)'s torque in the angle dynamics and to the
  torque output. It enters the step as opposite hysteresis-like forces +-b_tau / (2 r cos psi)
  on the two muscles (pam_model.effects_physics.step_with_effects), which adds exactly b_tau to
  r cos(psi) (F1 - F2) and leaves F1 + F2 (the friction law's load) unchanged.

Biases are random walks: b(k) = b(k-1) + w, w ~ N(0, q h) with q the BiasStates' rates
(Pa^2/s, (N m)^2/s). One step: Julier sigma points (n = 7, kappa = 0), each advanced by
step_with_effects with its own b_tau (the biases carried unchanged), prior + Q, sigma points
redrawn, update with g(x) = [P1 + b1, P2 + b2], outputs at the posterior. A locked joint holds
psi and psi_dot as the paper's filter does. The kernel is numba; the valve lag, hysteresis memory,
sensor gain/offset correction and supply handling are PamUkf's own (pam_ukf.py).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from pam_model.effects_physics import (
    forces_with_hysteresis,
    friction_with_hysteresis,
    step_with_effects,
)
from pam_model.physics import PSI_MAX, joint_torque, muscle_forces, subsystem_index

from .unscented import (
    julier_sigma_points,
    julier_weights,
    measurement_update,
    symmetrise,
    unscented_transform,
)

N_BIASED = 7
KAPPA = 0.0
LOCKED_VARIANCE = 1e-12      # rad^2 and (rad/s)^2 kept on psi, psi_dot of a locked joint
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


@njit(cache=True)
def hold_locked_biased(x, P, lock_angle):
    """A locked joint: psi = lock_angle, psi_dot = 0, their rows reduced to a tiny diagonal."""
    x = x.copy()
    P = P.copy()
    x[0] = lock_angle
    x[1] = 0.0
    for i in range(2):
        for j in range(N_BIASED):
            P[i, j] = 0.0
            P[j, i] = 0.0
        P[i, i] = LOCKED_VARIANCE
    return x, P


@njit(cache=True)
def bias_predict_correct(x, P, alpha1, alpha2, y, Q, R, h, p_array, friction_law, force_model,
                         locked, lock_angle, nis_gate, info, V_d, F_h1, F_h2):
    """pam_ukf.predict_correct_with_effects (same arguments) for the biased filter from x (7,),
    P (7, 7), with the dead volume V_d (m^3) and the hysteresis forces F_h1, F_h2 (N). Returns
    (x_post, P_post, F1, F2), F1, F2 the posterior's eq. (6) forces (N) without bias or
    hysteresis (they drive the hysteresis memory); info receives nis, valid, accepted, repairs
    (pam_ukf.INFO_FIELDS). y is already corrected for the sensors' extensions (non-finite: no
    update)."""
    W = julier_weights(N_BIASED, KAPPA)
    sigmas, rep1 = julier_sigma_points(x, P, KAPPA)
    sigmas_f = np.empty_like(sigmas)
    nxt = np.empty(4)
    for i in range(sigmas.shape[0]):
        fh1, fh2 = torque_forces(sigmas[i, 0], sigmas[i, 6], p_array[0], F_h1, F_h2)
        step_with_effects(sigmas[i, :4], alpha1, alpha2, h, p_array, friction_law, force_model,
                          locked, V_d, fh1, fh2, nxt)
        sigmas_f[i, :4] = nxt
        sigmas_f[i, 4:] = sigmas[i, 4:]
    x_prior, P_prior = unscented_transform(sigmas_f, W, Q)
    P_prior = symmetrise(P_prior)
    if locked:
        x_prior, P_prior = hold_locked_biased(x_prior, P_prior, lock_angle)
    sigmas_p, rep2 = julier_sigma_points(x_prior, P_prior, KAPPA)
    valid = np.isfinite(y[0]) and np.isfinite(y[1])
    nis = 0.0
    accepted = False
    x_post, P_post = x_prior, P_prior
    if valid:
        Y = sigmas_p[:, 2:4] + sigmas_p[:, 4:6]
        x_post, P_post, nis, accepted = measurement_update(x_prior, P_prior, sigmas_p, Y, W, R,
                                                           y, nis_gate)
        if not np.isfinite(nis):
            nis = 0.0
    if locked:
        x_post, P_post = hold_locked_biased(x_post, P_post, lock_angle)
    info[0] = nis
    info[1] = valid
    info[2] = accepted
    info[3] = int(rep1) + int(rep2)
    F1, F2 = muscle_forces(x_post[0], x_post[2], x_post[3], p_array[0], force_model)
    return x_post, P_post, F1, F2


@njit(cache=True)
def bias_outputs(x, P, x_post, P_post, h, p_array, friction_law, force_model, locked, F_h1, F_h2,
                 info):
    """pam_ukf.estimate_outputs for the biased state: torque = eq. (8) + b_tau (N m), its variance
    through the posterior's sigma points, forces (N) with the hysteresis forces F_h1, F_h2 (N);
    x, P become the posterior if it is finite (info[9])."""
    p = p_array[0]
    W = julier_weights(N_BIASED, KAPPA)
    F1, F2 = forces_with_hysteresis(x_post[0], x_post[2], x_post[3], p, force_model, F_h1, F_h2)
    tau = joint_torque(x_post[0], F1, F2, p) + x_post[6]
    sigmas_o, rep3 = julier_sigma_points(x_post, P_post, KAPPA)
    taus = np.empty(sigmas_o.shape[0])
    for i in range(sigmas_o.shape[0]):
        f1, f2 = forces_with_hysteresis(sigmas_o[i, 0], sigmas_o[i, 2], sigmas_o[i, 3], p,
                                        force_model, F_h1, F_h2)
        taus[i] = joint_torque(sigmas_o[i, 0], f1, f2, p) + sigmas_o[i, 6]
    tau_mean = W @ taus
    tau_variance = W @ ((taus - tau_mean) ** 2)
    if locked:
        sliding = False
    else:
        fh1, fh2 = torque_forces(x_post[0], x_post[6], p, F_h1, F_h2)
        _, sliding = friction_with_hysteresis(x_post[0], x_post[1], x_post[2], x_post[3], h, p,
                                              friction_law, force_model, fh1, fh2)
    sigma = subsystem_index(sliding, x_post[2], x_post[3], p)
    finite = (np.all(np.isfinite(x_post)) and np.all(np.isfinite(P_post)) and np.isfinite(tau)
              and np.isfinite(tau_variance))
    if finite:
        x[:] = x_post
        P[:, :] = P_post
    info[3] += int(rep3)
    info[4] = F1
    info[5] = F2
    info[6] = tau
    info[7] = tau_variance
    info[8] = sigma
    info[9] = finite
