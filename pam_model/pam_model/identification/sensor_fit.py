"""Pressure-sensor offsets from the vented static holds (0 V) of the locked runs.

A transducer reads y = (1 + g) P + o (pam_model.effects). Held at 0 V a valve vents its muscle
(kappa(0 V) = 0 by definition): the pressure settles at the exhaust pressure P_out, the
atmosphere (the prior's P_out, ASSUMED known). The settled reading y_0 of each sensor gives
    o = y_0 - P_out,
which is the offset plus g P_out (0.5 kPa per 0.5 % of gain error: a bias the report states).
The gain error would need a second known pressure: the fully open holds (10 V) settle at the
supply pressure, but not at its set point: a supply that ripples is followed up to its peaks and
not back (the valve does not flow backwards), and a regulator's set point is itself known to
about 1 % (1 % of P_tank is 1.2 % of gain). On the 'realistic' plant the 10 V holds read 5 kPa
above (1 + g) P_tank + o. So the gains stay 0 (the force coefficients, fitted on the same
readings, absorb a gain error of the torque; a supply-pressure channel would tell it).
Steady readings come from valve_fit.steady_state (the extrapolated approach).

An offset is kept only when it exceeds SIGNIFICANCE sigma and MIN_OFFSET (otherwise 0, the
paper's model): the parameters fitted on corrected pressures then stay as without the fit on a
rig with exact sensors. Without a settled hold at 0 V on a muscle, its sensor keeps offset 0 and
the report says why.
"""

from __future__ import annotations

import numpy as np

from .fit_result import Estimate, GroupFit
from .records import CalibrationRecord
from .valve_fit import MAX_GAP, MAX_STEADY_STD, MIN_STEADY_STD, hold_segments, steady_state

SIGNIFICANCE = 3.0          # a value is kept when it exceeds this many sigma
MIN_OFFSET = 250.0          # Pa, and this much: about one step of a 12-bit ADC over 1 MPa
LOW_VOLTAGE, HIGH_VOLTAGE = 0.0, 10.0   # V: vented (P_out) and fully open (P_tank)


def settled_readings(records, muscle: int, voltage: float):
    """[(y Pa, std Pa)]: the settled readings of one sensor at one hold voltage (locked runs)."""
    rows = []
    for rec in records:
        if not rec.locked:
            continue
        for a, b in hold_segments(rec.u[:, muscle], rec.t):
            if abs(rec.u[a, muscle] - voltage) > 1e-6:
                continue
            y, std, gap = steady_state(rec.t[a:b], rec.P[a:b, muscle])
            if abs(gap) <= MAX_GAP and std <= MAX_STEADY_STD:
                rows.append((y, max(std, MIN_STEADY_STD)))
    return rows


def mean_reading(rows) -> tuple[float, float]:
    """Weighted mean (Pa) and its std: the larger of the propagated one and the scatter."""
    values = np.array(rows)
    w = 1.0 / values[:, 1] ** 2
    mean = float(np.sum(w * values[:, 0]) / np.sum(w))
    std = float(np.sqrt(1.0 / np.sum(w)))
    if len(values) > 1:
        std = max(std, float(np.std(values[:, 0], ddof=1) / np.sqrt(len(values))))
    return mean, std


def fit_sensors(records, prior):
    """(GroupFit, offsets (o1, o2) Pa, gains (g1, g2) = (0, 0)): the kept offsets (0 where not
    identified or not significant)."""
    estimates, notes = [], []
    offsets = [0.0, 0.0]
    samples = 0
    for i in range(2):
        low = settled_readings(records, i, LOW_VOLTAGE)
        if not low:
            notes.append(f'P{i + 1} sensor: no settled hold at {LOW_VOLTAGE:g} V on a locked run: '
                         f'offset kept 0')
            continue
        samples += len(low)
        y0, std = mean_reading(low)
        offset = y0 - prior.P_out
        kept = abs(offset) > max(SIGNIFICANCE * std, MIN_OFFSET)
        estimates.append(Estimate(f'sensor_offset P{i + 1}', float(offset), std, 0.0, 'Pa',
                                  '' if kept else 'not significant: kept 0'))
        if kept:
            offsets[i] = float(offset)
    for i in range(2):
        estimates.append(Estimate(f'sensor_gain_error P{i + 1}', 0.0, float('nan'), 0.0, '-',
                                  'not identifiable from the holds: kept 0'))
    notes.append(f'offsets from the settled readings at {LOW_VOLTAGE:g} V = P_out '
                 f'({prior.P_out / 1e3:g} kPa, assumed known), biased by g P_out; kept above '
                 f'{SIGNIFICANCE:g} sigma and {MIN_OFFSET:g} Pa. Gains need a second known '
                 f'pressure: the {HIGH_VOLTAGE:g} V holds settle at the supply\'s peaks, not at '
                 'its set point')
    return (GroupFit('sensors', tuple(estimates), 0.0, 'Pa', samples, tuple(notes)),
            tuple(offsets), (0.0, 0.0))


def corrected(records, offsets, gains) -> list:
    """The records with their pressures corrected as the UKF inverts its readings:
    P = (y - o) / (1 + g)."""
    if not any(offsets) and not any(gains):
        return list(records)
    o, g = np.asarray(offsets, dtype=float), 1.0 + np.asarray(gains, dtype=float)
    return [CalibrationRecord(r.source, r.t, r.u, r.psi, r.psi_dot, (r.P - o) / g, r.tau,
                              r.locked) for r in records]
