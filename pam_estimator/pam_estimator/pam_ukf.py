"""The sensor-less UKF of MODEL.md section 5 over the pam_model hybrid model.

State x = [psi, psi_dot, P1, P2] (rad, rad/s, Pa abs, Pa abs); measurement y = [P1, P2] (Pa abs);
input u(k-1) = the valve voltages (V) held over the step just ended. One step:

1. Julier sigma points (n = 4, kappa = 0) of (x_hat, P); each advanced by the pam_model RK4 step
   (friction held per sigma point) with u(k-1);
2. prior x_hat-, P- = unscented transform + Q; P- symmetrised;
3. sigma points redrawn from (x_hat-, P-) (as filterpy 2.x does), observed through g(x) = [P1, P2];
4. K = P_xy P_yy^-1, posterior; P symmetrised. A non-finite or out-of-range measurement skips
   step 4 (counted), so does an innovation whose NIS exceeds the optional gate;
5. outputs at the estimate: F1, F2 by eq. (6), tau = r cos(psi) (F1 - F2), its variance through
   the posterior sigma points, and the subsystem index sigma.
A Cholesky factorisation that fails falls back to an eigenvalue clip (counted). Locked joint: the
angle is held at the lock angle with a tiny variance, psi_dot = 0.
The whole step is one compiled numba kernel (see the README for why): ukf_step for the paper's
model; with model extensions or a measured supply pressure (docs/model_extensions.md)
ukf_step_with_effects, which also holds the valve lag and the hysteresis memory (their states are
arrays the kernel updates in place). The option bias_states (bias_ukf.py) takes the same kernel
with a 7-state x (sensor offsets, torque bias).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import NamedTuple

import numpy as np
from numba import njit

from pam_model.effects import HYSTERESIS_PRESSURE, Effects, MaxwellSlip, ValveLag
from pam_model.effects_physics import (
    band_scale,
    bouc_wen_advance,
    bouc_wen_update,
    maxwell_slip_update,
    step_with_effects,
)
from pam_model.model import PamModel
from pam_model.model_extensions import ESTIMATOR_FIELDS, NO_EXTENSIONS
from pam_model.physics import (
    friction_torque,
    joint_torque,
    muscle_forces,
    muscle_lengths,
    rk4_step,
    sanitised_voltage,
    subsystem_index,
    valve_opening,
)
from pam_model.rest import REST_STATE

from .bias_ukf import N_BIASED, BiasStates, torque_forces
from .unscented import (
    julier_sigma_points,
    julier_weights,
    measurement_update,
    symmetrise,
    unscented_transform,
)
from .valid_readings import NIS_GATE_OFF, PRESSURE_MAX, PRESSURE_MIN

N_STATE = 4
KAPPA = 0.0
_NO_MEASUREMENT = (math.nan, math.nan)   # Pa: a sample that never came (PamUkf.coast)
LOCKED_VARIANCE = 1e-12      # rad^2 and (rad/s)^2 kept on psi, psi_dot of a locked joint


@njit(cache=True)
def propagate(sigmas, alpha1, alpha2, h, p, friction_law, force_model, locked):
    """Each sigma point (rows of sigmas) advanced one RK4 step with the openings alpha."""
    out = np.empty_like(sigmas)
    for i in range(sigmas.shape[0]):
        psi, psi_dot, P1, P2, _, _ = rk4_step(sigmas[i, 0], sigmas[i, 1], sigmas[i, 2],
                                              sigmas[i, 3], alpha1, alpha2, h, p, friction_law,
                                              force_model, locked)
        out[i, 0] = psi
        out[i, 1] = psi_dot
        out[i, 2] = P1
        out[i, 3] = P2
    return out


@njit(cache=True)
def hold_locked(x, P, lock_angle):
    """A locked joint: psi = lock_angle, psi_dot = 0, their covariance rows reduced to a tiny
    diagonal (the torque meter holds the joint). Any state length (the bias states too)."""
    x = x.copy()
    P = P.copy()
    x[0] = lock_angle
    x[1] = 0.0
    for i in range(2):
        for j in range(x.shape[0]):
            P[i, j] = 0.0
            P[j, i] = 0.0
        P[i, i] = LOCKED_VARIANCE
    return x, P


#: Layout of the `info` array ukf_step fills (one float each), and each field's index (module
#: constants: numba compiles them in as literals)
INFO_FIELDS = ('nis', 'valid', 'accepted', 'repairs', 'force1', 'force2', 'torque',
               'torque_variance', 'subsystem', 'finite')
(INFO_NIS, INFO_VALID, INFO_ACCEPTED, INFO_REPAIRS, INFO_FORCE1, INFO_FORCE2, INFO_TORQUE,
 INFO_TORQUE_VARIANCE, INFO_SUBSYSTEM, INFO_FINITE) = range(len(INFO_FIELDS))


@njit(cache=True)
def propagate_with_effects(sigmas, alpha1, alpha2, h, p_array, friction_law, force_model, locked,
                           V_d, F_h1, F_h2, loop, loop_state):
    """propagate() through pam_model.effects_physics.step_with_effects: dead volume V_d (m^3) in
    eq. (4), Maxwell-slip forces F_h1, F_h2 (N) held over the step, the same for every point;
    with a Bouc-Wen loop (loop: an EstimatorEffects, its band != 0) each point adds the loop's
    force at its own driver, z advanced from the memory loop_state (rows: z, the driver before)
    (held over the step: the loop acts per sigma point, as the friction does). With the
    bias states (7 columns) each point's b_tau adds its torque_forces and the biases are carried
    unchanged."""
    out = np.empty_like(sigmas)
    biased = sigmas.shape[1] > N_STATE
    drive = np.empty(2)
    for i in range(sigmas.shape[0]):
        fh1, fh2 = F_h1, F_h2
        if loop.bouc_wen_band != 0.0:
            bouc_wen_drive(sigmas[i], p_array[0], loop.bouc_wen_by_length,
                           loop.bouc_wen_travel, drive)
            fh1 += bouc_wen_force(sigmas[i, 2], loop,
                                  bouc_wen_advance(loop_state[0, 0], drive[0] - loop_state[1, 0]))
            fh2 += bouc_wen_force(sigmas[i, 3], loop,
                                  bouc_wen_advance(loop_state[0, 1], drive[1] - loop_state[1, 1]))
        if biased:
            fh1, fh2 = torque_forces(sigmas[i, 0], sigmas[i, 6], p_array[0], fh1, fh2)
            out[i, N_STATE:] = sigmas[i, N_STATE:]
        step_with_effects(sigmas[i], alpha1, alpha2, h, p_array, friction_law, force_model,
                          locked, V_d, fh1, fh2, out[i])
    return out


@njit(cache=True)
def correct(sigmas_f, Q, R, y, locked, lock_angle, nis_gate, y_min, y_max, info):
    """Steps 2-4 of the module doc from the propagated sigma points: the posterior (x, P);
    info receives nis, valid, accepted and the repairs of this part. With the bias states
    (7 columns) g(x) = [P1 + b1, P2 + b2]."""
    W = julier_weights(sigmas_f.shape[1], KAPPA)
    x_prior, P_prior = unscented_transform(sigmas_f, W, Q)
    P_prior = symmetrise(P_prior)
    if locked:
        x_prior, P_prior = hold_locked(x_prior, P_prior, lock_angle)
    sigmas_p, rep2 = julier_sigma_points(x_prior, P_prior, KAPPA)
    valid = (np.isfinite(y[0]) and np.isfinite(y[1]) and y_min <= y[0] <= y_max
             and y_min <= y[1] <= y_max)
    nis = 0.0
    accepted = False
    x_post, P_post = x_prior, P_prior
    if valid:
        Y = sigmas_p[:, 2:4].copy()
        if sigmas_p.shape[1] > N_STATE:
            Y += sigmas_p[:, 4:6]
        x_post, P_post, nis, accepted = measurement_update(x_prior, P_prior, sigmas_p, Y, W, R,
                                                           y, nis_gate)
        if not np.isfinite(nis):
            nis = 0.0
    if locked:
        x_post, P_post = hold_locked(x_post, P_post, lock_angle)
    info[INFO_NIS] = nis
    info[INFO_VALID] = valid
    info[INFO_ACCEPTED] = accepted
    info[INFO_REPAIRS] = int(rep2)
    return x_post, P_post


@njit(cache=True)
def estimate_outputs(x, P, x_post, P_post, h, p_array, friction_law, force_model, locked, F_h1,
                     F_h2, info):
    """Step 5 at the posterior, with the hysteresis forces F_h1, F_h2 (N; 0 in the paper's
    model) in eq. (6): forces, torque, its variance, sigma into info; x, P become the posterior
    if it is finite (info[INFO_FINITE]). With the bias states (7 entries) the torque gains b_tau."""
    p = p_array[0]
    biased = x_post.shape[0] > N_STATE
    W = julier_weights(x_post.shape[0], KAPPA)
    F1, F2 = muscle_forces(x_post[0], x_post[2], x_post[3], p, force_model, F_h1, F_h2)
    tau = joint_torque(x_post[0], F1, F2, p)
    if biased:
        tau += x_post[6]
    sigmas_o, rep3 = julier_sigma_points(x_post, P_post, KAPPA)
    taus = np.empty(sigmas_o.shape[0])
    for i in range(sigmas_o.shape[0]):
        f1, f2 = muscle_forces(sigmas_o[i, 0], sigmas_o[i, 2], sigmas_o[i, 3], p,
                                        force_model, F_h1, F_h2)
        taus[i] = joint_torque(sigmas_o[i, 0], f1, f2, p)
        if biased:
            taus[i] += sigmas_o[i, 6]
    tau_mean = W @ taus
    tau_variance = W @ ((taus - tau_mean) ** 2)
    if locked:
        sliding = False
    else:
        fh1, fh2 = F_h1, F_h2
        if biased:
            fh1, fh2 = torque_forces(x_post[0], x_post[6], p, F_h1, F_h2)
        _, sliding = friction_torque(x_post[0], x_post[1], x_post[2], x_post[3], h, p,
                                     friction_law, force_model, fh1, fh2)
    sigma = subsystem_index(sliding, x_post[2], x_post[3], p)
    finite = np.all(np.isfinite(x_post)) and np.all(np.isfinite(P_post)) and np.isfinite(
        tau) and np.isfinite(tau_variance)
    if finite:
        x[:] = x_post
        P[:, :] = P_post
    info[INFO_REPAIRS] += int(rep3)
    info[INFO_FORCE1] = F1
    info[INFO_FORCE2] = F2
    info[INFO_TORQUE] = tau
    info[INFO_TORQUE_VARIANCE] = tau_variance
    info[INFO_SUBSYSTEM] = sigma
    info[INFO_FINITE] = finite


class FilterSettings(NamedTuple):
    """The filter's fixed settings as the kernels take them, in one record: Q (n, n) and R
    (2, 2) in the state's and the measurement's SI units squared, lock_angle (rad, where a
    locked joint is held), nis_gate (0: off) and the valid readings [y_min, y_max] (Pa abs)."""

    Q: np.ndarray
    R: np.ndarray
    lock_angle: float
    nis_gate: float
    y_min: float
    y_max: float


@njit(cache=True)
def ukf_step(x, P, u_prev, y, model, settings, info):
    """One predict + update of the paper's model, in place: x (4,) and P (4, 4) become the
    posterior and info (10,) receives INFO_FIELDS (nis is 0 when the measurement was not valid).
    If the posterior were not finite, x and P are left unchanged and info[INFO_FINITE] = 0.
    model: a pam_model KernelModel; settings: a FilterSettings."""
    alpha1 = valve_opening(u_prev[0], model.kappa_u, model.kappa_alpha)
    alpha2 = valve_opening(u_prev[1], model.kappa_u, model.kappa_alpha)
    sigmas, rep1 = julier_sigma_points(x, P, KAPPA)
    sigmas_f = propagate(sigmas, alpha1, alpha2, model.h, model.p_array[0], model.friction_law,
                         model.force_model, model.locked)
    x_post, P_post = correct(sigmas_f, settings.Q, settings.R, y, model.locked,
                             settings.lock_angle, settings.nis_gate, settings.y_min,
                             settings.y_max, info)
    info[INFO_REPAIRS] += int(rep1)
    estimate_outputs(x, P, x_post, P_post, model.h, model.p_array, model.friction_law,
                     model.force_model, model.locked, 0.0, 0.0, info)


@njit(cache=True)
def predict_correct_with_effects(x, P, alpha1, alpha2, y, Q, R, h, p_array, friction_law,
                                 force_model, locked, lock_angle, nis_gate, info, V_d, F_h1,
                                 F_h2, loop, loop_state):
    """ukf_step's predict and update with the estimator's extensions: openings alpha already
    lagged, dead volume V_d (m^3), Maxwell-slip forces F_h1, F_h2 (N) held over the step, the
    Bouc-Wen loop per sigma point (propagate_with_effects), P_tank of the step in p_array; y
    already corrected for the sensors (non-finite = no update). Returns (x_post, P_post, F1,
    F2): the posterior and its nominal eq. (6) forces (N), which drive the Maxwell slip."""
    sigmas, rep1 = julier_sigma_points(x, P, KAPPA)
    sigmas_f = propagate_with_effects(sigmas, alpha1, alpha2, h, p_array, friction_law,
                                      force_model, locked, V_d, F_h1, F_h2, loop, loop_state)
    x_post, P_post = correct(sigmas_f, Q, R, y, locked, lock_angle, nis_gate, -np.inf, np.inf,
                             info)
    info[INFO_REPAIRS] += int(rep1)
    F1, F2 = muscle_forces(x_post[0], x_post[2], x_post[3], p_array[0], force_model)
    return x_post, P_post, F1, F2


class EstimatorEffects(NamedTuple):
    """The estimator's extensions as ukf_step_with_effects takes them, in one record: the valve
    lag's per-step decay e^(-h/tau) and mean weight (-; 0, 0: no lag), sensor offset o (2,) Pa
    and gain 1 + g (2,) (-), dead volume V_d (m^3), the Maxwell-slip elements' slip forces
    (n,) N at 500 kPa and stiffnesses (n,) N/N (n = 0: no Maxwell slip) with P_out (Pa abs),
    and the Bouc-Wen loop: its band B_w (N at 500 kPa, signed; 0: none), driven by the muscle
    length (True) or pressure (False), its travel (m or Pa per e-fold of z)."""

    valve_decay: float
    valve_mean_weight: float
    sensor_offset: np.ndarray
    sensor_gain: np.ndarray
    dead_volume: float
    slip: np.ndarray
    stiffness: np.ndarray
    p_out: float
    bouc_wen_band: float
    bouc_wen_by_length: bool
    bouc_wen_travel: float


@njit(cache=True)
def bouc_wen_force(P, loop, z):
    """N: the Bouc-Wen loop's force B_w c(P) z of a muscle at pressure P (Pa abs) with state z
    (-); loop: an EstimatorEffects."""
    return loop.bouc_wen_band * band_scale(P, loop.p_out, HYSTERESIS_PRESSURE) * z


@njit(cache=True)
def bouc_wen_drive(x, p, by_length, travel, out):
    """out (2,) (-): the Bouc-Wen driver of each muscle at state x over its travel: the lengths
    l1, l2 (m) at psi (by_length) or the pressures P1, P2 (Pa), divided by travel (m or Pa)."""
    if by_length:
        l1, l2 = muscle_lengths(x[0], p)
        out[0], out[1] = l1 / travel, l2 / travel
    else:
        out[0], out[1] = x[2] / travel, x[3] / travel


@njit(cache=True)
def ukf_step_with_effects(x, P, u_prev, y, model, settings, effects, valve, anchor, bouc_wen,
                          F_h, info):
    """One predict + update with the estimator's extensions, in place, as ukf_step: u_prev (2,)
    V sanitised and lagged through the valve state valve (3,) = [started, u_f1, u_f2] (V; the
    first command starts the lag at itself); a raw reading y (2,) Pa outside [y_min, y_max]
    (or non-finite) means no update, else it is corrected to (y - o) / (1 + g); the hysteresis
    memory anchor (2, n) N moves with the finite posterior's eq. (6) forces and F_h (2,) N
    (held over the next step) takes its new forces when the posterior is finite; the Bouc-Wen
    memory bouc_wen (3, 2) = [z, the driver before (-), the loop's force (N)] moves with the
    finite posterior's driver (the prediction adds the loop per sigma point; the outputs add
    its force at the posterior). model: a
    KernelModel (P_tank of the step in its p_array); settings: a FilterSettings; effects: an
    EstimatorEffects; info (10,) receives INFO_FIELDS."""
    u1, u2 = sanitised_voltage(u_prev[0]), sanitised_voltage(u_prev[1])
    if valve[0] == 0.0:
        valve[0], valve[1], valve[2] = 1.0, u1, u2
    f1, f2 = valve[1], valve[2]
    mean1 = u1 + (f1 - u1) * effects.valve_mean_weight
    mean2 = u2 + (f2 - u2) * effects.valve_mean_weight
    valve[1] = u1 + (f1 - u1) * effects.valve_decay
    valve[2] = u2 + (f2 - u2) * effects.valve_decay
    alpha1 = valve_opening(mean1, model.kappa_u, model.kappa_alpha)
    alpha2 = valve_opening(mean2, model.kappa_u, model.kappa_alpha)
    y_corrected = np.full(2, np.nan)             # a faulty raw reading: no update
    if (settings.y_min <= y[0] <= settings.y_max
            and settings.y_min <= y[1] <= settings.y_max):      # False for NaN
        for i in range(2):
            y_corrected[i] = (y[i] - effects.sensor_offset[i]) / effects.sensor_gain[i]
    x_post, P_post, F1, F2 = predict_correct_with_effects(
        x, P, alpha1, alpha2, y_corrected, settings.Q, settings.R, model.h, model.p_array,
        model.friction_law, model.force_model, model.locked, settings.lock_angle,
        settings.nis_gate, info, effects.dead_volume, F_h[0], F_h[1], effects, bouc_wen)
    F_h_next = F_h.copy()
    if effects.slip.size > 0 and np.all(np.isfinite(x_post)):
        s = np.array((F1, F2))
        maxwell_slip_update(s, x_post[2:4], effects.slip, effects.stiffness, effects.p_out,
                            HYSTERESIS_PRESSURE, anchor, F_h_next)
    F_out = F_h_next
    if effects.bouc_wen_band != 0.0:
        if np.all(np.isfinite(x_post)):
            drive = np.empty(2)
            bouc_wen_drive(x_post, model.p_array[0], effects.bouc_wen_by_length,
                           effects.bouc_wen_travel, drive)
            bouc_wen_update(drive, bouc_wen[1], bouc_wen[0], effects.bouc_wen_band, x_post[2:4],
                            effects.p_out, HYSTERESIS_PRESSURE, bouc_wen[2])
        F_out = F_h_next + bouc_wen[2]
    estimate_outputs(x, P, x_post, P_post, model.h, model.p_array, model.friction_law,
                     model.force_model, model.locked, F_out[0], F_out[1], info)
    if info[INFO_FINITE]:
        F_h[:] = F_h_next


class UkfTuning(NamedTuple):
    """Diagonals of Q (process), R (measurement) and P(0), in the state's SI units squared."""

    Q: tuple
    R: tuple
    P0: tuple

    def validate(self) -> UkfTuning:
        for name, diag, size in (('Q', self.Q, 4), ('R', self.R, 2), ('P0', self.P0, 4)):
            values = np.asarray(diag, dtype=float)
            if values.shape != (size,):
                raise ValueError(f'UKF {name} needs {size} diagonal entries, got {len(values)}')
            if not np.all(np.isfinite(values)) or np.any(values < 0.0):
                raise ValueError(f'UKF {name} entries must be finite and >= 0, got {list(diag)}')
            if name != 'Q' and np.any(values <= 0.0):
                raise ValueError(f'UKF {name} entries must be > 0, got {list(diag)}')
        return self


#: The paper's tuning: P(0) = Q = diag(1e-5, 1e-4, 1e6, 1e6), R = diag(1e8, 1e8).
PAPER_TUNING = UkfTuning(Q=(1e-5, 1e-4, 1e6, 1e6), R=(1e8, 1e8), P0=(1e-5, 1e-4, 1e6, 1e6))
#: Default tuning, chosen on the simulated rig with the 'mild' plant mismatch (README).
DEFAULT_TUNING = UkfTuning(Q=(1e-9, 1e-6, 1e3, 1e3), R=(4e6, 4e6), P0=(1e-5, 1e-4, 1e6, 1e6))
TUNINGS = {'default': DEFAULT_TUNING, 'paper': PAPER_TUNING}


class UkfOutput(NamedTuple):
    """One estimate: state (rad, rad/s, Pa, Pa), forces (N), torque (N m) and health."""

    x: np.ndarray
    P: np.ndarray
    force1: float
    force2: float
    torque: float
    torque_variance: float
    subsystem: int
    nis: float
    update_skipped: bool


@dataclass
class PamUkf:
    """The estimator: call step(y, u_prev) once per pressure sample.

    y_range (Pa abs): measurements outside are rejected (sensor fault) and counted; nis_gate > 0
    rejects innovations with a larger NIS (chi-square with 2 degrees of freedom: 13.8 is 0.1 %).
    extensions: the model's extensions (pam_model.model_extensions; docs/model_extensions.md),
    the paper's model by default (NO_EXTENSIONS: the same numbers as before, bit for bit):
    valve lag of the known commands (pam_model.effects.ValveLag), dead volume V_d in eq. (4),
    Maxwell-slip force hysteresis driven by the posterior's eq. (6) forces and held over the next
    step (the same for every sigma point), a Bouc-Wen loop (pam_model.effects.BoucWen) whose
    memory follows the posterior's muscle lengths or pressures and whose force each sigma point
    takes at its own driver (both in the outputs), sensor offset o and gain error g: the
    reading y becomes (y - o) / (1 + g) before the update (the range check is on y).
    bias_states: None (the default: the 4-state filter, unchanged) or a bias_ukf.BiasStates: the
    state grows to [psi, psi_dot, P1, P2, b1, b2, b_tau] with random-walk sensor offsets b1, b2
    (Pa) and a joint-torque bias b_tau (N m) (bias_ukf.py; docs/model_extensions.md).
    """

    model: PamModel = field(default_factory=PamModel)
    tuning: UkfTuning = DEFAULT_TUNING
    x0: tuple = REST_STATE
    nis_gate: float = NIS_GATE_OFF
    y_range: tuple = (PRESSURE_MIN, PRESSURE_MAX)
    extensions: Effects = NO_EXTENSIONS
    bias_states: BiasStates | None = None

    def __post_init__(self):
        self.tuning = UkfTuning(*self.tuning).validate()
        self._Q = np.diag(np.asarray(self.tuning.Q, dtype=float))
        if self.bias_states is not None:
            self.bias_states = BiasStates(*self.bias_states).validate()
            self._Q = np.diag(np.concatenate([self.tuning.Q,
                                              self.bias_states.q_diag(self.model.h)]))
        self._R = np.diag(np.asarray(self.tuning.R, dtype=float))
        if not (math.isfinite(self.nis_gate) and self.nis_gate >= 0.0):
            raise ValueError(f'nis_gate must be >= 0 (0 = off), got {self.nis_gate!r}')
        if not (self.y_range[0] < self.y_range[1]):
            raise ValueError(f'y_range must be (min, max) with min < max, got {self.y_range!r}')
        refused = [f.name for f in fields(Effects) if f.name not in ESTIMATOR_FIELDS
                   and getattr(self.extensions, f.name) != getattr(NO_EXTENSIONS, f.name)]
        if refused:
            raise ValueError(f'extensions: {", ".join(refused)} not allowed in an estimator '
                             f'(allowed: {", ".join(ESTIMATOR_FIELDS)})')
        e = self.extensions
        self._record = self.model.params_array.copy()    # P_tank of a step written here
        self._kernel_model = self.model.kernel_model()
        self._effects_model = self.model.kernel_model(self._record)
        lag = ValveLag(self.model.valve_map, self.model.h, e.valve_time_constant, (0.0, 0.0))
        memory = self._new_memory()
        self._effects = EstimatorEffects(
            valve_decay=lag.decay, valve_mean_weight=lag.mean_weight,
            sensor_offset=np.array(e.sensor_offset, dtype=float),
            sensor_gain=1.0 + np.array(e.sensor_gain_error, dtype=float),
            dead_volume=float(e.dead_volume),
            slip=memory.slip if memory else np.zeros(0),
            stiffness=memory.stiffness if memory else np.zeros(0),
            p_out=float(self.model.params.P_out),
            bouc_wen_band=float(e.bouc_wen_band),
            bouc_wen_by_length=e.bouc_wen_driver == 'length',
            bouc_wen_travel=float(e.bouc_wen_length_travel if e.bouc_wen_driver == 'length'
                                  else e.bouc_wen_pressure_travel))
        self._extended = e.active or self.bias_states is not None
        self.reset()

    def reset(self, x0=None, P0=None) -> None:
        """Restart from x0 (4,) and P0 ((4,) diagonal or (4, 4)); defaults: the configured ones.
        With bias states, x0 (7,) and P0 ((7,) or (7, 7)) too; from 4 the biases start at 0 with
        their configured variances, uncorrelated."""
        x = np.array(self.x0 if x0 is None else x0, dtype=float)
        P = np.asarray(self.tuning.P0 if P0 is None else P0, dtype=float)
        P = np.diag(P) if P.ndim == 1 else P.copy()
        n = N_STATE
        if self.bias_states is not None:
            n = N_BIASED
            if x.shape == (4,):
                x = np.concatenate([x, np.zeros(3)])
            if P.shape == (4, 4):
                P4, P = P, np.diag(np.concatenate([np.zeros(4), self.bias_states.p0_diag()]))
                P[:4, :4] = P4
        if x.shape != (n,) or not np.all(np.isfinite(x)):
            raise ValueError(f'initial state must be {n} finite numbers, got {x!r}')
        if P.shape != (n, n) or not np.all(np.isfinite(P)) or np.any(np.diag(P) <= 0.0):
            raise ValueError(f'initial covariance must be finite, {n}x{n} (or a {n}-diagonal), '
                             'with a positive diagonal')
        self.x, self.P = x, 0.5 * (P + P.T)
        self._info = np.zeros(len(INFO_FIELDS))
        self.lock_angle = float(x[0])
        self._settings = FilterSettings(self._Q, self._R, self.lock_angle, float(self.nis_gate),
                                        float(self.y_range[0]), float(self.y_range[1]))
        self.steps = 0
        self.rejected_samples = 0     # invalid measurements (non-finite, out of range)
        self.gated_samples = 0        # innovations rejected by the NIS gate
        self.repairs = 0              # covariance repairs (Cholesky fallback)
        self._valve = np.zeros(3)     # [started, u_f1, u_f2]: started by the first command
        self.F_h = np.zeros(2)        # N, Maxwell-slip forces held over the next step
        memory = self._new_memory()
        self._anchor = np.zeros((2, 1))   # no hysteresis: the kernel never reads it
        if memory is not None:            # the memory starts relaxed (F_h = 0) at x0's forces
            memory.update(self.model.outputs_at(x[:4])[:2], x[2:4])
            self._anchor = memory.anchor
        self._bouc_wen = np.zeros((3, 2))   # [z, driver before, force]: z = 0 (no force) at x0
        effects = self._effects
        if effects.bouc_wen_band != 0.0:
            bouc_wen_drive(x, self._kernel_model.p_array[0], effects.bouc_wen_by_length,
                           effects.bouc_wen_travel, self._bouc_wen[1])

    def _new_memory(self) -> MaxwellSlip | None:
        """The extensions' Maxwell-slip hysteresis memory, None without hysteresis."""
        e = self.extensions
        if e.hysteresis_band <= 0.0:
            return None
        return MaxwellSlip(e.hysteresis_band, e.hysteresis_elements, e.hysteresis_travel,
                           self.model.params.P_out)

    def step(self, y, u_prev, supply=None) -> UkfOutput:
        """Predict with u_prev (V, the command held since the last sample), update with y (Pa).

        supply: the measured supply pressure (Pa abs), P_tank of this step when finite and > 0;
        None (or not finite): the model's P_tank."""
        y = np.asarray(y, dtype=float)
        u_prev = np.asarray(u_prev, dtype=float)
        if y.shape != (2,) or u_prev.shape != (2,):
            raise ValueError('y needs 2 pressures (Pa) and u_prev 2 voltages (V)')
        m, info = self.model, self._info
        if self._extended or supply is not None:
            self._step_with_effects(y, u_prev, supply)
        else:
            ukf_step(self.x, self.P, u_prev, y, self._kernel_model, self._settings, info)
        nis, valid, accepted, repairs, F1, F2, tau, tau_var, sigma, finite = info.tolist()
        if not finite:
            # cannot happen with the model's guards; never hand out NaN if it ever does:
            # keep the state, restart its covariance, and report the update as skipped
            self.repairs += 1
            self.P = np.diag(np.asarray(self.tuning.P0, dtype=float))
            if self.bias_states is not None:
                self.P = np.diag(np.concatenate([self.tuning.P0, self.bias_states.p0_diag()]))
            F1, F2, tau = m.outputs_at(self.x[:4])
            if self._effects.slip.size or self._effects.bouc_wen_band:
                F1 = F1 + self.F_h[0] + self._bouc_wen[2, 0]
                F2 = F2 + self.F_h[1] + self._bouc_wen[2, 1]
                tau = m.params.r * math.cos(self.x[0]) * (F1 - F2)
            if self.bias_states is not None:
                tau += float(self.x[6])
            tau_var, accepted = 0.0, False
        self.steps += 1
        self.repairs += int(repairs)
        if not valid:
            self.rejected_samples += 1
        elif not accepted:
            self.gated_samples += 1
        return UkfOutput(x=self.x.copy(), P=self.P.copy(), force1=F1, force2=F2, torque=tau,
                         torque_variance=tau_var, subsystem=int(sigma), nis=nis,
                         update_skipped=not accepted)

    def coast(self, u_prev, supply=None) -> None:
        """One model step h without a measurement, for a sample that never came (the rig missed
        it, or it was lost on the way): the prediction with u_prev (V) only; not counted as a
        rejected sample."""
        rejected = self.rejected_samples
        self.step(_NO_MEASUREMENT, u_prev, supply)
        self.rejected_samples = rejected

    def _step_with_effects(self, y, u_prev, supply) -> None:
        """ukf_step_with_effects with P_tank of this step: the measured supply when finite and
        > 0, else the model's; fills self._info."""
        P_tank = self.model.params.P_tank
        if supply is not None and math.isfinite(supply) and supply > 0.0:
            P_tank = float(supply)
        if self._record[0]['P_tank'] != P_tank:
            self._record['P_tank'] = P_tank
        ukf_step_with_effects(self.x, self.P, u_prev, y, self._effects_model, self._settings,
                              self._effects, self._valve, self._anchor, self._bouc_wen, self.F_h,
                              self._info)
