"""Friction coefficients mu_s (shaft) and mu_p (tubes) from free runs (output error, eq. (10)).

The joint of each free run is simulated from its first measured angle and velocity, driven by
its measured pressures (low-pass filtered at PRESSURE_FILTER_HZ, zero phase), with the force model
already identified and Kikuuwe's friction of the proposed law; the residual is simulated minus
measured angle. The filter matters: sensor noise left in the pressures dithers the model joint
out of sticking (noise-induced creep), which the fit would pay back with more friction. On the
'strong' plant with 2 kPa noise (60 s free run, true forces) a 25 Hz cut-off overestimated mu_s
by 1.6 % and mu_p by 22 %, 10 Hz by 0.1 % and 9 %, 5 Hz: -0.6 % and +1 % (without noise any
cut-off gives < 0.3 % and < 5 %); the muscles' pressures change over >= 0.1 s, so 5 Hz keeps
them. Slow antagonistic ramps make the joint lag its frictionless equilibrium by T_c /
stiffness, and co-contraction levels with different pressures weigh T_sh (mu_s, grows with
F1 + F2) and T_p (mu_p, grows as a pressure nears P_out) differently.
A coarse grid of the coefficients gives the start of the least-squares refinement (the cost is
not smooth where the joint sticks).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numba import njit
from scipy.optimize import least_squares
from scipy.signal import butter, sosfiltfilt

from ..model_choices import ForceModel, FrictionLaw
from ..physics import friction_from_forces, joint_torque, muscle_forces
from .fit_result import Estimate, GroupFit, NotIdentifiable, check_identified, standard_errors
from .hysteresis_fit import slip_step

MIN_TRAVEL = math.radians(5.0)          # rad, a free run must move this much
PRESSURE_FILTER_HZ = 5.0                # Hz, low-pass of the measured pressures (zero phase)
GRID = np.linspace(-1.2, 1.2, 9)        # log factors of the coarse start grid
PARAMETERS = ('mu_s', 'mu_p')
UNITS = ('-', 'N m Pa^2')
FRICTION = int(FrictionLaw.PROPOSED)    # the law whose mu_s, mu_p are fitted (kernel code)
FORCE = int(ForceModel.PROPOSED)        # the force model of the identified coefficients


@njit(cache=True)
def joint_acceleration(psi, P1, P2, T_f, p, F_h1=0.0, F_h2=0.0):
    """psi_ddot (rad/s^2) of eq. (9) at angle psi (rad), pressures P1, P2 (Pa), friction T_f
    (N m), hysteresis forces F_h1, F_h2 (N) added to eq. (6)."""
    F1, F2 = muscle_forces(psi, P1, P2, p, FORCE)
    return (joint_torque(psi, F1 + F_h1, F2 + F_h2, p) - T_f - p.k_s * psi) / p.J


@njit(cache=True)
def joint_trajectory_with_hysteresis(psi0, psi_dot0, P1, P2, dt, p, band, elements, travel, out):
    """out[k] (rad): the joint angle from (psi0 rad, psi_dot0 rad/s) driven by pressures P1, P2
    (N,) Pa held over each step dt (N-1,) s; friction (proposed law) once per step, RK4. With
    band B > 0 (N at 500 kPa) each muscle's force carries the Maxwell slip of pam_model.effects
    (elements n, travel Delta N), driven by its nominal force at each sample and held over the
    step, in the torque and in the friction's F1 + F2 (as the plant of effects_physics)."""
    psi, w = psi0, psi_dot0
    out[0] = psi
    hysteresis = band > 0.0
    anchors = np.empty((2, elements))
    for k in range(dt.shape[0]):
        h = dt[k]
        F1, F2 = muscle_forces(psi, P1[k], P2[k], p, FORCE)
        if hysteresis:
            if k == 0:
                anchors[0, :] = F1
                anchors[1, :] = F2
            F_h1 = band * slip_step(anchors[0], F1, P1[k], travel, p.P_out)
            F_h2 = band * slip_step(anchors[1], F2, P2[k], travel, p.P_out)
        else:
            F_h1, F_h2 = 0.0, 0.0
        T_f, _ = friction_from_forces(psi, w, P1[k], P2[k], F1 + F_h1, F2 + F_h2, h, p,
                                      FRICTION)
        a1 = joint_acceleration(psi, P1[k], P2[k], T_f, p, F_h1, F_h2)
        a2 = joint_acceleration(psi + 0.5 * h * w, P1[k], P2[k], T_f, p, F_h1, F_h2)
        w2 = w + 0.5 * h * a1
        a3 = joint_acceleration(psi + 0.5 * h * w2, P1[k], P2[k], T_f, p, F_h1, F_h2)
        w3 = w + 0.5 * h * a2
        w4 = w + h * a3
        a4 = joint_acceleration(psi + h * w3, P1[k], P2[k], T_f, p, F_h1, F_h2)
        psi = psi + h / 6.0 * (w + 2.0 * w2 + 2.0 * w3 + w4)
        w = w + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        out[k + 1] = psi
    return out


@njit(cache=True)
def joint_trajectory(psi0, psi_dot0, P1, P2, dt, p, out):
    """joint_trajectory_with_hysteresis without hysteresis (the paper's eq. (6)-(10))."""
    return joint_trajectory_with_hysteresis(psi0, psi_dot0, P1, P2, dt, p, 0.0, 1, 1.0, out)


def filtered_pressures(rec) -> np.ndarray:
    """(N, 2) Pa: the measured pressures low-passed at PRESSURE_FILTER_HZ, zero phase."""
    fs = 1.0 / float(np.median(rec.dt))
    sos = butter(2, min(PRESSURE_FILTER_HZ, 0.4 * fs), fs=fs, output='sos')
    return sosfiltfilt(sos, rec.P, axis=0)


def fit_friction(records, params, hysteresis=(0.0, 1, 1.0)) -> tuple[GroupFit, dict, list]:
    """mu_s, mu_p from the free runs, with `params` holding the identified forces.

    Returns the fit, the Parameters changes and what was not identified: when the runs pin mu_s
    but not mu_p (a small part of T_c inside the envelope), mu_s is fitted again with mu_p held
    at its prior value and mu_p is reported as not identified. hysteresis: (B N at 500 kPa,
    elements n, travel Delta N) of the identified force hysteresis in the model joint (B = 0:
    none), so that the friction does not absorb the loop.
    """
    used = [r for r in records if not r.locked and r.travel >= MIN_TRAVEL]
    if not used:
        raise NotIdentifiable(
            f'mu_s and mu_p need a free-joint run with an encoder in which the joint moves '
            f'(>= {math.degrees(MIN_TRAVEL):.0f} deg of travel)', PARAMETERS)
    band, elements, travel = float(hysteresis[0]), int(hysteresis[1]), float(hysteresis[2])
    inputs = [(r, filtered_pressures(r)) for r in used]
    measured = np.concatenate([r.psi for r in used])
    prior = np.array([params.mu_s, params.mu_p])

    def solve(fitted: list):
        """Fit the coefficients with indices `fitted` (0 mu_s, 1 mu_p), the others at prior."""
        def residual(z):
            log_factors = np.zeros(2)
            log_factors[fitted] = z
            mu_s, mu_p = prior * np.exp(log_factors)
            p = params.replace(mu_s=float(mu_s), mu_p=float(mu_p)).as_record_array()[0]
            parts = []
            for rec, P in inputs:
                out = np.empty(len(rec.t))
                joint_trajectory_with_hysteresis(float(rec.psi[0]), float(rec.psi_dot[0]),
                                                 P[:, 0], P[:, 1], rec.dt, p, band, elements,
                                                 travel, out)
                parts.append(out)
            return np.degrees(np.concatenate(parts) - measured)

        starts = [np.array(z) for z in itertools.product(GRID, repeat=len(fitted))]
        start = min(starts, key=lambda z: float(np.sum(residual(z) ** 2)))
        sol = least_squares(residual, start, method='trf', diff_step=1e-2, x_scale=0.1)
        values = prior[fitted] * np.exp(sol.x)
        std = values * standard_errors(sol.jac, sol.fun, correlated=True)
        estimates = tuple(Estimate(PARAMETERS[i], float(v), float(s), float(prior[i]), UNITS[i])
                          for i, v, s in zip(fitted, values, std, strict=True))
        return sol, estimates

    sol, estimates = solve([0, 1])
    skipped = []
    try:
        check_identified(estimates, 'friction')
    except NotIdentifiable as gap:
        if gap.parameters != ('mu_p',):
            raise
        skipped.append(gap)
        sol, estimates = solve([0])
        check_identified(estimates, 'friction')
    notes = (f'{len(used)} free runs, pressures low-passed at {PRESSURE_FILTER_HZ:g} Hz'
             + (f'; with the identified force hysteresis (B {band:.3g} N, Delta {travel:.3g} N)'
                if band > 0.0 else ''),)
    return (GroupFit('friction', estimates, float(np.sqrt(np.mean(sol.fun ** 2))), 'deg',
                     len(measured), notes), {e.name: e.value for e in estimates}, skipped)
