"""Force coefficients of eq. (6)-(7) from the torque meter of locked runs (linear least squares).

On a locked joint tau = r cos(psi) (F1 - F2) with F_i = (p_v1i l_i + p_v2i) P_i + p_w1i l_i + p_w2i
and l1 = L0 - dL, l2 = L0 + dL, dL = r sin(psi). The torque sees the intercepts only through
    w1(l1) - w2(l2) = w0 - a dL,   w0 = w1(L0) - w2(L0),   a = p_w1_1 + p_w1_2,
so the regression has six unknowns: p_v1, p_v2 of each muscle (separable when the runs span two
or more lock angles), w0 and a. The split of w0 and a between the two muscles cannot be seen by a
torque meter (only the shaft friction feels F1 + F2): it is kept as in the prior (each p_w1 moves
by half the change of a, p_w2 of PAM1 and PAM2 by plus and minus half the change of w0).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from .fit_result import Estimate, GroupFit, NotIdentifiable, check_identified, standard_errors

MIN_ANGLE_SPAN = math.radians(10.0)   # rad, lock angles must span this much
MIN_PRESSURE_SPAN = 150.0e3           # Pa, each muscle's pressure must span this much
#: Smallest scale of each unknown (p_v1 m, p_v2 m^2, p_v1 m, p_v2 m^2, w0 N, a N/m): a prior of 0
#: must not make its column vanish.
TYPICAL_SCALE = np.array([1e-3, 1e-4, 1e-3, 1e-4, 1.0, 10.0])
PARAMETERS = ('pam1.p_v1', 'pam1.p_v2', 'pam1.p_w1', 'pam1.p_w2',
              'pam2.p_v1', 'pam2.p_v2', 'pam2.p_w1', 'pam2.p_w2')


def intercept_combinations(p) -> tuple[float, float]:
    """(w0 in N, a in N/m) of a parameter set: the intercept terms a torque meter sees."""
    w0 = (p.p_w1_1 * p.L0 + p.p_w2_1) - (p.p_w1_2 * p.L0 + p.p_w2_2)
    return w0, p.p_w1_1 + p.p_w1_2


def regressors(psi, P1, P2, p) -> np.ndarray:
    """(N, 6) columns of tau for (p_v1_1, p_v2_1, p_v1_2, p_v2_2, w0, a)."""
    dL = p.r * np.sin(psi)
    c = p.r * np.cos(psi)
    l1, l2 = p.L0 - dL, p.L0 + dL
    return c[:, None] * np.column_stack([l1 * P1, P1, -l2 * P2, -P2, np.ones_like(psi), -dL])


def usable_records(records):
    """Locked runs with a torque meter; NotIdentifiable naming what is missing."""
    used = [r for r in records if r.locked and r.has_torque]
    if not used:
        raise NotIdentifiable('the force coefficients need a locked-joint run with a torque meter '
                              '(joint_measured.torque)', PARAMETERS)
    angles = sorted(r.lock_angle for r in used)
    if angles[-1] - angles[0] < MIN_ANGLE_SPAN:
        have = ', '.join(f'{math.degrees(a):+.1f}' for a in angles)
        raise NotIdentifiable(
            f'the force coefficients need locked runs at two or more angles at least '
            f'{math.degrees(MIN_ANGLE_SPAN):.0f} deg apart (p_v1 and p_v2, p_w1 and p_w2 only '
            f'separate when the muscle lengths change); lock angles found: {have} deg', PARAMETERS)
    P = np.concatenate([r.P for r in used])
    spans = np.ptp(P, axis=0)
    if np.any(spans < MIN_PRESSURE_SPAN):
        raise NotIdentifiable(
            f'the force coefficients need each pressure to span at least '
            f'{MIN_PRESSURE_SPAN / 1e3:.0f} kPa on the locked runs; spans: '
            f'{spans[0] / 1e3:.0f} kPa (P1), {spans[1] / 1e3:.0f} kPa (P2)', PARAMETERS)
    return used


def fit_forces(records, prior, extra_column=None):
    """The force coefficients; returns the fit and the Parameters changes (field: value).

    extra_column (N,) N m, optional: one more regressor over the usable records' samples in order
    (hysteresis_fit: the torque of a 1 N hysteresis band), fitted jointly; its (coefficient, std)
    is then returned third."""
    used = usable_records(records)
    psi = np.concatenate([r.psi for r in used])
    P = np.concatenate([r.P for r in used])
    tau = np.concatenate([r.tau for r in used])
    A = regressors(psi, P[:, 0], P[:, 1], prior)
    w0_prior, a_prior = intercept_combinations(prior)
    theta0 = np.array([prior.p_v1_1, prior.p_v2_1, prior.p_v1_2, prior.p_v2_2, w0_prior, a_prior])
    scale = np.maximum(np.abs(theta0), TYPICAL_SCALE)
    if extra_column is not None:
        A = np.column_stack([A, extra_column])
        theta0 = np.append(theta0, 0.0)
        scale = np.append(scale, 1.0)
    As = A * scale
    sol = least_squares(lambda z: As @ z - tau, theta0 / scale, jac=lambda z: As, method='lm')
    theta = sol.x * scale
    std = standard_errors(As, sol.fun) * scale
    extra = None
    if extra_column is not None:
        extra = (float(theta[-1]), float(std[-1]))
        theta, std, theta0 = theta[:-1], std[:-1], theta0[:-1]
    names = ('pam1.p_v1', 'pam1.p_v2', 'pam2.p_v1', 'pam2.p_v2', 'w1(L0) - w2(L0)',
             'pam1.p_w1 + pam2.p_w1')
    units = ('m', 'm^2', 'm', 'm^2', 'N', 'N/m')
    fitted = tuple(Estimate(n, float(v), float(s), float(p0), u)
                   for n, v, s, p0, u in zip(names, theta, std, theta0, units, strict=True))
    check_identified(fitted[:4], 'force')
    d_w0, d_a = theta[4] - w0_prior, theta[5] - a_prior
    changes = {'p_v1_1': theta[0], 'p_v2_1': theta[1], 'p_v1_2': theta[2], 'p_v2_2': theta[3],
               'p_w1_1': prior.p_w1_1 + 0.5 * d_a, 'p_w1_2': prior.p_w1_2 + 0.5 * d_a,
               'p_w2_1': prior.p_w2_1 + 0.5 * d_w0, 'p_w2_2': prior.p_w2_2 - 0.5 * d_w0}
    split = 'from the two combinations above, split as in the prior'
    derived = tuple(Estimate(n, float(changes[f]), float('nan'), float(getattr(prior, f)), u,
                             split)
                    for n, f, u in (('pam1.p_w1', 'p_w1_1', 'N/m'), ('pam1.p_w2', 'p_w2_1', 'N'),
                                    ('pam2.p_w1', 'p_w1_2', 'N/m'), ('pam2.p_w2', 'p_w2_2', 'N')))
    angles = sorted({round(math.degrees(r.lock_angle), 1) for r in used})
    notes = (f'{len(used)} locked runs, lock angles {", ".join(f"{a:+g}" for a in angles)} deg',)
    group = GroupFit('forces', fitted + derived, float(np.sqrt(np.mean(sol.fun ** 2))), 'N m',
                     len(tau), notes)
    changes = {k: float(v) for k, v in changes.items()}
    return (group, changes) if extra_column is None else (group, changes, extra)
