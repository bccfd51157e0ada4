"""The sensor-less closed loop on the batch simulator: plant + sensor -> UKF -> PI -> plant, one
compiled loop, many gain candidates at once. Used to tune the gains and to check them fast.

Per sample k: the sensor reads the plant's pressures; the UKF steps with u(k-1) and that reading;
the PI acts on reference(k) - estimate(k) (angle, or torque for a locked joint) and gives u(k);
the plant steps with u(k). This is the order of the ROS loop in lockstep. The UKF + PI half of
that (control_step) is shared by the compiled loop (the paper's plant) and by
simulate_closed_loop_with_effects, which steps a plant with unmodelled effects
(pam_model.effects.EffectsPlant) sample by sample in Python: about 60 us per sample against
about 12 us in the compiled loop (a 64 s run: about 4 s against 0.8 s).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from pam_estimator.pam_ukf import (
    DEFAULT_TUNING,
    INFO_FIELDS,
    INFO_TORQUE,
    FilterSettings,
    PamUkf,
    UkfTuning,
    ukf_step,
)
from pam_estimator.valid_readings import NIS_GATE_OFF, PRESSURE_MAX, PRESSURE_MIN
from pam_model.effects import Effects, EffectsPlant
from pam_model.model import KernelModel, PamModel
from pam_model.model_extensions import NO_EXTENSIONS
from pam_model.physics import joint_torque, muscle_forces, step_array
from pam_model.rest import REST_STATE
from pam_model.sensor import PressureSensor, adc_reading

from .pi import ANTI_WINDUP, PiGains, pi_step
from .step_metrics import StepReport, step_report


class PiSettings(NamedTuple):
    """The PI's settings as the kernels take them, in one record: gains kp (V per rad or N m),
    ki (V per rad s or N m s), the bias beta (V), the limits u_min, u_max (V), the anti-windup
    scheme's index in pi.ANTI_WINDUP and the back-calculation's tracking_time (s)."""

    kp: float
    ki: float
    beta: float
    u_min: float
    u_max: float
    anti_windup: int
    tracking_time: float


@njit(cache=True)
def control_step(x_hat, P, u, y, model, settings, pi, info, torque_mode, reference, i_term):
    """The controller's half of one sample: the UKF steps (in place) with u(k-1) = u and the
    reading y (Pa), the PI acts on reference - estimate (angle rad, or torque N m in torque_mode)
    and writes u(k) (V) into u. model: the estimator's KernelModel; settings: its
    FilterSettings; pi: a PiSettings. Returns (feedback, the PI's new integral term)."""
    ukf_step(x_hat, P, u, y, model, settings, info)
    feedback = info[INFO_TORQUE] if torque_mode else x_hat[0]
    h = model.h
    u[0], u[1], _, i_term, _ = pi_step(reference - feedback, h, i_term, pi.kp, pi.ki, pi.beta,
                                       pi.u_min, pi.u_max, pi.anti_windup, pi.tracking_time,
                                       2.0 * h)
    return feedback, i_term


@njit(cache=True)
def closed_loop_kernel(x0, reference, torque_mode, noise, h, plant_array, est_array, kappa_u,
                       kappa_alpha, friction_law, force_model, locked, Q, R, P0, gains,
                       beta, u_min, u_max, anti_windup, tracking_time, resolution, range_min,
                       range_max):
    """Runs every gain candidate (rows of gains: kp, ki) over the reference (N,).

    noise (N, 2): sensor noise samples (Pa). Returns true feedback (C, N) (rad or N m),
    estimated feedback (C, N) and commands (C, N, 2) (V).
    """
    n = reference.shape[0]
    c_count = gains.shape[0]
    truth = np.empty((c_count, n))
    estimate = np.empty((c_count, n))
    commands = np.empty((c_count, n, 2))
    info = np.zeros(len(INFO_FIELDS))
    plant_p = plant_array[0]
    model = KernelModel(h, est_array, kappa_u, kappa_alpha, friction_law, force_model, locked)
    settings = FilterSettings(Q, R, x0[0], NIS_GATE_OFF, PRESSURE_MIN, PRESSURE_MAX)
    for c in range(c_count):
        pi = PiSettings(gains[c, 0], gains[c, 1], beta, u_min, u_max, anti_windup, tracking_time)
        x_true = x0.copy()
        x_hat = x0.copy()
        P = P0.copy()
        u = np.array([beta, beta])
        y = np.empty(2)
        x_next = np.empty(4)
        i_term = 0.0
        for k in range(n):
            for j in range(2):
                y[j] = adc_reading(x_true[2 + j] + noise[k, j], resolution, range_min, range_max)
            if torque_mode:
                F1, F2 = muscle_forces(x_true[0], x_true[2], x_true[3], plant_p, force_model)
                truth[c, k] = joint_torque(x_true[0], F1, F2, plant_p)
            else:
                truth[c, k] = x_true[0]
            estimate[c, k], i_term = control_step(x_hat, P, u, y, model, settings, pi, info,
                                                  torque_mode, reference[k], i_term)
            commands[c, k, 0] = u[0]
            commands[c, k, 1] = u[1]
            step_array(x_true, u[0], u[1], h, plant_array, kappa_u, kappa_alpha, friction_law,
                       force_model, locked, x_next)
            x_true[:] = x_next
    return truth, estimate, commands


class ClosedLoopRun(NamedTuple):
    """One candidate's run: time (s), reference, true and estimated feedback, commands (V)."""

    t: np.ndarray
    reference: np.ndarray
    truth: np.ndarray
    estimate: np.ndarray
    commands: np.ndarray
    gains: tuple

    def report(self, span: float, hold: float) -> StepReport:
        return step_report(self.t, self.reference, self.truth, span, hold)


def simulate_closed_loop(plant: PamModel, estimator_model: PamModel, reference, gain_candidates,
                         sensor: PressureSensor = PressureSensor(), tuning: UkfTuning =
                         DEFAULT_TUNING, mode: str = 'angle', anti_windup: str = 'conditional',
                         tracking_time: float = 0.1, limits: PiGains = PiGains(0.0, 0.0),
                         x0=REST_STATE, seed: int = 0) -> list[ClosedLoopRun]:
    """Closed-loop runs of every (kp, ki) in gain_candidates over reference (N,) (rad or N m).

    The plant and the estimator's model must agree on h, friction law, force model and joint
    mode (the estimator keeps its own parameters); mode 'torque' needs a locked joint.
    """
    reference, noise = _checked_inputs(plant, mode, reference, sensor, seed)
    gains = np.ascontiguousarray(np.atleast_2d(gain_candidates), dtype=float)
    truth, estimate, commands = closed_loop_kernel(
        np.asarray(x0, dtype=float), reference, mode == 'torque', noise, plant.h,
        plant.params_array, estimator_model.params_array, plant.valve_map.u,
        plant.valve_map.alpha, plant.friction_code, plant.force_code, plant.locked,
        np.diag(tuning.Q), np.diag(tuning.R), np.diag(tuning.P0), gains, limits.beta,
        limits.u_min, limits.u_max, ANTI_WINDUP.index(anti_windup), tracking_time,
        sensor.resolution, sensor.range_min, sensor.range_max)
    t = np.arange(len(reference)) * plant.h
    return [ClosedLoopRun(t, reference, truth[c], estimate[c], commands[c], tuple(gains[c]))
            for c in range(len(gains))]


def _checked_inputs(plant: PamModel, mode: str, reference, sensor: PressureSensor, seed: int):
    """(reference (N,), sensor noise (N, 2) Pa) of a closed-loop run; ValueError on a bad mode."""
    if mode not in ('angle', 'torque'):
        raise ValueError(f"mode must be 'angle' or 'torque', got {mode!r}")
    if (mode == 'torque') != plant.locked:
        raise ValueError('torque mode runs on a locked joint, angle mode on a free one')
    reference = np.ascontiguousarray(reference, dtype=float)
    noise = sensor.noise_std * np.random.default_rng(seed).standard_normal((len(reference), 2))
    return reference, noise


def simulate_closed_loop_with_effects(plant: PamModel, effects: Effects, estimator_model:
                                      PamModel, reference, gains, sensor: PressureSensor =
                                      PressureSensor(), tuning: UkfTuning = DEFAULT_TUNING,
                                      mode: str = 'angle', anti_windup: str = 'conditional',
                                      tracking_time: float = 0.1,
                                      limits: PiGains = PiGains(0.0, 0.0),
                                      x0=REST_STATE, seed: int = 0,
                                      extensions: Effects = NO_EXTENSIONS) -> ClosedLoopRun:
    """One closed-loop run of the gains (kp, ki) on a plant with unmodelled effects (any, or
    none): simulate_closed_loop's loop, the same sensor noise draws and the same control_step,
    with the plant stepped by pam_model.effects.EffectsPlant one sample at a time (the sensor
    reads its sensed pressures, the truth includes its hysteresis forces). With no effect on it
    gives simulate_closed_loop's run sample for sample. extensions: the estimator model's
    (pam_model.model_extensions); when any is on, the estimate comes from a PamUkf carrying them
    (its step one compiled call, ukf_step_with_effects) and the PI from the same pi_step."""
    reference, noise = _checked_inputs(plant, mode, reference, sensor, seed)
    kp, ki = (float(g) for g in gains)
    h = plant.h
    x = np.array(x0, dtype=float)
    x_hat = x.copy()
    P = np.diag(np.asarray(tuning.P0, dtype=float))
    Q, R = np.diag(np.asarray(tuning.Q, dtype=float)), np.diag(np.asarray(tuning.R, dtype=float))
    u = np.array([limits.beta, limits.beta])
    y = np.empty(2)
    info = np.zeros(len(INFO_FIELDS))
    est = estimator_model
    torque_mode = mode == 'torque'
    aw = ANTI_WINDUP.index(anti_windup)
    model = est.kernel_model()
    settings = FilterSettings(Q, R, float(x0[0]), NIS_GATE_OFF, PRESSURE_MIN, PRESSURE_MAX)
    pi = PiSettings(kp, ki, float(limits.beta), float(limits.u_min), float(limits.u_max), aw,
                    float(tracking_time))
    plant_steps = EffectsPlant(plant, effects, x, u)
    extended = PamUkf(model=est, tuning=tuning, x0=tuple(x), extensions=extensions) \
        if extensions.active else None
    n = len(reference)
    truth, estimate, commands = np.empty(n), np.empty(n), np.empty((n, 2))
    i_term = 0.0
    for k in range(n):
        sensed = plant_steps.sensed_pressures()
        for j in range(2):
            y[j] = adc_reading(sensed[j] + noise[k, j], sensor.resolution, sensor.range_min,
                               sensor.range_max)
        truth[k] = plant_steps.outputs(x)[2] if torque_mode else x[0]
        if extended is None:
            estimate[k], i_term = control_step(x_hat, P, u, y, model, settings, pi, info,
                                               torque_mode, reference[k], i_term)
        else:
            out = extended.step(y, u)
            estimate[k] = out.torque if torque_mode else out.x[0]
            u[0], u[1], _, i_term, _ = pi_step(reference[k] - estimate[k], h, i_term, kp, ki,
                                               limits.beta, limits.u_min, limits.u_max, aw,
                                               tracking_time, 2.0 * h)
        commands[k] = u
        x, _, _ = plant_steps.step(x, u, k * h)
    return ClosedLoopRun(np.arange(n) * h, reference, truth, estimate, commands, (kp, ki))
