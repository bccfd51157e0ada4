"""The valve map kappa(u): valve voltage (V) -> valve opening alpha in [0, 1] (MODEL.md section 4).

Three-step procedure (Sec. II-C of the paper):
  (a) the model's static map alpha -> steady muscle pressure P_bar (a closed muscle at rest, where
      the net flow alpha m_in(P) - (1 - alpha) m_out(P) vanishes; A_0 drops out, Prop. 1);
  (b) the rig's measured static map u -> P_bar (a CSV of voltage and absolute pressure);
  (c) their composition alpha = P_bar^-1(P_bar(u)) at the measured voltages, interpolated linearly.
Step (c) uses the closed form alpha = m_out / (m_in + m_out), which inverts (a) exactly.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from .parameters import Parameters, data_path
from .physics import gas_constants, inflow_per_area, outflow_per_area
from .valve_voltage import U_MAX, U_MIN

#: The shipped static curve of the simulated rig (step (b) input) and the kappa table made from it.
DEFAULT_STATIC_CURVE = 'static_voltage_pressure.csv'
DEFAULT_KAPPA_TABLE = 'kappa_default.csv'


class ValveMapError(ValueError):
    """A kappa table or static-curve file is malformed or not monotone."""


@dataclass(frozen=True)
class ValveMap:
    """kappa as a table: voltages u (V, strictly increasing, 0..10) and openings alpha (0..1)."""

    u: np.ndarray
    alpha: np.ndarray

    def __post_init__(self):
        u = np.ascontiguousarray(self.u, dtype=float)
        alpha = np.ascontiguousarray(self.alpha, dtype=float)
        object.__setattr__(self, 'u', u)
        object.__setattr__(self, 'alpha', alpha)
        if u.ndim != 1 or u.shape != alpha.shape or len(u) < 2:
            raise ValveMapError('kappa table needs two equal 1-D columns of at least 2 rows')
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(alpha))):
            raise ValveMapError('kappa table holds a non-finite value')
        if np.any(np.diff(u) <= 0.0):
            raise ValveMapError('kappa table voltages must be strictly increasing')
        if np.any(np.diff(alpha) < 0.0):
            raise ValveMapError('kappa table openings must be non-decreasing (kappa is monotone)')
        if u[0] > U_MIN or u[-1] < U_MAX:
            raise ValveMapError(f'kappa table must cover {U_MIN}..{U_MAX} V')
        if alpha[0] < 0.0 or alpha[-1] > 1.0:
            raise ValveMapError('kappa table openings must lie in [0, 1]')

    def __call__(self, u):
        """alpha = kappa(u) for a voltage or an array of voltages (V); NaN reads as 0 V."""
        u = np.asarray(u, dtype=float)
        u = np.clip(np.where(np.isfinite(u), u, U_MIN), U_MIN, U_MAX)
        return np.interp(u, self.u, self.alpha)

    def to_csv(self) -> str:
        """The table as CSV text with header voltage_V,alpha."""
        lines = ['voltage_V,alpha', *(f'{u:.6g},{a:.6f}'
                                      for u, a in zip(self.u, self.alpha, strict=True))]
        return '\n'.join(lines) + '\n'

    def save(self, path: str | Path) -> None:
        Path(path).write_text(self.to_csv())


def read_two_column_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Two numeric columns from a CSV with '#' comments and one header row."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ValveMapError(f'{path}: cannot read: {exc.strerror}') from exc
    rows = [row for row in csv.reader(io.StringIO(text))
            if row and not row[0].lstrip().startswith('#')]
    if len(rows) < 3:
        raise ValveMapError(f'{path}: expected a header and at least 2 data rows')
    try:
        data = np.array([[float(v) for v in row[:2]] for row in rows[1:]])
    except (ValueError, IndexError) as exc:
        raise ValveMapError(f'{path}: every data row needs two numbers ({exc})') from exc
    return data[:, 0], data[:, 1]


def load_valve_map(name_or_path: str | Path = 'default') -> ValveMap:
    """Load a kappa table CSV (voltage_V,alpha); 'default' is the shipped table."""
    path = data_path(DEFAULT_KAPPA_TABLE) if str(name_or_path) == 'default' else Path(name_or_path)
    u, alpha = read_two_column_csv(path)
    try:
        return ValveMap(u, alpha)
    except ValveMapError as exc:
        raise ValveMapError(f'{path}: {exc}') from exc


def net_flow_per_area(P: float, alpha: float, p: Parameters) -> float:
    """alpha m_in(P) - (1 - alpha) m_out(P) (kg/(s m^2)) at pressure P (Pa abs)."""
    gas = gas_constants(p)
    return alpha * inflow_per_area(P, p, gas) - (1.0 - alpha) * outflow_per_area(P, p, gas)


def steady_pressure(alpha: float, p: Parameters) -> float:
    """Step (a): the steady pressure P_bar (Pa abs) of a closed muscle at opening alpha in
    [0, 1]."""
    if alpha <= 0.0:
        return p.P_out
    if alpha >= 1.0:
        return p.P_tank
    return brentq(net_flow_per_area, p.P_out, p.P_tank, args=(alpha, p), xtol=1e-6, rtol=1e-14)


def opening_for_steady_pressure(P_bar, p: Parameters):
    """Step (c) inverse: alpha = m_out / (m_in + m_out) at steady pressure P_bar (Pa abs).

    P_bar <= P_out gives 0, P_bar >= P_tank gives 1. Accepts a scalar or an array.
    """
    P_bar = np.atleast_1d(np.asarray(P_bar, dtype=float))
    alpha = np.empty_like(P_bar)
    gas = gas_constants(p)
    for j, P in enumerate(P_bar):
        if P <= p.P_out:
            alpha[j] = 0.0
        elif P >= p.P_tank:
            alpha[j] = 1.0
        else:
            m_out = outflow_per_area(P, p, gas)
            alpha[j] = m_out / (inflow_per_area(P, p, gas) + m_out)
    return alpha


def calibrate_valve_map(u_measured, P_measured, p: Parameters) -> ValveMap:
    """Steps (b)-(c): the kappa table at the measured voltages from a measured static map.

    u_measured (V) and P_measured (Pa abs) are the rig's steady pressures at constant voltages.
    The result is forced monotone (a running maximum over noisy data) and pinned to kappa = 0 at the
    lowest and 1 at the highest voltage, which must be 0 V and 10 V.
    """
    u = np.asarray(u_measured, dtype=float)
    P = np.asarray(P_measured, dtype=float)
    order = np.argsort(u)
    u, P = u[order], P[order]
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(P))):
        raise ValveMapError('static map holds a non-finite value')
    alpha = np.maximum.accumulate(opening_for_steady_pressure(P, p))
    alpha[0], alpha[-1] = 0.0, 1.0
    return ValveMap(u, alpha)


def static_pressure_curve(alphas, p: Parameters) -> np.ndarray:
    """Step (a) over a grid of openings: P_bar(alpha) (Pa abs) for each alpha."""
    return np.array([steady_pressure(float(a), p) for a in np.asarray(alphas, dtype=float)])
