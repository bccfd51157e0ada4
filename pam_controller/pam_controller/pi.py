"""The PI law of MODEL.md section 7, antagonistic, with saturation and anti-windup (no ROS).

    e = reference - feedback
    v = Kp e + I,  I = the integral TERM (V), I <- I + Ki e dt
    u1 = beta + v,  u2 = beta - v,  each saturated to [u_min, u_max]

Storing the integral term I (V) rather than the integral of e means a run-time change of Ki
changes only future increments: the output does not jump. Anti-windup while saturated:
conditional integration (the integral is frozen while the output is saturated and the error
pushes further into saturation) or back-calculation (the integral is pulled back by
(v_sat - v) dt / T_t). dt comes from the feedback stamps; a dt <= 0 or > dt_max leaves the
state unchanged (the output is still computed). Units: e in rad (angle mode) or N m (torque
mode); Kp in V per unit of e, Ki in V per unit of e per second; u, v, I in V.

No intermediate term can become non-finite, whatever the (finite) gains and the error: e is
bounded to +-ERROR_LIMIT (a NaN error counts as 0), and the proportional term, each integral
increment and the integral term to +-TERM_LIMIT V, far beyond any saturation (the outputs span
10 V), so back-calculation never computes inf - inf and a huge error leaves a state that
recovers by itself. ControlLoop clamps the reference to the rig's envelope before this.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit

from pam_model.rest import BETA

ANTI_WINDUP = ('conditional', 'back_calculation')
ERROR_LIMIT = 1.0e6    # rad or N m: a larger error is taken as this (numerical bound only)
TERM_LIMIT = 1.0e6     # V: bound of the proportional term, an integral increment, the integral


class PiGains(NamedTuple):
    """Gains and limits of one mode."""

    kp: float              # V per rad (angle) or per N m (torque)
    ki: float              # V per rad s or per N m s
    beta: float = BETA     # V, bias of both valves
    u_min: float = 0.0     # V
    u_max: float = 10.0    # V


class PiOutput(NamedTuple):
    u1: float
    u2: float
    p_term: float
    i_term: float          # the integral term after this step (V)
    saturated: bool


@njit(cache=True)
def differential_limits(beta, u_min, u_max):
    """Range [v_lo, v_hi] of the differential v keeping both u1 = beta + v and u2 = beta - v
    inside [u_min, u_max]."""
    return max(u_min - beta, beta - u_max), min(u_max - beta, beta - u_min)


@njit(cache=True)
def bounded(x, limit):
    """x clamped to [-limit, limit]; NaN -> 0 (+-inf -> +-limit)."""
    if x > limit:
        return limit
    if x < -limit:
        return -limit
    if x != x:
        return 0.0
    return x


@njit(cache=True)
def pi_step(e, dt, i_term, kp, ki, beta, u_min, u_max, anti_windup, tracking_time, dt_max):
    """One PI step. Returns (u1, u2, p_term, i_term_new, saturated), all finite.

    anti_windup: 0 conditional integration, 1 back-calculation with time constant
    tracking_time (s). dt (s) outside (0, dt_max] freezes the integral. e is bounded to
    +-ERROR_LIMIT, the terms to +-TERM_LIMIT V (see the module docstring).
    """
    e = bounded(e, ERROR_LIMIT)
    i_term = bounded(i_term, TERM_LIMIT)
    p_term = bounded(kp * e, TERM_LIMIT)
    v = p_term + i_term
    v_lo, v_hi = differential_limits(beta, u_min, u_max)
    v_sat = min(max(v, v_lo), v_hi)
    saturated = v_sat != v
    if 0.0 < dt <= dt_max:
        if anti_windup == 0:
            pushing_further = (v > v_hi and e > 0.0) or (v < v_lo and e < 0.0)
            if not pushing_further:
                i_term = bounded(i_term + bounded(ki * e * dt, TERM_LIMIT), TERM_LIMIT)
        else:
            increment = (bounded(ki * e * dt, TERM_LIMIT)
                         + bounded((v_sat - v) / tracking_time * dt, TERM_LIMIT))
            i_term = bounded(i_term + increment, TERM_LIMIT)
    return beta + v_sat, beta - v_sat, p_term, i_term, saturated


class PiController:
    """A PI controller with state: step(e, dt) -> PiOutput. Gains change through set_gains()."""

    def __init__(self, gains: PiGains, anti_windup: str = 'conditional',
                 tracking_time: float = 0.1, dt_max: float = 0.1):
        if not 0.0 < dt_max < math.inf:
            raise ValueError(f'dt_max must be finite and > 0 s, got {dt_max!r}')
        self.dt_max = float(dt_max)
        self.i_term = 0.0
        self.set_gains(gains, anti_windup, tracking_time)

    def set_gains(self, gains: PiGains, anti_windup: str | None = None,
                  tracking_time: float | None = None) -> None:
        """New gains and limits, and (None: unchanged) anti-windup scheme and tracking time (s).

        Checked as __init__ checks them (validate_gains, check_anti_windup): a ValueError naming
        the bad field leaves everything unchanged. The integral term is kept, so the output does
        not jump (see the module docstring).
        """
        anti_windup = self.anti_windup if anti_windup is None else anti_windup
        tracking_time = self.tracking_time if tracking_time is None else tracking_time
        validate_gains(gains)
        check_anti_windup(anti_windup, tracking_time)
        self.gains = gains
        self.anti_windup = anti_windup
        self.tracking_time = float(tracking_time)

    def reset(self) -> None:
        self.i_term = 0.0

    def step(self, e: float, dt: float) -> PiOutput:
        g = self.gains
        u1, u2, p, i, sat = pi_step(float(e), float(dt), self.i_term, g.kp, g.ki, g.beta,
                                    g.u_min, g.u_max, ANTI_WINDUP.index(self.anti_windup),
                                    self.tracking_time, self.dt_max)
        self.i_term = i
        return PiOutput(u1, u2, p, i, bool(sat))


def check_anti_windup(anti_windup: str, tracking_time: float) -> None:
    """A known scheme (ANTI_WINDUP) and a finite tracking_time > 0 s; else a ValueError."""
    if anti_windup not in ANTI_WINDUP:
        raise ValueError(f'anti_windup must be one of {ANTI_WINDUP}, got {anti_windup!r}')
    if not 0.0 < tracking_time < math.inf:
        raise ValueError(f'tracking_time must be finite and > 0 s, got {tracking_time!r}')


def validate_gains(g: PiGains) -> PiGains:
    """Finite, non-negative gains; u_min <= beta <= u_max within [0, 10] V."""
    for name, value in g._asdict().items():
        if not math.isfinite(value):
            raise ValueError(f'{name} must be finite, got {value!r}')
    if g.kp < 0.0 or g.ki < 0.0:
        raise ValueError(f'gains must be >= 0, got kp={g.kp!r}, ki={g.ki!r}')
    if not 0.0 <= g.u_min < g.u_max <= 10.0:
        raise ValueError(f'need 0 <= u_min < u_max <= 10 V, got u_min={g.u_min!r}, '
                         f'u_max={g.u_max!r}')
    if not g.u_min <= g.beta <= g.u_max:
        raise ValueError(f'beta must lie in [u_min, u_max], got {g.beta!r}')
    return g
