"""Effective valve areas A1, A2 of each valve and the polytropic gain k2 from the pressure
transients (output error, eq. (4)-(5)).

Each muscle's pressure is simulated from its first measured value with the measured command
(alpha = kappa(u)) and the measured angle and velocity (its volume V and volume rate V_dot), RK4
with the geometry held over each sample; the residual is simulated minus measured pressure.
eq. (4) multiplies the mass flow by k1 and eq. (5) makes it proportional to A_0, so only the
products k1 A1 and k1 A2 are identifiable: k1 stays at its prior value and A1, A2 are the
effective areas for it. k2 needs a free run in which the joint moves (V_dot != 0).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.optimize import least_squares

from ..physics import (
    P_MAX,
    P_MIN,
    clip,
    gas_constants,
    mass_flow,
    muscle_volume,
    pressure_rate,
    volume_rate,
)
from .fit_result import Estimate, GroupFit, NotIdentifiable, check_identified, standard_errors

MIN_TRAVEL = math.radians(5.0)    # rad, a free run needs this much motion to inform k2
VOLUME_SCALE = 1.0e-5             # m^3, scale of the dead volume's unknown
SIGNIFICANCE = 3.0                # a dead volume is kept when it exceeds this many sigma
#: m^3, and this much (0.5 cm^3, a 4 cm line of 4 mm bore; 1.4 % of a muscle's volume at L0): the
#: statistical sigma misses the fit's model bias (on the 'mild' plant, with no dead volume, the
#: fit gave 0.07 cm^3 at 20 sigma)
MIN_DEAD_VOLUME = 0.5e-6
AREA_FIELDS = ('A1_1', 'A2_1', 'A1_2', 'A2_2')
AREA_NAMES = ('pam1.A1', 'pam1.A2', 'pam2.A1', 'pam2.A2')


@njit(cache=True)
def pressure_trajectory_with_volume(P0, alpha, l, l_dot, dt, p, A1, A2, V_d, out):
    """out[k] (Pa): one muscle's pressure from P0 (Pa) under openings alpha (N,), length l (N,) m
    and its rate l_dot (N,) m/s held over each step dt (N-1,) s; valve areas A1, A2 (m^2); a dead
    volume V_d (m^3) in series (eq. (4) with V + V_d, V_dot of the muscle alone)."""
    gas = gas_constants(p)
    P = P0
    out[0] = P
    for k in range(dt.shape[0]):
        V = muscle_volume(l[k], p) + V_d
        V_dot = volume_rate(l[k], l_dot[k], p)
        h = dt[k]
        a = alpha[k]
        k1 = pressure_rate(P, V, V_dot, mass_flow(P, a, A1, A2, p, gas), p)
        P2 = P + 0.5 * h * k1
        k2 = pressure_rate(P2, V, V_dot, mass_flow(P2, a, A1, A2, p, gas), p)
        P3 = P + 0.5 * h * k2
        k3 = pressure_rate(P3, V, V_dot, mass_flow(P3, a, A1, A2, p, gas), p)
        P4 = P + h * k3
        k4 = pressure_rate(P4, V, V_dot, mass_flow(P4, a, A1, A2, p, gas), p)
        P = clip(P + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), P_MIN, P_MAX)
        out[k + 1] = P
    return out


@njit(cache=True)
def pressure_trajectory(P0, alpha, l, l_dot, dt, p, A1, A2, out):
    """pressure_trajectory_with_volume without a dead volume (the paper's eq. (4))."""
    return pressure_trajectory_with_volume(P0, alpha, l, l_dot, dt, p, A1, A2, 0.0, out)


def muscle_inputs(rec, valve_map, p):
    """Per muscle i: (alpha (N,), l_i (N,) m, l_dot_i (N,) m/s) of a record."""
    dL = p.r * np.sin(rec.psi)
    dL_dot = 0.0 if rec.locked else p.r * np.cos(rec.psi) * rec.psi_dot
    l_dot = np.broadcast_to(dL_dot, rec.psi.shape).astype(float)
    return ((valve_map(rec.u[:, 0]), p.L0 - dL, -l_dot),
            (valve_map(rec.u[:, 1]), p.L0 + dL, l_dot))


class PressureModel:
    """The simulated pressures of all records for given (A1_1, A2_1, A1_2, A2_2, k2)."""

    def __init__(self, records, valve_map, prior):
        self.records = records
        self.prior = prior
        self.inputs = [muscle_inputs(r, valve_map, prior) for r in records]
        self.measured = np.concatenate([r.P[:, i] for r in records for i in range(2)])

    def simulate(self, areas, k2, dead_volume: float = 0.0) -> np.ndarray:
        p = self.prior.replace(k2=float(k2)).as_record_array()[0]
        parts = []
        for rec, inputs in zip(self.records, self.inputs, strict=True):
            dt = rec.dt
            for i, (alpha, l, l_dot) in enumerate(inputs):
                out = np.empty(len(rec.t))
                pressure_trajectory_with_volume(float(rec.P[0, i]), alpha, l, l_dot, dt, p,
                                                float(areas[2 * i]), float(areas[2 * i + 1]),
                                                float(dead_volume), out)
                parts.append(out)
        return np.concatenate(parts)


def fit_flow(records, prior, valve_map, dead_volume: bool = False):
    """The fit, the Parameters changes and what could not be fitted (NotIdentifiable list);
    dead_volume: also fit V_d (eq. (4) with V + V_d), returned fourth (m^3, 0 when not
    significant: V_d <= SIGNIFICANCE sigma).

    When k2 alone is too uncertain (its volume term is the small part of the transients, and a
    supply or valve of another form than eq. (4)-(5) biases it first), the areas are fitted
    again with k2 held at its prior: they shape every transient and stay identifiable, so a
    weak k2 does not cost the areas too; k2 is then reported not identified."""
    if not records:
        raise NotIdentifiable('the valve areas need calibration runs with pressure transients',
                              (*AREA_NAMES, 'k2'))
    moving = [r for r in records if not r.locked and r.travel >= MIN_TRAVEL]
    skipped = []
    if not moving:
        skipped.append(NotIdentifiable(
            f'k2 needs a free-joint run in which the joint moves (>= '
            f'{math.degrees(MIN_TRAVEL):.0f} deg of travel): the volume-change term of eq. (4)',
            ('k2',)))
    model = PressureModel(records, valve_map, prior)
    try:
        fitted = _fit_flow(model, prior, bool(moving), dead_volume)
    except NotIdentifiable as gap:
        if not moving or gap.parameters != ('k2',):
            raise NotIdentifiable(gap.what, (*AREA_NAMES, 'k2')) from None
        skipped.append(NotIdentifiable(f'{gap.what}; the areas were fitted with k2 held at '
                                       f'its prior {prior.k2:g}', ('k2',)))
        fitted = _fit_flow(model, prior, False, dead_volume)
    group, changes, V_d = fitted
    if dead_volume:
        return group, changes, skipped, V_d
    return group, changes, skipped


def _fit_flow(model, prior, fit_k2: bool, dead_volume: bool):
    """(GroupFit, Parameters changes, V_d m^3) of the output-error fit of the areas (and k2 when
    fit_k2, and V_d when dead_volume); NotIdentifiable names the weak estimates."""
    areas0 = np.array([getattr(prior, f) for f in AREA_FIELDS])
    n_k2 = 5 if fit_k2 else 4

    def unpack(z, with_volume=dead_volume):
        areas = areas0 * np.exp(z[:4])
        k2 = prior.k2 * (1.0 + z[4]) if fit_k2 else prior.k2
        return areas, k2, (VOLUME_SCALE * z[n_k2] if with_volume else 0.0)

    def solve(with_volume):
        def residual(z):
            return (model.simulate(*unpack(z, with_volume)) - model.measured) / 1e3     # kPa

        z0 = np.zeros(n_k2 + int(with_volume))
        sol = least_squares(residual, z0, method='trf', x_scale=0.1, diff_step=1e-4)
        return sol, standard_errors(sol.jac, sol.fun, correlated=True)

    sol, z_std = solve(dead_volume)
    volume_estimate, V_d = None, 0.0
    if dead_volume:
        value, std = VOLUME_SCALE * sol.x[n_k2], VOLUME_SCALE * z_std[n_k2]
        kept = value > max(SIGNIFICANCE * std, MIN_DEAD_VOLUME)
        volume_estimate = Estimate('dead_volume', float(value), float(std), 0.0, 'm^3',
                                   '' if kept else 'not significant: kept 0')
        if kept:
            V_d = float(value)
        else:
            sol, z_std = solve(False)
    areas, k2, _ = unpack(sol.x, V_d > 0.0)
    estimates = [Estimate(n, float(a), float(a * s), float(a0), 'm^2')
                 for n, a, s, a0 in zip(AREA_NAMES, areas, z_std[:4], areas0, strict=True)]
    if fit_k2:
        estimates.append(Estimate('k2', float(k2), float(prior.k2 * z_std[4]), prior.k2, '-'))
    check_identified(estimates, 'valve flow')
    if volume_estimate is not None:
        estimates.append(volume_estimate)
    changes = dict(zip(AREA_FIELDS, map(float, areas), strict=True))
    if fit_k2:
        changes['k2'] = float(k2)
    notes = (f'k1 held at {prior.k1:g}: A1, A2 are effective areas for it (only k1 A_0 is '
             'identifiable)',)
    if not fit_k2:
        notes += (f'k2 held at its prior {prior.k2:g}',)
    if dead_volume:
        notes += (f'dead volume V_d per muscle in eq. (4) fitted with the areas (it separates '
                  f'from them as the lock angles change V); kept above {SIGNIFICANCE:g} sigma and '
                  f'{MIN_DEAD_VOLUME * 1e6:g} cm^3',)
    group = GroupFit('flow', tuple(estimates), float(np.sqrt(np.mean(sol.fun ** 2))) * 1e3, 'Pa',
                     len(model.measured), notes)
    return group, changes, V_d
