"""Input profiles, deterministic from a seed.

* validation_profile: the 130 s open-loop valve profile shaped like the paper's Fig. 8: both valves
  antagonistic around beta, u1 = beta + d(t), u2 = beta - d(t), with steps, ramps and a slow chirp
  of d. With the default parameters the pressures span about 185-670 kPa, psi about +-17..20 deg
  (free joint) and tau about +-2.2..2.5 N m (locked joint), depending on the seed.
  Segments are slow: the valves need seconds to fill a muscle.
* step_reference_profile: reference steps for closed-loop control, within +-20 deg (angle) or
  +-2 N m (torque).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .model import T_S
from .rest import BETA

D_MAX = 1.85          # V, largest antagonistic offset of the validation profile
ANGLE_STEP_MAX = math.radians(20.0)   # rad
TORQUE_STEP_MAX = 2.0                  # N m


class InputProfile(NamedTuple):
    """Sampled valve voltages: t (N,) s, u (N, 2) V, held from t[j] to t[j+1]."""

    t: np.ndarray
    u: np.ndarray


class ReferenceProfile(NamedTuple):
    """Sampled reference: t (N,) s, value (N,) in rad (angle) or N m (torque)."""

    mode: str
    t: np.ndarray
    value: np.ndarray


def _segment_times(duration: float, Ts: float) -> np.ndarray:
    n = round(duration / Ts)
    return np.arange(n) * Ts


def validation_offsets(t: np.ndarray, seed: int) -> np.ndarray:
    """d(t) (V) of the validation profile, scaled to the 130 s layout whatever the duration.

    Layout as fractions of the duration: settle 0-4 %, eight steps 4-35 %, two triangle ramps
    35-58 %, a chirp 0.02 -> 0.3 Hz 58-96 %, settle 96-100 %.
    """
    rng = np.random.default_rng(seed)
    duration = t[-1] + (t[1] - t[0]) if len(t) > 1 else 1.0
    s = t / duration
    d = np.zeros_like(t)
    # steps: a permutation of 8 levels spanning +-D_MAX, each with a little jitter
    levels = np.linspace(-D_MAX, D_MAX, 8)[rng.permutation(8)]
    levels = np.clip(levels + rng.uniform(-0.1, 0.1, 8), -D_MAX, D_MAX)
    in_steps = (s >= 0.04) & (s < 0.35)
    idx = np.minimum(((s[in_steps] - 0.04) / 0.31 * 8).astype(int), 7)
    d[in_steps] = levels[idx]
    # ramps: two triangle periods between -D_MAX and +D_MAX, random sign
    in_ramps = (s >= 0.35) & (s < 0.58)
    phase = (s[in_ramps] - 0.35) / 0.23 * 2.0 % 1.0
    sign = rng.choice([-1.0, 1.0])
    d[in_ramps] = sign * D_MAX * (1.0 - 4.0 * np.abs(phase - 0.5)) * -1.0
    # chirp: linear sweep of frequency f0 -> f1 over its segment
    in_chirp = (s >= 0.58) & (s < 0.96)
    tc = t[in_chirp] - t[in_chirp][0] if np.any(in_chirp) else t[in_chirp]
    T_c = 0.38 * duration
    f0, f1 = 0.02, 0.3
    d[in_chirp] = D_MAX * np.sin(2.0 * np.pi * (f0 * tc + 0.5 * (f1 - f0) / T_c * tc ** 2))
    return d


def validation_profile(seed: int = 0, duration: float = 130.0, Ts: float = T_S,
                       beta: float = BETA) -> InputProfile:
    """The open-loop validation profile: u1 = beta + d(t), u2 = beta - d(t) (V)."""
    if duration <= 0.0 or Ts <= 0.0:
        raise ValueError('duration and Ts must be > 0 s')
    t = _segment_times(duration, Ts)
    d = validation_offsets(t, seed)
    return InputProfile(t, np.column_stack([beta + d, beta - d]))


def step_reference_profile(mode: str = 'angle', seed: int = 0, duration: float = 60.0,
                           hold: float = 6.0, Ts: float = T_S) -> ReferenceProfile:
    """Reference steps held `hold` s each: 0 first, then levels drawn uniformly within +-20 deg
    (mode 'angle', rad) or +-2 N m (mode 'torque'), at least a quarter of the range apart."""
    if mode not in ('angle', 'torque'):
        raise ValueError(f"mode must be 'angle' or 'torque', got {mode!r}")
    if duration <= 0.0 or hold <= 0.0 or Ts <= 0.0:
        raise ValueError('duration, hold and Ts must be > 0 s')
    limit = ANGLE_STEP_MAX if mode == 'angle' else TORQUE_STEP_MAX
    rng = np.random.default_rng(seed)
    t = _segment_times(duration, Ts)
    n_steps = math.ceil(duration / hold)
    levels = [0.0]
    while len(levels) < n_steps:
        level = rng.uniform(-limit, limit)
        if abs(level - levels[-1]) >= 0.5 * limit:
            levels.append(level)
    value = np.asarray(levels)[np.minimum((t / hold).astype(int), n_steps - 1)]
    return ReferenceProfile(mode, t, value)
