"""Force hysteresis (Maxwell slip, pam_model.effects) from the torque meter of locked runs, fitted
jointly with the force coefficients of eq. (6)-(7).

On a locked joint tau = r cos(psi) (F1 - F2) with F_i = v(l_i) P_i + w(l_i) + F_h,i. The
Maxwell-slip force F_h,i of pam_model.effects.MaxwellSlip (n elements, band B in N at 500 kPa,
travel Delta in N), driven by the nominal force s_i = v(l_i) P_i + w(l_i), is LINEAR in B for a
fixed Delta: scaling B scales every slip force and every stiffness alike, and the anchors do not
move with it. So for a given Delta the torque is linear in the six force unknowns of force_fit
and B (one more column: r cos(psi) (h_1 - h_2), h_i the response with a 1 N band); Delta is
searched (a log grid, then a bounded refinement of the residual sum of squares), and the nominal
forces s_i are recomputed from the refitted coefficients (ITERATIONS passes).

s_i is computed from the measured pressures, low-passed at PRESSURE_FILTER_HZ (zero phase): the
sensor noise (2 kPa is 0.3 N of force) would otherwise make the model's elements slip on noise,
which the fit pays back with a wider loop. On a plant with hysteresis alone (B = 2 N, Delta = 5 N,
2 kPa noise) B came out +0.8 % at 5 Hz, +1.4 % at 10 Hz, +2.6 % at 20 Hz, +17 % unfiltered;
without noise within 0.1 % at 5-10 Hz (the loop is rate independent: smoothing the pressure jumps
does not change its path).
The 1-sigma uncertainties come from the Jacobian of the joint fit (B and Delta included), with the
residuals' correlation time (the torque residual is not white once a loop is modelled). The loop
counts as seen when B > SIGNIFICANCE sigma_B and B > MIN_BAND; otherwise B stays 0 (the paper's
model) and the force coefficients are those of the plain fit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.optimize import minimize_scalar
from scipy.signal import butter, sosfiltfilt

from ..effects import HYSTERESIS_PRESSURE
from ..effects_physics import band_scale, bouc_wen_advance
from ..physics_vectorised import muscle_forces
from .fit_result import Estimate, GroupFit, standard_errors
from .force_fit import fit_forces, regressors, usable_records

PRESSURE_FILTER_HZ = 5.0                  # Hz, low-pass of the pressures driving the model loop
TRAVELS = np.geomspace(0.5, 40.0, 19)     # N, grid of the travel Delta
#: the loop forms a locked run can show, and the grid of each one's travel: the Maxwell slip
#: driven by the nominal force (N), a Bouc-Wen loop driven by the pressure (Pa; signed band)
LOCKED_FORMS = ('maxwell', 'pressure')
FORM_TRAVELS = {'maxwell': TRAVELS, 'pressure': np.geomspace(2e3, 2e5, 19)}
FORM_NAMES = {'maxwell': 'Maxwell slip driven by the nominal force',
              'pressure': 'Bouc-Wen loop driven by the pressure'}
ITERATIONS = 2                            # passes of (nominal forces, joint fit)
SIGNIFICANCE = 3.0                        # a loop is seen when B > this many sigma
#: N, and B > this (the statistical sigma misses the model bias; on the 'mild' plant, with no
#: loop, B came out -0.02 N)
MIN_BAND = 0.1
PARAMETERS = ('hysteresis_band', 'hysteresis_travel')


@njit(cache=True)
def slip_step(anchor, s, P, travel, p_out):
    """One sample of ONE muscle's Maxwell slip with a 1 N band at 500 kPa (MaxwellSlip.update):
    moves the anchors (n,) N in place with nominal force s (N) at pressure P (Pa abs), travel
    Delta (N); returns the force (N)."""
    n = anchor.shape[0]
    c = band_scale(P, p_out, HYSTERESIS_PRESSURE)
    total = 0.0
    for j in range(n):
        slip = 1.0 / n
        stiffness = slip / ((j + 1) * travel / n)
        limit = slip * c
        f = stiffness * (s - anchor[j])
        if f > limit:
            f = limit
        elif f < -limit:
            f = -limit
        anchor[j] = s - f / stiffness
        total += f
    return total


@njit(cache=True)
def slip_response(s, P, n, travel, p_out, out):
    """out[k] (N): the Maxwell-slip force of ONE muscle with a 1 N band at 500 kPa, n elements and
    travel Delta (N), driven by the nominal force s (N,) N at pressures P (N,) Pa abs; the elements
    start relaxed at s[0] (as MaxwellSlip's first update)."""
    anchor = np.full(n, s[0])
    for k in range(s.shape[0]):
        out[k] = slip_step(anchor, s[k], P[k], travel, p_out)
    return out


@njit(cache=True)
def pressure_loop_response(P, travel, p_out, out):
    """out[k] (N): the Bouc-Wen force of ONE muscle with a 1 N band at 500 kPa driven by its
    pressure P (N,) Pa abs over travel (Pa), z starting at 0 (as BoucWen's first update)."""
    z = 0.0
    before = P[0] / travel
    for k in range(P.shape[0]):
        x = P[k] / travel
        z = bouc_wen_advance(z, x - before)
        before = x
        out[k] = band_scale(P[k], p_out, HYSTERESIS_PRESSURE) * z
    return out


def low_passed(rec, cutoff_hz: float = PRESSURE_FILTER_HZ) -> np.ndarray:
    """(N, 2) Pa: a record's pressures low-passed at cutoff_hz, zero phase."""
    fs = 1.0 / float(np.median(rec.dt))
    sos = butter(2, min(cutoff_hz, 0.4 * fs), fs=fs, output='sos')
    return sosfiltfilt(sos, rec.P, axis=0)


def nominal_forces(used, params, pressures) -> list:
    """[(F1 (N,), F2 (N,)) N]: eq. (6)-(7) of each used record at its pressures."""
    return [tuple(np.ascontiguousarray(F, dtype=float)
                  for F in muscle_forces(r.psi, P[:, 0], P[:, 1], params))
            for r, P in zip(used, pressures, strict=True)]


def unit_loops(used, forces, pressures, travel: float, elements: int, p_out: float, r: float,
               form: str = 'maxwell'):
    """(N,) N m: the torque r cos(psi) (h_1 - h_2) of a 1 N band of `form` over all used
    records (travel in N for the Maxwell slip, Pa for the pressure's Bouc-Wen loop)."""
    parts = []
    for rec, F, P in zip(used, forces, pressures, strict=True):
        h = []
        for i in range(2):
            out = np.empty(len(rec.t))
            if form == 'maxwell':
                slip_response(F[i], np.ascontiguousarray(P[:, i]), elements, float(travel),
                              p_out, out)
            else:
                pressure_loop_response(np.ascontiguousarray(P[:, i]), float(travel), p_out, out)
            h.append(out)
        parts.append(r * np.cos(rec.psi) * (h[0] - h[1]))
    return np.concatenate(parts)


class LinearTorqueFit:
    """Least squares of tau on the force regressors plus one column, by the normal equations
    (columns scaled to unit RMS): fast enough to search Delta."""

    def __init__(self, A, tau):
        self.scale = np.sqrt(np.mean(A ** 2, axis=0))
        self.A = A / self.scale
        self.AtA, self.Att, self.tt = self.A.T @ self.A, self.A.T @ tau, float(tau @ tau)
        self.tau = tau

    def ssr(self, column) -> tuple[float, float]:
        """(residual sum of squares N^2 m^2, coefficient of the column)."""
        c_scale = max(float(np.sqrt(np.mean(column ** 2))), 1e-300)
        c = column / c_scale
        Atc = self.A.T @ c
        M = np.block([[self.AtA, Atc[:, None]], [Atc[None, :], np.array([[c @ c]])]])
        b = np.append(self.Att, c @ self.tau)
        theta = np.linalg.solve(M, b)
        return float(self.tt - 2.0 * theta @ b + theta @ M @ theta), float(theta[-1] / c_scale)


def fit_hysteresis(records, prior, elements: int, form: str = 'maxwell'):
    """(force GroupFit, force changes, hysteresis GroupFit, (B N, Delta N or Pa)).

    form: 'maxwell' (B > 0) or 'pressure' (a Bouc-Wen loop driven by the pressure, B signed).
    (B, Delta) = (0, None) when the loop is not seen (|B| <= SIGNIFICANCE sigma); the force fit
    is then the plain one. NotIdentifiable as fit_forces when the locked runs are missing."""
    travels = FORM_TRAVELS[form]
    unit = 'N' if form == 'maxwell' else 'Pa'
    names = (('hysteresis_band', 'hysteresis_travel') if form == 'maxwell' else
             ('bouc_wen_band', 'bouc_wen_pressure_travel'))
    used = usable_records(records)
    plain_group, plain_changes = fit_forces(records, prior)
    pressures = [low_passed(r) for r in used]
    tau = np.concatenate([r.tau for r in used])
    A = _force_design(used, prior)
    linear = LinearTorqueFit(A, tau)
    changes = plain_changes
    p_out, r = float(prior.P_out), float(prior.r)
    for _ in range(ITERATIONS):
        forces = nominal_forces(used, prior.replace(**changes), pressures)

        def cost(log_delta, forces=forces):
            return linear.ssr(unit_loops(used, forces, pressures, math.exp(log_delta), elements,
                                         p_out, r, form))[0]

        costs = [cost(math.log(d)) for d in travels]
        j = int(np.argmin(costs))
        lo, hi = math.log(travels[max(j - 1, 0)]), math.log(travels[min(j + 1, len(travels) - 1)])
        best = minimize_scalar(cost, bounds=(lo, hi), method='bounded', options={'xatol': 1e-3})
        travel = math.exp(best.x)
        column = unit_loops(used, forces, pressures, travel, elements, p_out, r, form)
        group, changes, (band, _) = fit_forces(records, prior, extra_column=column)
    # uncertainties of the joint fit: the linear columns, B's, and Delta's (log) derivative
    step = 1e-3
    d_column = (unit_loops(used, forces, pressures, travel * math.exp(step), elements, p_out, r,
                           form)
                - unit_loops(used, forces, pressures, travel * math.exp(-step), elements, p_out,
                             r, form)) / (2.0 * step)
    jac = np.column_stack([A, column, band * d_column])
    theta = np.linalg.lstsq(jac[:, :-1], tau, rcond=None)[0]
    residual = jac[:, :-1] @ theta - tau
    col_scale = np.maximum(np.sqrt(np.mean(jac ** 2, axis=0)), 1e-300)
    std = standard_errors(jac / col_scale, residual, correlated=True) / col_scale
    band_std, log_travel_std = float(std[-2]), float(std[-1])
    travel_std = travel * log_travel_std
    size = band if form == 'maxwell' else abs(band)
    seen = size > max(SIGNIFICANCE * band_std, MIN_BAND)
    estimates = (Estimate(names[0], float(band), band_std, 0.0, 'N'),
                 Estimate(names[1], float(travel), travel_std, 0.0, unit))
    notes = [f'Maxwell slip, {elements} elements, driven by the nominal forces of the pressures '
             f'low-passed at {PRESSURE_FILTER_HZ:g} Hz; band B at 500 kPa (half-width of the loop)'
             if form == 'maxwell' else
             f'Bouc-Wen loop driven by the pressures low-passed at {PRESSURE_FILTER_HZ:g} Hz; '
             'band B_w at 500 kPa, signed (its orientation)']
    if not seen:
        notes.append(f'loop not seen (B {band:.3g} N, sigma {band_std:.2g} N: not above '
                     f'{SIGNIFICANCE:g} sigma and {MIN_BAND:g} N): B kept 0, force coefficients '
                     'of the plain fit')
        return (plain_group, plain_changes,
                GroupFit('hysteresis', estimates, group.residual_rms, 'N m', len(tau),
                         tuple(notes)), (0.0, None))
    notes.append(f'torque residual RMS {plain_group.residual_rms:.4g} N m without the loop')
    return (group, changes,
            GroupFit('hysteresis', estimates, group.residual_rms, 'N m', len(tau), tuple(notes)),
            (float(band), float(travel)))


def _force_design(used, prior) -> np.ndarray:
    psi = np.concatenate([r.psi for r in used])
    P = np.concatenate([r.P for r in used])
    return regressors(psi, P[:, 0], P[:, 1], prior)

