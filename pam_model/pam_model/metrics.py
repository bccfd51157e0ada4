"""Estimation metrics of Sec. IV (MODEL.md section 6).

I(z) = sqrt(mean z^2) (RMSE), M(z) = max |z|, Q(z, xi) = M(z) / (max xi - min xi), with z the
error (for example psi - psi_hat in degrees, tau - tau_hat in N m) and xi the measured signal.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: s: the initial transient left out by metrics_after() unless told otherwise.
DEFAULT_TRANSIENT = 1.0


def rmse(z) -> float:
    """I(z, N) = sqrt(mean z^2), same unit as z."""
    z = np.asarray(z, dtype=float)
    return float(np.sqrt(np.mean(z * z)))


def max_abs(z) -> float:
    """M(z) = max |z|, same unit as z."""
    return float(np.max(np.abs(np.asarray(z, dtype=float))))


def relative_max(z, xi) -> float:
    """Q(z, xi) = M(z) / (max xi - min xi), dimensionless (0.0613 is 6.13 %)."""
    xi = np.asarray(xi, dtype=float)
    span = float(np.max(xi) - np.min(xi))
    if span <= 0.0:
        raise ValueError('Q needs a signal xi that varies (max xi - min xi = 0)')
    return max_abs(z) / span


class Metrics(NamedTuple):
    """I (RMSE), M (max |error|) in the error's unit, Q (fraction of the measured range)."""

    I: float
    M: float
    Q: float

    def row(self, unit: str = '') -> str:
        return f'I {self.I:.4g}{unit}  M {self.M:.4g}{unit}  Q {100.0 * self.Q:.2f} %'


def metrics(measured, estimated) -> Metrics:
    """I, M, Q of z = measured - estimated over the whole record, xi = measured."""
    measured = np.asarray(measured, dtype=float)
    z = measured - np.asarray(estimated, dtype=float)
    if z.size == 0 or not np.all(np.isfinite(z)):
        raise ValueError('metrics need a non-empty, finite error signal')
    return Metrics(rmse(z), max_abs(z), relative_max(z, measured))


def after_transient(t, transient: float = DEFAULT_TRANSIENT) -> np.ndarray:
    """Boolean mask of the samples at t >= t[0] + transient (t in s, transient in s, >= 0)."""
    t = np.asarray(t, dtype=float)
    if not (np.isfinite(transient) and transient >= 0.0):
        raise ValueError(f'the initial transient must be a finite number of seconds >= 0, '
                         f'got {transient!r}')
    if t.size == 0:
        raise ValueError('metrics need a non-empty record')
    return t >= t[0] + transient


def metrics_after(t, measured, estimated, transient: float = DEFAULT_TRANSIENT) -> Metrics:
    """I, M, Q as metrics() over the samples at t >= t[0] + transient only (t in s).

    ValueError when the record is no longer than the transient (no sample left)."""
    keep = after_transient(t, transient)
    measured = np.asarray(measured, dtype=float)
    estimated = np.asarray(estimated, dtype=float)
    if keep.shape != measured.shape or keep.shape != estimated.shape:
        raise ValueError(f't, measured and estimated must have one sample each, got '
                         f'{keep.shape}, {measured.shape}, {estimated.shape}')
    if not keep.any():
        span = float(np.asarray(t, dtype=float)[-1] - np.asarray(t, dtype=float)[0])
        raise ValueError(f'no sample after the initial transient of {transient:g} s: the record '
                         f'spans {span:.3f} s')
    return metrics(measured[keep], estimated[keep])
