"""Unmodelled effects of a real rig, for the simulated plant only: each one off by
default, set in the `effects:` section of a mismatch scenario YAML. SI units; pressures absolute.

The paper's model (MODEL.md, ``physics.py``) stays the default path: with every effect off the
plant steps through ``physics.step_array`` exactly as before. With any effect on, the plant steps
through :class:`EffectsPlant` (numpy per sample around the numba step of ``effects_physics``).
The equations, t = k h the time of sample k, h the step (s):

* valve spool (``valve_time_constant`` tau_v, s): the commanded voltage u goes through a
  first-order lag before the valve map, du_f/dt = (u - u_f) / tau_v, exact over a step with u
  held: u_f[k+1] = u + (u_f[k] - u) e^(-h/tau_v); the opening held over step k is
  alpha = kappa(mean of u_f over the step) = kappa(u + (u_f[k] - u) (tau_v/h)(1 - e^(-h/tau_v))).
  Changes the input alpha of eq. (5).
* air line (``dead_volume`` V_d, m^3 per muscle): eq. (4) becomes
  dP_i/dt = k1 R T m_i / (V_i + V_d) - k2 (V_dot_i / (V_i + V_d)) P_i (V_dot of the muscle alone).
* supply (``supply_droop`` D, Pa; ``supply_ripple`` a, Pa; ``supply_ripple_frequency`` f, Hz):
  P_tank(t) = P_tank0 - D (m_in,1 + m_in,2) / m_ref + a sin(2 pi f t), held over each step, with
  m_in,i = alpha_i A1_i m_in~(P_i) the inflow of eq. (5) at the start of the step (nominal tank)
  and m_ref = (A1_1 + A1_2) P_tank0 C_ch / sqrt(T) the choked inflow of both valves fully open.
  Linear in the summed INFLOW, not the summed openings: a regulator droops with the flow it
  delivers, so a valve held open on a muscle already at tank pressure draws nothing and the tank
  recovers; the droop is D exactly at both valves fully open on muscles below c* P_tank (choked).
  Changes P_tank in eq. (5) (the orifice equations).
* force hysteresis (``hysteresis_band`` B, N at 500 kPa; ``hysteresis_elements`` n;
  ``hysteresis_travel`` Delta, N): a Maxwell-slip operator per muscle added to eq. (6):
  F_i = v(l_i) P_i + w(l_i) + F_h,i, F_h,i = sum_j f_ij, driven by the nominal force
  s_i = v(l_i) P_i + w(l_i) (it moves with the pressure in locked runs and with the length in free
  ones). Element j (1..n): slip force b_j = (B/n) c(P_i), stiffness k_j = (B/n) / (j Delta/n)
  (N/N), f_ij = clip(k_j (s_i - z_ij), -b_j, b_j), its anchor z_ij moved so that the clip holds.
  c(P) = max(P - P_out, 0) / (500 kPa - P_out): the band scales with the gauge pressure, as
  braid-on-bladder friction scales with the contact pressure (c = 1 at 500 kPa abs, 0 vented).
  Rate independent (it depends on the path of s only). Once s has reversed by 2 Delta the loop
  is fully open: its width is 2 B at 500 kPa (Delta = 5 N by default: 2 Delta is about 70 kPa of
  pressure at L0, where dF/dP = 1.45e-4 N/Pa, so the loops of a 200-700 kPa profile are open).
  Updated at each sample, held over the step; it enters eq. (8) and the friction law's F1 + F2
  (eq. 10).
* air temperature (``temperature_drift`` dT, K; ``temperature_drift_time`` t_d, s):
  T(t) = T0 + dT min(t / t_d, 1), linear, then held: T in eq. (4) and in the orifice flows.
* pressure sensors (``sensor_offset`` [o1, o2] Pa; ``sensor_gain_error`` [g1, g2], fraction;
  ``sensor_time_constant`` tau_s, s): P_f,i[k] = P_i[k] + (P_f,i[k-1] - P_i[k]) e^(-h/tau_s),
  reading_i = ADC((1 + g_i) P_f,i + o_i + noise); noise and ADC as before (sensor.py).

Not modelled: valve spool saturation and its rate limit, line flow resistance (the line is a pure
volume), heat exchange dynamics (T is imposed, not a state), pressure-dependent sensor noise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from . import effects_physics
from .physics import gas_constants, valve_opening
from .valve_voltage import U_MAX, U_MIN

HYSTERESIS_PRESSURE = 5.0e5  # Pa abs, the pressure at which hysteresis_band is given


@dataclass(frozen=True)
class Effects:
    """The effects of the module docstring; every default is "off"."""

    valve_time_constant: float = 0.0           # s
    dead_volume: float = 0.0                   # m^3 per muscle
    supply_droop: float = 0.0                  # Pa at both valves fully open (choked inflow)
    supply_ripple: float = 0.0                 # Pa amplitude
    supply_ripple_frequency: float = 0.0       # Hz
    hysteresis_band: float = 0.0               # N (half-width of the loop) at 500 kPa abs
    hysteresis_elements: int = 4               # Maxwell-slip elements per muscle
    hysteresis_travel: float = 5.0             # N of nominal force until the loop is fully open
    temperature_drift: float = 0.0             # K
    temperature_drift_time: float = 130.0      # s, over which the drift is reached
    sensor_offset: tuple = (0.0, 0.0)          # Pa, P1 and P2 sensors
    sensor_gain_error: tuple = (0.0, 0.0)      # -, fraction (0.005 = +0.5 %)
    sensor_time_constant: float = 0.0          # s

    def __post_init__(self):
        for name in ('valve_time_constant', 'dead_volume', 'supply_droop', 'supply_ripple',
                     'supply_ripple_frequency', 'hysteresis_band', 'sensor_time_constant'):
            _require(name, getattr(self, name), lambda v: v >= 0.0, '>= 0')
        _require('hysteresis_travel', self.hysteresis_travel, lambda v: v > 0.0, '> 0')
        _require('temperature_drift', self.temperature_drift, lambda v: True, 'finite')
        _require('temperature_drift_time', self.temperature_drift_time, lambda v: v > 0.0, '> 0')
        n = self.hysteresis_elements
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 32:
            raise ValueError(f'hysteresis_elements: must be an integer in 1..32, got {n!r}')
        for name, ok, text in (('sensor_offset', lambda v: True, 'finite'),
                               ('sensor_gain_error', lambda v: v > -1.0, '> -1')):
            pair = getattr(self, name)
            if not (isinstance(pair, (tuple, list)) and len(pair) == 2):
                raise ValueError(f'{name}: must be a pair [P1, P2], got {pair!r}')
            for value in pair:
                _require(name, value, ok, text)
            object.__setattr__(self, name, (float(pair[0]), float(pair[1])))

    @property
    def active(self) -> bool:
        """True if any effect is on (the plant then steps through EffectsPlant)."""
        return self != Effects(hysteresis_elements=self.hysteresis_elements,
                               hysteresis_travel=self.hysteresis_travel,
                               temperature_drift_time=self.temperature_drift_time)

    def describe(self) -> str:
        """One line naming the effects that are on, with their values and units."""
        e = self
        parts = [(e.valve_time_constant, f'valve lag {e.valve_time_constant * 1e3:g} ms'),
                 (e.dead_volume, f'dead volume {e.dead_volume:g} m^3'),
                 (e.supply_droop, f'supply droop {e.supply_droop / 1e3:g} kPa'),
                 (e.supply_ripple, f'ripple +-{e.supply_ripple / 1e3:g} kPa at '
                                   f'{e.supply_ripple_frequency:g} Hz'),
                 (e.hysteresis_band, f'hysteresis +-{e.hysteresis_band:g} N at 500 kPa'),
                 (e.temperature_drift, f'T {e.temperature_drift:+g} K over '
                                       f'{e.temperature_drift_time:g} s'),
                 (any(e.sensor_offset), 'sensor offsets {:+g}/{:+g} kPa'.format(
                     *(o / 1e3 for o in e.sensor_offset))),
                 (any(e.sensor_gain_error), 'gains {:+g}/{:+g} %'.format(
                     *(g * 100 for g in e.sensor_gain_error))),
                 (e.sensor_time_constant, f'sensor filter {e.sensor_time_constant * 1e3:g} ms')]
        return ', '.join(text for on, text in parts if on) or 'none'

    @classmethod
    def from_dict(cls, data: Mapping) -> Effects:
        """From the `effects` section of a scenario YAML; ValueError naming the key."""
        if not isinstance(data, Mapping):
            raise ValueError(f'must be a mapping, got {type(data).__name__}')
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(map(str, data)) - known)
        if unknown:
            raise ValueError(f'unknown key {unknown[0]!r} (known: {", ".join(sorted(known))})')
        values = {}
        for key, value in data.items():
            if key in ('sensor_offset', 'sensor_gain_error'):
                if not (isinstance(value, (list, tuple)) and len(value) == 2):
                    raise ValueError(f'{key}: must be a pair [P1, P2], got {value!r}')
                values[key] = tuple(_number(key, v) for v in value)
            elif key == 'hysteresis_elements':
                if isinstance(value, bool) or not isinstance(value, int):
                    raise ValueError(f'{key}: must be an integer in 1..32, got {value!r}')
                values[key] = value
            else:
                values[key] = _number(key, value)
        return cls(**values)


def _number(key, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ValueError(f'{key}: expected a number, got {value!r}')
    try:
        return float(value)
    except ValueError:
        raise ValueError(f'{key}: expected a number, got {value!r}') from None


def _require(name, value, ok, text):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and ok(value)):
        raise ValueError(f'{name}: must be {text}, got {value!r}')


NO_EFFECTS = Effects()


def lag_factor(h: float, tau: float) -> float:
    """e^(-h/tau) of a first-order lag sampled at h (s); 0 for tau = 0 (no lag)."""
    return math.exp(-h / tau) if tau > 0.0 else 0.0


class MaxwellSlip:
    """Maxwell-slip hysteresis of the module docstring for `count` muscles at once.

    band (N at 500 kPa), n elements, travel Delta (N), p_out (Pa abs) for the pressure scale.
    """

    def __init__(self, band: float, n: int, travel: float, p_out: float, count: int = 2):
        j = np.arange(1, n + 1, dtype=float)
        self.slip = np.full(n, band / n)                    # N at 500 kPa
        self.stiffness = self.slip / (j * travel / n)       # N/N
        self.p_out = p_out
        self.anchor = None                                  # (count, n), set by the first input
        self.count = count

    def pressure_scale(self, P) -> np.ndarray:
        """c(P) = max(P - P_out, 0) / (500 kPa - P_out)."""
        return np.maximum(np.asarray(P, dtype=float) - self.p_out, 0.0) / (
            HYSTERESIS_PRESSURE - self.p_out)

    def update(self, s, P) -> np.ndarray:
        """Move every element with inputs s (count,) N at pressures P (count,) Pa; the forces
        F_h (count,) N. The first call starts every element relaxed (F_h = 0). One compiled
        kernel (effects_physics.maxwell_slip_update): the 1 kHz path of the simulated rig and
        of the UKF calls it every sample."""
        s = np.asarray(s, dtype=float).reshape(self.count)
        if self.anchor is None:
            self.anchor = np.repeat(s.reshape(self.count, 1), self.slip.size, axis=1)
        force = np.empty(self.count)
        effects_physics.maxwell_slip_update(s, np.asarray(P, dtype=float), self.slip,
                                            self.stiffness, self.p_out, HYSTERESIS_PRESSURE,
                                            self.anchor, force)
        return force


class ValveLag:
    """The valve spool's first-order lag of the module docstring for both valves: the plant's
    (EffectsPlant) and the estimator's model (pam_estimator.pam_ukf, which knows the commands).

    valve_map (kappa), h (s), tau (s, 0 = no lag), u0 (2,) V the voltages held before."""

    def __init__(self, valve_map, h: float, tau: float, u0):
        self.valve_map = valve_map
        self.decay = lag_factor(h, tau)
        self.mean_weight = (tau / h * (1.0 - self.decay)) if tau > 0.0 else 0.0
        self.u_filtered = np.clip(np.nan_to_num(np.asarray(u0, dtype=float), nan=U_MIN),
                                  U_MIN, U_MAX)

    def openings(self, u) -> tuple[float, float]:
        """Openings alpha (2,) over the coming step for the held (sanitised) voltages u (V);
        advances the lag by one step. Plain floats: two numbers per valve, no array needed."""
        vm = self.valve_map
        u0, u1 = float(u[0]), float(u[1])
        f0, f1 = float(self.u_filtered[0]), float(self.u_filtered[1])
        mean0 = u0 + (f0 - u0) * self.mean_weight
        mean1 = u1 + (f1 - u1) * self.mean_weight
        self.u_filtered = np.array((u0 + (f0 - u0) * self.decay, u1 + (f1 - u1) * self.decay))
        return (valve_opening(mean0, vm.u, vm.alpha), valve_opening(mean1, vm.u, vm.alpha))


class EffectsPlant:
    """The internal states of the effects (filtered valve voltages, hysteresis elements, sensor
    filters) and the step of a plant with effects; SimulatedRig and simulate() drive it."""

    def __init__(self, model, effects: Effects, x0, u0):
        self.model = model
        self.effects = effects
        p = model.params
        self.P_tank0, self.T0 = p.P_tank, p.T
        self.record = model.params_array.copy()
        gas = gas_constants(p)
        self.m_ref = (p.A1_1 + p.A1_2) * p.P_tank * gas.C_ch / gas.sqrt_T
        self.valve = ValveLag(model.valve_map, model.h, effects.valve_time_constant, u0)
        self.sensor_decay = lag_factor(model.h, effects.sensor_time_constant)
        self.gain = 1.0 + np.asarray(effects.sensor_gain_error)
        self.offset = np.asarray(effects.sensor_offset)
        self.hysteresis = (MaxwellSlip(effects.hysteresis_band, effects.hysteresis_elements,
                                       effects.hysteresis_travel, p.P_out)
                           if effects.hysteresis_band > 0.0 else None)
        self.F_h = np.zeros(2)
        x0 = np.asarray(x0, dtype=float)
        self.P_filtered = x0[2:].copy()
        self._update_hysteresis(x0)
        self._x_next = np.empty(4)

    def temperature(self, t: float) -> float:
        """T(t) (K)."""
        e = self.effects
        return self.T0 + e.temperature_drift * min(t / e.temperature_drift_time, 1.0)

    def tank_pressure(self, t: float, P, alpha, T: float) -> float:
        """P_tank(t) (Pa abs) over a step from pressures P (2,) with openings alpha (2,)."""
        e = self.effects
        P_tank = self.P_tank0
        if e.supply_droop > 0.0:
            self.record['P_tank'], self.record['T'] = self.P_tank0, T
            inflow = effects_physics.supply_inflow(P[0], P[1], alpha[0], alpha[1], self.record)
            P_tank -= e.supply_droop * inflow / self.m_ref
        if e.supply_ripple > 0.0:
            P_tank += e.supply_ripple * math.sin(2.0 * math.pi * e.supply_ripple_frequency * t)
        return P_tank

    @property
    def u_filtered(self) -> np.ndarray:
        """The valves' lagged voltages u_f (V)."""
        return self.valve.u_filtered

    def openings(self, u) -> tuple[float, float]:
        """Openings over the coming step for the held (sanitised) voltages u (V); advances the
        valve lag by one step."""
        return self.valve.openings(u)

    def step(self, x, u, t: float):
        """x (4,) at time t (s) -> (x_next (4,), T_f N m, sigma) with voltages u (V) held."""
        model = self.model
        alpha = self.openings(u)
        T = self.temperature(t)
        P_tank = self.tank_pressure(t, x[2:], alpha, T)
        self.record['P_tank'], self.record['T'] = P_tank, T
        T_f, sigma = effects_physics.step_with_effects(
            x, alpha[0], alpha[1], model.h, self.record, model.friction_code, model.force_code,
            model.locked, self.effects.dead_volume, self.F_h[0], self.F_h[1], self._x_next)
        x_next = self._x_next.copy()
        self._update_hysteresis(x_next)
        self.filter_pressures(x_next[2:])
        return x_next, T_f, sigma

    def filter_pressures(self, P) -> None:
        """One sample of the transducers' first-order filters with true pressures P (2,) Pa."""
        self.P_filtered = P + (self.P_filtered - P) * self.sensor_decay

    def _update_hysteresis(self, x) -> None:
        if self.hysteresis is None:
            return
        F1, F2, _ = self.model.outputs(x)
        self.F_h = self.hysteresis.update((float(F1), float(F2)), x[2:])

    def outputs(self, x):
        """(F1 N, F2 N, tau N m) of eq. (6)-(8) with the hysteresis forces."""
        F1, F2, _ = self.model.outputs(x)
        F1, F2 = float(F1) + self.F_h[0], float(F2) + self.F_h[1]
        return F1, F2, self.model.params.r * math.cos(x[0]) * (F1 - F2)

    def sensed_pressures(self) -> np.ndarray:
        """What the transducers put out before noise and ADC (Pa abs): (1 + g) P_f + o."""
        return self.gain * self.P_filtered + self.offset
