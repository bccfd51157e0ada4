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
A coarse grid of the coefficients gives the starts of the least-squares refinement, from the
STARTS best grid points (the cost is not smooth where the joint sticks).

With a Bouc-Wen loop (pam_model.effects.BoucWen; driver 'length' or 'pressure') the model joint
carries its force F_bw,i = B_w c(P_i) z_i in both muscles, and B_w (N at 500 kPa, signed: the
fit finds the orientation) and its travel (m or Pa per e-fold of z, fitted in log) are fitted
with the friction coefficients. A loop driven by the length does not move in a locked run, so
the free runs are where it shows; it resembles friction (it opposes the motion when B_w > 0 and
grows with the pressure), which is why loop_fit chooses between the forms on a part of the free
runs that the fit did not see.
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.optimize import least_squares
from scipy.signal import butter, sosfiltfilt

from ..effects import HYSTERESIS_PRESSURE
from ..effects_physics import bouc_wen_update
from ..model_choices import ForceModel, FrictionLaw
from ..physics import friction_from_forces, joint_torque, muscle_forces, muscle_lengths
from .fit_result import Estimate, GroupFit, NotIdentifiable, check_identified, standard_errors
from .hysteresis_fit import slip_step

MIN_TRAVEL = math.radians(5.0)          # rad, a free run must move this much
PRESSURE_FILTER_HZ = 5.0                # Hz, low-pass of the measured pressures (zero phase)
GRID = np.linspace(-1.2, 1.2, 9)        # log factors of the coarse start grid
PARAMETERS = ('mu_s', 'mu_p')
UNITS = ('-', 'N m Pa^2')
FRICTION = int(FrictionLaw.PROPOSED)    # the law whose mu_s, mu_p are fitted (kernel code)
FORCE = int(ForceModel.PROPOSED)        # the force model of the identified coefficients
LOOP_DRIVERS = ('length', 'pressure')   # what may drive a Bouc-Wen loop (effects.BOUC_WEN_DRIVERS)
#: start grids of a loop's fit: B_w (N at 500 kPa) and the travel per driver (m, Pa)
LOOP_BANDS = (-4.0, -2.0, -1.0, 1.0, 2.0, 4.0)
LOOP_TRAVELS = {'length': (3e-4, 1e-3, 3e-3), 'pressure': (5e3, 2e4, 8e4)}
LOOP_UNITS = {'length': 'm', 'pressure': 'Pa'}
#: least-squares refinements from the best grid points (with and without a loop alike, so that
#: the forms compare on equal effort)
STARTS = 3


class Loop(NamedTuple):
    """A Bouc-Wen loop of the model joint: band B_w (N at 500 kPa, signed; 0: none), its driver
    ('length' or 'pressure') and travel (m or Pa per e-fold of z)."""

    band: float = 0.0
    driver: str = 'length'
    travel: float = 1e-3

    def effects(self) -> dict:
        """The Effects fields of this loop (empty without one)."""
        if self.band == 0.0:
            return {}
        return {'bouc_wen_band': self.band, 'bouc_wen_driver': self.driver,
                f'bouc_wen_{self.driver}_travel': self.travel}


NO_LOOP = Loop()


@njit(cache=True)
def joint_acceleration(psi, P1, P2, T_f, p, F_h1=0.0, F_h2=0.0):
    """psi_ddot (rad/s^2) of eq. (9) at angle psi (rad), pressures P1, P2 (Pa), friction T_f
    (N m), hysteresis forces F_h1, F_h2 (N) added to eq. (6)."""
    F1, F2 = muscle_forces(psi, P1, P2, p, FORCE)
    return (joint_torque(psi, F1 + F_h1, F2 + F_h2, p) - T_f - p.k_s * psi) / p.J


@njit(cache=True)
def joint_trajectory_with_hysteresis(psi0, psi_dot0, P1, P2, dt, p, band, elements, travel,
                                     loop_band, loop_by_length, loop_travel, out):
    """out[k] (rad): the joint angle from (psi0 rad, psi_dot0 rad/s) driven by pressures P1, P2
    (N,) Pa held over each step dt (N-1,) s; friction (proposed law) once per step, RK4. With
    band B > 0 (N at 500 kPa) each muscle's force carries the Maxwell slip of pam_model.effects
    (elements n, travel Delta N), driven by its nominal force at each sample; with loop_band
    B_w != 0 (N at 500 kPa) the Bouc-Wen loop of pam_model.effects, driven by the muscle's
    length (loop_by_length) or pressure over loop_travel (m or Pa), starting at z = 0; both held
    over the step, in the torque and in the friction's F1 + F2 (as the plant of
    effects_physics)."""
    psi, w = psi0, psi_dot0
    out[0] = psi
    hysteresis = band > 0.0
    anchors = np.empty((2, elements))
    drive, drive_before = np.empty(2), np.empty(2)
    z, F_bw, P = np.zeros(2), np.zeros(2), np.empty(2)
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
        if loop_band != 0.0:
            P[0], P[1] = P1[k], P2[k]
            if loop_by_length:
                l1, l2 = muscle_lengths(psi, p)
                drive[0], drive[1] = l1 / loop_travel, l2 / loop_travel
            else:
                drive[0], drive[1] = P1[k] / loop_travel, P2[k] / loop_travel
            if k == 0:
                drive_before[:] = drive
            bouc_wen_update(drive, drive_before, z, loop_band, P, p.P_out, HYSTERESIS_PRESSURE,
                            F_bw)
            F_h1 += F_bw[0]
            F_h2 += F_bw[1]
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
    return joint_trajectory_with_hysteresis(psi0, psi_dot0, P1, P2, dt, p, 0.0, 1, 1.0, 0.0,
                                            True, 1.0, out)


def filtered_pressures(rec) -> np.ndarray:
    """(N, 2) Pa: the measured pressures low-passed at PRESSURE_FILTER_HZ, zero phase."""
    fs = 1.0 / float(np.median(rec.dt))
    sos = butter(2, min(PRESSURE_FILTER_HZ, 0.4 * fs), fs=fs, output='sos')
    return sosfiltfilt(sos, rec.P, axis=0)


def free_runs(records) -> list:
    """The free runs with an encoder in which the joint moves (NotIdentifiable without one)."""
    used = [r for r in records if not r.locked and r.travel >= MIN_TRAVEL]
    if not used:
        raise NotIdentifiable(
            f'mu_s and mu_p need a free-joint run with an encoder in which the joint moves '
            f'(>= {math.degrees(MIN_TRAVEL):.0f} deg of travel)', PARAMETERS)
    return used


def simulated_angles(inputs, params, hysteresis, loop: Loop) -> np.ndarray:
    """rad: the model joint's angle over each (record, filtered pressures) of inputs,
    concatenated, with `params` (its friction coefficients), the Maxwell slip `hysteresis`
    (B, n, Delta) and the Bouc-Wen `loop`."""
    band, elements, travel = float(hysteresis[0]), int(hysteresis[1]), float(hysteresis[2])
    p = params.as_record_array()[0]
    parts = []
    for rec, P in inputs:
        out = np.empty(len(rec.t))
        joint_trajectory_with_hysteresis(float(rec.psi[0]), float(rec.psi_dot[0]), P[:, 0],
                                         P[:, 1], rec.dt, p, band, elements, travel,
                                         float(loop.band), loop.driver == 'length',
                                         float(loop.travel), out)
        parts.append(out)
    return np.concatenate(parts)


def fit_friction(records, params, hysteresis=(0.0, 1, 1.0), driver: str | None = None,
                 strict: bool = True, fixed: Loop = NO_LOOP) -> tuple[GroupFit, dict, list, Loop]:
    """mu_s, mu_p from the free runs, with `params` holding the identified forces; with `driver`
    ('length' or 'pressure') also a Bouc-Wen loop so driven (its band B_w, signed, and travel).

    Returns the fit, the Parameters changes, what was not identified and the fitted Loop
    (NO_LOOP without a driver): when the runs pin mu_s but not mu_p (a small part of T_c inside
    the envelope), mu_s is fitted again with mu_p held at its prior value and mu_p is reported
    as not identified. hysteresis: (B N at 500 kPa, elements n, travel Delta N) of the
    identified force hysteresis in the model joint (B = 0: none), so that the friction does not
    absorb the loop. strict=False: no identifiability checks (both coefficients fitted; for a
    fit judged on runs it did not see, loop_fit). fixed: a Bouc-Wen loop already identified (the
    locked runs'), in the model joint without a driver; returned as the Loop then.
    """
    used = free_runs(records)
    inputs = [(r, filtered_pressures(r)) for r in used]
    measured = np.concatenate([r.psi for r in used])
    prior = np.array([params.mu_s, params.mu_p])

    def unpack(z, fitted):
        """(friction Parameters, Loop) of the fitted vector z: the log factors of the
        coefficients `fitted`, then B_w and the log travel with a driver."""
        log_factors = np.zeros(2)
        log_factors[fitted] = z[:len(fitted)]
        mu_s, mu_p = prior * np.exp(log_factors)
        if driver is None or len(z) == len(fitted):     # the start grid of the coefficients
            return params.replace(mu_s=float(mu_s), mu_p=float(mu_p)), fixed
        loop = Loop(float(z[len(fitted)]), driver, float(np.exp(z[len(fitted) + 1])))
        return params.replace(mu_s=float(mu_s), mu_p=float(mu_p)), loop

    def residual(z, fitted):
        friction, loop = unpack(z, fitted)
        return np.degrees(simulated_angles(inputs, friction, hysteresis, loop) - measured)

    def cost(z, fitted):
        return float(np.sum(residual(z, fitted) ** 2))

    def solve(fitted: list):
        """Fit the coefficients with indices `fitted` (0 mu_s, 1 mu_p), the others at prior."""
        starts = [np.array(z) for z in itertools.product(GRID, repeat=len(fitted))]
        starts = sorted(starts, key=lambda z: cost(z, fitted))[:STARTS]
        start = starts[0]
        scale = [0.1] * len(fitted)
        if driver is not None:
            # a loop trades against mu_s (both grow with the pressure and oppose or help the
            # motion): mu_s is searched again with each loop start
            loops = []
            for factor, band, travel in itertools.product(GRID, LOOP_BANDS,
                                                          LOOP_TRAVELS[driver]):
                z = np.concatenate([start, [band, math.log(travel)]])
                z[0] = factor
                loops.append(z)
            starts = sorted(loops, key=lambda z: cost(z, fitted))[:STARTS]
            scale += [1.0, 0.3]
        sol = min((least_squares(residual, z, method='trf', diff_step=1e-2, x_scale=scale,
                                 args=(fitted,)) for z in starts), key=lambda sol: sol.cost)
        rel = standard_errors(sol.jac, sol.fun, correlated=True)
        values = prior[fitted] * np.exp(sol.x[:len(fitted)])
        estimates = tuple(Estimate(PARAMETERS[i], float(v), float(v * s), float(prior[i]),
                                   UNITS[i])
                          for i, v, s in zip(fitted, values, rel[:len(fitted)], strict=True))
        if driver is not None:
            _, loop = unpack(sol.x, fitted)
            estimates += (Estimate('bouc_wen_band', loop.band, float(rel[len(fitted)]), 0.0,
                                   'N'),
                          Estimate(f'bouc_wen_{driver}_travel', loop.travel,
                                   float(loop.travel * rel[len(fitted) + 1]), float('nan'),
                                   LOOP_UNITS[driver]))
        return sol, estimates

    sol, estimates = solve([0, 1])
    skipped = []
    if strict:
        try:
            check_identified(estimates[:2], 'friction')
        except NotIdentifiable as gap:
            if gap.parameters != ('mu_p',):
                raise
            skipped.append(gap)
            sol, estimates = solve([0])
            check_identified(estimates[:1], 'friction')
    fitted = [0] if skipped else [0, 1]
    _, loop = unpack(sol.x, fitted)
    friction = tuple(e for e in estimates if e.name in PARAMETERS)
    notes = (f'{len(used)} free runs, pressures low-passed at {PRESSURE_FILTER_HZ:g} Hz'
             + (f'; with the identified force hysteresis (B {hysteresis[0]:.3g} N, Delta '
                f'{hysteresis[2]:.3g} N)' if hysteresis[0] > 0.0 else '')
             + (f'; with a Bouc-Wen loop driven by the {loop.driver} (B_w {loop.band:+.3g} N, '
                f'travel {loop.travel:.3g} {LOOP_UNITS[loop.driver]})' if loop.band else '')
             + ('' if driver is not None or not loop.band else ', identified before, fixed'),)
    return (GroupFit('friction', estimates, float(np.sqrt(np.mean(sol.fun ** 2))), 'deg',
                     len(measured), notes), {e.name: e.value for e in friction}, skipped, loop)
