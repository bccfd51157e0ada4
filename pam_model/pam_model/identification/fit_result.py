"""Estimates with their uncertainty, one group per fit, and the error for what cannot be fitted."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: A fitted value whose standard deviation exceeds this fraction of its magnitude is declared not
#: identifiable from the runs given.
MAX_RELATIVE_STD = 0.25


class NotIdentifiable(Exception):
    """The runs lack what a fit needs: `what` says what is missing, `parameters` what it would
    fit."""

    def __init__(self, what: str, parameters):
        super().__init__(what)
        self.what = what
        self.parameters = tuple(parameters)


@dataclass(frozen=True)
class Estimate:
    """One identified quantity: value and 1-sigma std in `unit`, the prior it started from; note
    says how it was obtained when that is not a direct fit (std NaN then)."""

    name: str
    value: float
    std: float
    prior: float
    unit: str
    note: str = ''


@dataclass(frozen=True)
class GroupFit:
    """The result of one fit: its estimates, the RMS of its residuals and how many were used."""

    group: str
    estimates: tuple
    residual_rms: float
    residual_unit: str
    samples: int
    notes: tuple = field(default_factory=tuple)


def correlation_time(residuals: np.ndarray, max_lag: int = 20000) -> float:
    """Integrated autocorrelation time of a residual sequence, in samples (1 for white noise):
    1 + 2 sum of the autocorrelations up to the first lag where they drop below 0.05."""
    r = residuals - residuals.mean()
    n = len(r)
    if n < 4 or not np.any(r):
        return 1.0
    size = 1 << int(np.ceil(np.log2(2 * n)))
    spectrum = np.fft.rfft(r, size)
    acf = np.fft.irfft(spectrum * np.conj(spectrum), size)[:min(n, max_lag)]
    acf = acf / acf[0]
    below = np.flatnonzero(acf < 0.05)
    stop = int(below[0]) if below.size else len(acf)
    return float(max(1.0, 1.0 + 2.0 * np.sum(acf[1:stop])))


def standard_errors(jac: np.ndarray, residuals: np.ndarray, correlated: bool = False) -> np.ndarray:
    """1-sigma standard errors of least-squares parameters: sqrt(diag(s^2 (J^T J)^-1)),
    s^2 = |r|^2 / (m - n); inf in a direction where J^T J is singular. correlated: the residuals
    are correlated in time (output-error fits), so the variance is scaled by their integrated
    autocorrelation time (fewer independent samples than residuals)."""
    m, n = jac.shape
    s2 = float(residuals @ residuals) / max(m - n, 1)
    if correlated:
        s2 *= correlation_time(residuals)
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    tol = sv.max() * max(m, n) * np.finfo(float).eps if sv.size else 0.0
    inv = np.where(sv > tol, 1.0 / np.where(sv > tol, sv, 1.0) ** 2, np.inf)
    with np.errstate(invalid='ignore'):
        var = np.array([np.sum(np.where(vt[:, j] ** 2 > 0.0, vt[:, j] ** 2 * inv, 0.0))
                        for j in range(n)])
    return np.sqrt(s2 * var)


def check_identified(estimates, group: str) -> None:
    """NotIdentifiable if any fitted estimate is too uncertain (MAX_RELATIVE_STD)."""
    weak = [e for e in estimates if not e.note and e.value != 0.0
            and not (e.std <= MAX_RELATIVE_STD * abs(e.value))]
    if weak:
        listing = ', '.join(f'{e.name} ({e.std / abs(e.value):.0%})' if np.isfinite(e.std)
                            else f'{e.name} (unbounded)' for e in weak)
        raise NotIdentifiable(f'the runs do not excite the {group} fit enough: relative '
                              f'uncertainty over {MAX_RELATIVE_STD:.0%} for {listing}',
                              [e.name for e in weak])
