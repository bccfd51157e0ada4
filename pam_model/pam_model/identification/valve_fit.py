"""kappa(u) from static holds (MODEL.md section 4, step (b) measured on the runs).

A hold is a stretch of at least MIN_HOLD s where one valve's voltage stays constant on a locked
joint. Its steady pressure P_bar is extrapolated from the second half of the hold by fitting
P(t) = P_bar + c exp(-(t - t_end) / tau_h) (a grid over the time constant tau_h, linear least
squares in P_bar and c): near equilibrium a muscle settles exponentially, with tau_h up to ~4 s.
A hold counts as settled when the remaining approach |c| <= MAX_GAP and P_bar is known to
MAX_STEADY_STD. The settled P_bar of each voltage are averaged over holds, muscles and runs, and
kappa = P_bar^-1(P_bar(u)) through the model's static map (valve_map.calibrate_valve_map).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..valve_map import ValveMap, ValveMapError, calibrate_valve_map, opening_for_steady_pressure
from .fit_result import Estimate, GroupFit, NotIdentifiable

MIN_HOLD = 2.0            # s, shortest stretch of constant voltage that counts as a hold
MAX_GAP = 15.0e3          # Pa, largest remaining approach of a settled hold
MAX_STEADY_STD = 1.5e3    # Pa, largest 1-sigma uncertainty of a settled P_bar
MIN_STEADY_STD = 10.0     # Pa, floor of that uncertainty (a noise-free, constant pressure)
TIME_CONSTANTS = np.geomspace(0.1, 20.0, 48)   # s, grid of the exponential approach
VOLTAGE_DECIMALS = 3      # voltages equal to 1 mV are one hold voltage
PARAMETER = 'kappa'


def hold_segments(u: np.ndarray, t: np.ndarray, min_duration: float = MIN_HOLD):
    """[(start, stop)] index ranges (stop exclusive) where u (V) is constant >= min_duration s."""
    change = np.flatnonzero(np.abs(np.diff(u)) > 1e-9) + 1
    bounds = np.concatenate([[0], change, [len(u)]])
    return [(int(a), int(b)) for a, b in itertools.pairwise(bounds)
            if t[b - 1] - t[a] >= min_duration]


def steady_state(t: np.ndarray, P: np.ndarray) -> tuple[float, float, float]:
    """(P_bar, its 1-sigma std, remaining gap c) in Pa from one hold's time t (s) and pressure P
    (Pa), fitted on the hold's second half."""
    half = len(t) // 2
    tt, pp = t[half:] - t[-1], P[half:]
    best = None
    for tau_h in (np.inf, *TIME_CONSTANTS):
        X = (np.ones((len(tt), 1)) if np.isinf(tau_h)
             else np.column_stack([np.ones_like(tt), np.exp(-tt / tau_h)]))
        coef, *_ = np.linalg.lstsq(X, pp, rcond=None)
        r = pp - X @ coef
        ssr = float(r @ r)
        if best is None or ssr < best[0]:
            best = (ssr, X, coef)
    ssr, X, coef = best
    s2 = ssr / max(len(tt) - X.shape[1], 1)
    cov = s2 * np.linalg.pinv(X.T @ X)
    gap = float(coef[1]) if len(coef) > 1 else 0.0
    return float(coef[0]), float(np.sqrt(cov[0, 0])), gap


def static_map(records):
    """Settled holds of locked runs: (voltages (V), P_bar (Pa), std (Pa)) per hold, and the
    number of holds rejected as not settled."""
    rows, rejected = [], 0
    for rec in records:
        if not rec.locked:
            continue
        for i in range(2):
            for a, b in hold_segments(rec.u[:, i], rec.t):
                P_bar, std, gap = steady_state(rec.t[a:b], rec.P[a:b, i])
                if abs(gap) <= MAX_GAP and std <= MAX_STEADY_STD:
                    rows.append((round(float(rec.u[a, i]), VOLTAGE_DECIMALS), P_bar,
                                 max(std, MIN_STEADY_STD)))
                else:
                    rejected += 1
    return rows, rejected


def fit_valve_map(records, prior, prior_map: ValveMap) -> tuple[GroupFit, ValveMap]:
    """kappa(u) at the hold voltages, from the settled static holds of the locked runs."""
    rows, rejected = static_map(records)
    voltages = sorted({u for u, _, _ in rows})
    if not voltages or voltages[0] > 0.0 or voltages[-1] < 10.0 or len(voltages) < 5:
        found = ', '.join(f'{u:g}' for u in voltages) or 'none'
        raise NotIdentifiable(
            f'kappa(u) needs settled static holds (>= {MIN_HOLD:g} s at a constant voltage, '
            f'locked joint) at 0 V, 10 V and at least 3 voltages between; settled holds found at: '
            f'{found} V ({rejected} holds not settled)', [PARAMETER])
    P_bar, P_std, spread = [], [], []
    for u in voltages:
        values = np.array([(p, s) for v, p, s in rows if v == u])
        weights = 1.0 / values[:, 1] ** 2
        mean = float(np.sum(weights * values[:, 0]) / np.sum(weights))
        P_bar.append(mean)
        # the larger of the propagated std and the scatter between holds
        scatter = (float(np.std(values[:, 0], ddof=1) / np.sqrt(len(values)))
                   if len(values) > 1 else 0.0)
        P_std.append(max(float(np.sqrt(1.0 / np.sum(weights))), scatter))
        spread.extend(values[:, 0] - mean)
    try:
        valve_map = calibrate_valve_map(voltages, P_bar, prior)
    except ValveMapError as exc:
        raise NotIdentifiable(f'kappa(u): {exc}', [PARAMETER]) from exc
    P_bar, P_std = np.asarray(P_bar), np.asarray(P_std)
    alpha_std = 0.5 * np.abs(opening_for_steady_pressure(P_bar + P_std, prior)
                             - opening_for_steady_pressure(P_bar - P_std, prior))
    estimates = tuple(
        Estimate(f'kappa({u:g} V)', float(a), float(s), float(prior_map(u)), '-',
                 'pinned' if j in (0, len(voltages) - 1) else '')
        for j, (u, a, s) in enumerate(zip(voltages, valve_map.alpha, alpha_std, strict=True)))
    notes = (f'{len(rows)} settled holds at {len(voltages)} voltages, {rejected} not settled '
             'and left out; kappa(0 V) = 0 and kappa(10 V) = 1 by definition',)
    return (GroupFit('valve_map', estimates, float(np.sqrt(np.mean(np.square(spread)))), 'Pa',
                     len(rows), notes), valve_map)
