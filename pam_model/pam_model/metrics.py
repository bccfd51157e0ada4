"""Estimation metrics of Sec. IV (MODEL.md section 6).

I(z) = sqrt(mean z^2) (RMSE), M(z) = max |z|, Q(z, xi) = M(z) / (max xi - min xi), with z the
error (for example psi - psi_hat in degrees, tau - tau_hat in N m) and xi the measured signal.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


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
