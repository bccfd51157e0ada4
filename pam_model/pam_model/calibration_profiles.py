"""Input profiles for parameter identification (pam-identify), deterministic from a seed.

* locked_calibration_profile: for a LOCKED joint (torque meter fitted). Static holds of both valves
  at the voltages of the valve-map table, then jumps between them, so that
  (a) the holds end in steady pressures: the static map u -> P_bar that gives kappa(u)
      (MODEL.md section 4);
  (b) the two pressures take many independent pairs: the force coefficients of eq. (7) from the
      torque meter;
  (c) the jumps are fast charging and discharging transients: the effective valve areas A1, A2
      (Prop. 1: they shape transients only).
  Run it at two or more lock angles at least 10 deg apart (e.g. -15, 0, +15 deg), so that the
  length-dependent force coefficients p_v1, p_w1 separate from p_v2, p_w2.
* free_calibration_profile: for a FREE joint (encoder fitted). Antagonistic inputs
  u1 = beta + d(t), u2 = beta - d(t) at three co-contraction levels beta (low, middle, high
  pressures), each with a slow triangle of d (the joint slides slowly: the friction level sets how
  far it lags, a hysteresis of width 2 T_c / stiffness) and fast steps of d (the muscles' volumes
  change fast: the polytropic gain k2 of eq. (4)). Pressures stay within about 200-700 kPa.

A static hold needs ~10 s: near its steady pressure a muscle settles with a time constant of up to
~4 s (mid-range voltages, where the valve is nearly balanced).
"""

from __future__ import annotations

import numpy as np

from .model import T_S
from .profiles import InputProfile, _segment_times

#: Voltages of the static holds (V): the nodes of the shipped valve-map table.
HOLD_VOLTAGES = (0.0, 1.0, 2.0, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 6.5, 7.0, 7.5, 8.0, 9.0, 10.0)
#: Co-contraction levels beta (V) and the largest offset d (V) at each, of the free profile:
#: pressures within about 200-700 kPa with the shipped valve map.
FREE_LEVELS = ((4.7, 0.6), (5.5, 1.4), (6.4, 0.6))
#: Shortest sensible hold (s): the pressure must settle within one hold.
MIN_HOLD = 2.0


def locked_calibration_profile(seed: int = 0, hold: float = 10.0, pair_hold: float = 3.0,
                               voltages=HOLD_VOLTAGES, Ts: float = T_S) -> InputProfile:
    """Inputs for a locked joint, in two phases (u in V, held from t[j] to t[j+1]):

    1. static holds, len(voltages) * hold s: valve 1 climbs the voltages while valve 2 descends
       them, each level held `hold` s. The steps between levels are small, so each hold ends close
       to its steady pressure (pam-identify extrapolates the rest of the approach); hold = 0 skips
       this phase.
    2. pairs, len(voltages) * pair_hold s: both valves jump through the voltages in two
       independent random orders: fast transients and many independent pressure pairs;
       pair_hold = 0 skips this phase.
    Default: 16 voltages, 160 s + 48 s.
    """
    voltages = np.sort(np.asarray(voltages, dtype=float))
    if voltages.ndim != 1 or len(voltages) < 3:
        raise ValueError('need at least 3 hold voltages')
    if np.any(voltages < 0.0) or np.any(voltages > 10.0):
        raise ValueError('hold voltages must lie in 0..10 V')
    for name, value in (('hold', hold), ('pair_hold', pair_hold)):
        if not (value == 0.0 or value >= MIN_HOLD):
            raise ValueError(f'{name} must be 0 (skip) or >= {MIN_HOLD} s, got {value!r}')
    if hold == 0.0 and pair_hold == 0.0:
        raise ValueError('hold and pair_hold cannot both be 0')
    if Ts <= 0.0:
        raise ValueError('Ts must be > 0 s')
    rng = np.random.default_rng(seed)
    n = len(voltages)
    order2 = rng.permutation(n)
    while n > 1 and np.array_equal(order2, np.arange(n)):
        order2 = rng.permutation(n)
    phases = []
    if hold > 0.0:
        phases.append((hold, voltages, voltages[::-1]))
    if pair_hold > 0.0:
        phases.append((pair_hold, voltages[rng.permutation(n)], voltages[order2]))
    parts = []
    for length, u1, u2 in phases:
        t = _segment_times(n * length, Ts)
        idx = np.minimum((t / length).astype(int), n - 1)
        parts.append(np.column_stack([u1[idx], u2[idx]]))
    u = np.concatenate(parts)
    return InputProfile(np.arange(len(u)) * Ts, u)


def free_calibration_profile(seed: int = 0, duration: float = 60.0, levels=FREE_LEVELS,
                             Ts: float = T_S) -> InputProfile:
    """Antagonistic inputs (free joint) at each co-contraction level (beta, d_max) in `levels`,
    one equal block each: 1 s settle at d = 0, a triangle 0 -> +d_max -> -d_max -> 0 over 60 % of
    the block, then four steps to random offsets within +-d_max. u1 = beta + d, u2 = beta - d (V).
    """
    if not duration >= 6.0 * len(levels) or Ts <= 0.0:
        raise ValueError(f'duration must be >= {6.0 * len(levels)} s (6 s per level) and Ts > 0 s')
    rng = np.random.default_rng(seed)
    t = _segment_times(duration, Ts)
    block = duration / len(levels)
    u = np.empty((len(t), 2))
    for b, (beta, d_max) in enumerate(levels):
        inside = (t >= b * block) & (t < (b + 1) * block)
        s = t[inside] - b * block
        d = np.zeros_like(s)
        ramp = (s >= 1.0) & (s < 1.0 + 0.6 * (block - 1.0))
        phase = (s[ramp] - 1.0) / (0.6 * (block - 1.0))        # 0..1 over the triangle
        d[ramp] = d_max * np.interp(phase, [0.0, 0.25, 0.75, 1.0], [0.0, 1.0, -1.0, 0.0])
        steps = s >= 1.0 + 0.6 * (block - 1.0)
        start = 1.0 + 0.6 * (block - 1.0)
        step_len = (block - start) / 4.0
        offsets = d_max * rng.uniform(-1.0, 1.0, 4)
        d[steps] = offsets[np.minimum(((s[steps] - start) / step_len).astype(int), 3)]
        u[inside] = np.column_stack([beta + d, beta - d])
    return InputProfile(t, np.clip(u, 0.0, 10.0))
