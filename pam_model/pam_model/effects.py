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

Forms of a second plant family (the same physics by other laws; docs/realistic_rig.md cites
the literature each one follows); each off by default, each combinable with the ones above:

* valve transport delay (``valve_delay`` theta, s): the valve acts on the command of
  n = round(theta / h) samples before (the voltages held before the start fill the line).
* second-order valve spool (``valve_natural_frequency`` f_n, Hz; ``valve_damping`` zeta, -):
  instead of the first-order lag (refused together with ``valve_time_constant``),
  d^2u_f/dt^2 = omega^2 (u - u_f) - 2 zeta omega du_f/dt, omega = 2 pi f_n, integrated exactly
  over a step with u held (the matrix exponential of [u_f, du_f/dt, integral of u_f, u]); the
  opening held over step k is kappa(mean of u_f over the step), as for the lag.
* Bouc-Wen force hysteresis (``bouc_wen_band`` B_w, N at 500 kPa, SIGNED; ``bouc_wen_driver``
  'length' or 'pressure'; ``bouc_wen_length_travel`` delta_l, m; ``bouc_wen_pressure_travel``
  delta_P, Pa): per muscle F_bw,i = B_w c(P_i) z_i is added to F_i of eq. (6) (with the
  Maxwell-slip force if both are on), c(P) as for the Maxwell slip. z_i in (-1, 1) follows the
  rate-independent Bouc-Wen law with n = 1, A = 1, beta = gamma = 1/2 in the driver
  x_i = l_i / delta_l (length) or P_i / delta_P (pressure):
  dz = dx - (|dx| z + dx |z|) / 2, i.e. dz/dx = 1 while z opposes the motion (a reversal) and
  dz/dx = 1 - |z| while it follows it. Solved exactly over each sample's increment dx (linear
  up to z = 0, then z = sgn(dx) (1 - (1 - |z|) e^(-|dx|))). Orientation: B_w > 0 makes the
  force larger while the driver rises (length: while the muscle is stretched, as braid friction
  does); B_w < 0 the other way. Driven by the length, it is still in a locked run.
* finite supply tank with a compressor (``tank_volume`` V_t, m^3, 0 = the infinite tank of
  the paper; ``compressor_flow`` m_c, kg/s; ``compressor_band`` b, Pa): the tank's pressure
  P_t (isothermal, at the air temperature T(t)) empties into the valves and is refilled by a
  hysteretic on/off compressor: P_t[k+1] = P_t[k] + h (R T / V_t) (m_c on[k] - m_in[k]),
  m_in the valves' summed inflow of eq. (5) over step k; the compressor cuts in when P_t falls
  to P_tank0 - b and out when it reaches P_tank0 (it starts full, off). P_t replaces P_tank0
  in the supply line above (droop and ripple, if set, act on it).
* sensor filter order (``sensor_filter_order`` n, 1..4): the transducer filter is n cascaded
  first-order stages of ``sensor_time_constant`` each (n = 1: the filter above).

Not modelled: valve spool saturation and its rate limit, line flow resistance (the line is a pure
volume), heat exchange dynamics (T is imposed, not a state), pressure-dependent sensor noise.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np
from scipy.linalg import expm

from . import effects_physics
from .physics import gas_constants, muscle_lengths, valve_opening
from .valve_voltage import U_MAX, U_MIN

HYSTERESIS_PRESSURE = 5.0e5  # Pa abs, the pressure at which hysteresis_band is given
BOUC_WEN_DRIVERS = ('length', 'pressure')
#: Fields that shape an effect but switch nothing on (an effect is on by its magnitude).
SHAPE_FIELDS = ('hysteresis_elements', 'hysteresis_travel', 'temperature_drift_time',
                'bouc_wen_driver', 'bouc_wen_length_travel', 'bouc_wen_pressure_travel',
                'valve_damping', 'compressor_band', 'sensor_filter_order')
_INTEGER_FIELDS = {'hysteresis_elements': 32, 'sensor_filter_order': 4}    # key: largest value


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
    valve_delay: float = 0.0                   # s, transport delay (whole samples)
    valve_natural_frequency: float = 0.0       # Hz, second-order spool (0 = none)
    valve_damping: float = 0.7                 # -, its damping ratio
    bouc_wen_band: float = 0.0                 # N at 500 kPa abs, signed (orientation)
    bouc_wen_driver: str = 'length'            # 'length' or 'pressure'
    bouc_wen_length_travel: float = 1.0e-3     # m of muscle length per e-fold of z
    bouc_wen_pressure_travel: float = 2.0e4    # Pa of muscle pressure per e-fold of z
    tank_volume: float = 0.0                   # m^3 (0 = infinite tank, P_tank held)
    compressor_flow: float = 0.0               # kg/s while the compressor runs
    compressor_band: float = 5.0e4             # Pa, cut in at P_tank0 - band, out at P_tank0
    sensor_filter_order: int = 1               # first-order stages of sensor_time_constant

    def __post_init__(self):
        for name in ('valve_time_constant', 'dead_volume', 'supply_droop', 'supply_ripple',
                     'supply_ripple_frequency', 'hysteresis_band', 'sensor_time_constant',
                     'valve_delay', 'valve_natural_frequency', 'tank_volume',
                     'compressor_flow'):
            _require(name, getattr(self, name), lambda v: v >= 0.0, '>= 0')
        for name in ('hysteresis_travel', 'temperature_drift_time', 'valve_damping',
                     'bouc_wen_length_travel', 'bouc_wen_pressure_travel', 'compressor_band'):
            _require(name, getattr(self, name), lambda v: v > 0.0, '> 0')
        for name in ('temperature_drift', 'bouc_wen_band'):
            _require(name, getattr(self, name), lambda v: True, 'finite')
        for name, largest in _INTEGER_FIELDS.items():
            n = getattr(self, name)
            if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= largest:
                raise ValueError(f'{name}: must be an integer in 1..{largest}, got {n!r}')
        if self.bouc_wen_driver not in BOUC_WEN_DRIVERS:
            raise ValueError(f'bouc_wen_driver: must be one of {", ".join(BOUC_WEN_DRIVERS)}, '
                             f'got {self.bouc_wen_driver!r}')
        if self.valve_time_constant > 0.0 and self.valve_natural_frequency > 0.0:
            raise ValueError('valve_time_constant and valve_natural_frequency: one valve law '
                             '(first- or second-order), not both')
        if self.compressor_flow > 0.0 and self.tank_volume == 0.0:
            raise ValueError('compressor_flow: needs a finite tank (tank_volume > 0)')
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
        return self != Effects(**{name: getattr(self, name) for name in SHAPE_FIELDS})

    @property
    def supply_varies(self) -> bool:
        """True if P_tank is not the nominal constant (droop, ripple or a finite tank)."""
        return self.supply_droop > 0.0 or self.supply_ripple > 0.0 or self.tank_volume > 0.0

    def describe(self) -> str:
        """One line naming the effects that are on, with their values and units."""
        e = self
        parts = [(e.valve_time_constant, f'valve lag {e.valve_time_constant * 1e3:g} ms'),
                 (e.valve_natural_frequency, f'2nd-order valve {e.valve_natural_frequency:g} Hz '
                                             f'zeta {e.valve_damping:g}'),
                 (e.valve_delay, f'valve delay {e.valve_delay * 1e3:g} ms'),
                 (e.dead_volume, f'dead volume {e.dead_volume:g} m^3'),
                 (e.supply_droop, f'supply droop {e.supply_droop / 1e3:g} kPa'),
                 (e.supply_ripple, f'ripple +-{e.supply_ripple / 1e3:g} kPa at '
                                   f'{e.supply_ripple_frequency:g} Hz'),
                 (e.tank_volume, f'tank {e.tank_volume * 1e3:g} L, compressor '
                                 f'{e.compressor_flow * 1e3:g} g/s, band '
                                 f'{e.compressor_band / 1e3:g} kPa'),
                 (e.hysteresis_band, f'hysteresis +-{e.hysteresis_band:g} N at 500 kPa'),
                 (e.bouc_wen_band, f'Bouc-Wen {e.bouc_wen_band:+g} N at 500 kPa by '
                                   + (f'length ({e.bouc_wen_length_travel * 1e3:g} mm)'
                                      if e.bouc_wen_driver == 'length' else
                                      f'pressure ({e.bouc_wen_pressure_travel / 1e3:g} kPa)')),
                 (e.temperature_drift, f'T {e.temperature_drift:+g} K over '
                                       f'{e.temperature_drift_time:g} s'),
                 (any(e.sensor_offset), 'sensor offsets {:+g}/{:+g} kPa'.format(
                     *(o / 1e3 for o in e.sensor_offset))),
                 (any(e.sensor_gain_error), 'gains {:+g}/{:+g} %'.format(
                     *(g * 100 for g in e.sensor_gain_error))),
                 (e.sensor_time_constant, f'sensor filter {e.sensor_time_constant * 1e3:g} ms'
                                          + (f' x{e.sensor_filter_order}'
                                             if e.sensor_filter_order > 1 else ''))]
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
            elif key in _INTEGER_FIELDS:
                if isinstance(value, bool) or not isinstance(value, int):
                    raise ValueError(f'{key}: must be an integer in 1..{_INTEGER_FIELDS[key]}, '
                                     f'got {value!r}')
                values[key] = value
            elif key == 'bouc_wen_driver':
                values[key] = str(value)
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


def pressure_scale(P, p_out: float) -> np.ndarray:
    """c(P) = max(P - P_out, 0) / (500 kPa - P_out) (-) of the hysteresis bands, P in Pa abs (an
    array or a number): the compiled kernel effects_physics.band_scale element by element."""
    return np.vectorize(effects_physics.band_scale, otypes=[float])(
        np.asarray(P, dtype=float), p_out, HYSTERESIS_PRESSURE)


def sanitised_voltages(u) -> np.ndarray:
    """u (2,) V as a valve reads it: non-finite as U_MIN, clipped to [U_MIN, U_MAX]."""
    u = np.asarray(u, dtype=float)
    return np.clip(np.where(np.isfinite(u), u, U_MIN), U_MIN, U_MAX)


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
        return pressure_scale(P, self.p_out)

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
        self.u_filtered = sanitised_voltages(u0)

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


class BoucWen:
    """Bouc-Wen hysteresis of the module docstring for `count` muscles at once.

    band B_w (N at 500 kPa, signed), travel (the driver's unit per e-fold of z: m or Pa),
    p_out (Pa abs) for the pressure scale."""

    def __init__(self, band: float, travel: float, p_out: float, count: int = 2):
        self.band, self.travel, self.p_out = band, travel, p_out
        self.z = np.zeros(count)
        self.drive_before = None                 # (count,) -, set by the first input

    def update(self, drive, P) -> np.ndarray:
        """Move z with the driver's values drive (count,) (m or Pa) at pressures P (count,) Pa;
        the forces F_bw (count,) N. The first call starts z at 0 (no force). One compiled
        kernel (effects_physics.bouc_wen_update)."""
        x = np.asarray(drive, dtype=float) / self.travel
        if self.drive_before is None:
            self.drive_before = x.copy()
        force = np.empty(self.z.size)
        effects_physics.bouc_wen_update(x, self.drive_before, self.z, self.band,
                                        np.asarray(P, dtype=float), self.p_out,
                                        HYSTERESIS_PRESSURE, force)
        return force


def spool_transition(h: float, frequency: float, damping: float) -> np.ndarray:
    """The exact step (3, 3) of the second-order spool with u held over h (s): rows u_f (V),
    du_f/dt (V/s) and the mean of u_f over the step (V), columns u_f, du_f/dt, u; from the matrix
    exponential of [u_f, du_f/dt, integral of u_f, u] (frequency f_n in Hz, damping zeta)."""
    w = 2.0 * math.pi * frequency
    generator = np.array([[0.0, 1.0, 0.0, 0.0],
                          [-w * w, -2.0 * damping * w, 0.0, w * w],
                          [1.0, 0.0, 0.0, 0.0],
                          [0.0, 0.0, 0.0, 0.0]])
    E = expm(generator * h)
    return np.array([E[0, [0, 1, 3]], E[1, [0, 1, 3]], E[2, [0, 1, 3]] / h])


class SecondOrderValve:
    """The second-order valve spools of the module docstring for both valves (the plant's
    alternative to ValveLag, with the same interface).

    valve_map (kappa), h (s), frequency f_n (Hz), damping zeta (-), u0 (2,) V held before (the
    spools start at rest there)."""

    def __init__(self, valve_map, h: float, frequency: float, damping: float, u0):
        self.valve_map = valve_map
        self.transition = spool_transition(h, frequency, damping)
        self.state = np.zeros((2, 2))
        self.state[:, 0] = sanitised_voltages(u0)
        self._mean = np.empty(2)

    @property
    def u_filtered(self) -> np.ndarray:
        """The spools' positions u_f (2,) in V."""
        return self.state[:, 0].copy()

    def openings(self, u) -> tuple[float, float]:
        """Openings alpha over the coming step for the held (sanitised) voltages u (V) (kappa of
        each spool's mean over the step); advances the spools by one step."""
        vm = self.valve_map
        effects_physics.spool_second_order(float(u[0]), float(u[1]), self.state,
                                           self.transition, self._mean)
        return (valve_opening(self._mean[0], vm.u, vm.alpha),
                valve_opening(self._mean[1], vm.u, vm.alpha))


class CommandDelay:
    """The valves' transport delay: the command of `samples` steps before (u0, V, before the
    start)."""

    def __init__(self, samples: int, u0):
        start = tuple(float(v) for v in sanitised_voltages(u0))
        self.line = deque([start] * samples)

    def delayed(self, u) -> tuple[float, float]:
        """Push the command u (2,) V of this step; the one the valves act on."""
        self.line.append((float(u[0]), float(u[1])))
        return self.line.popleft()


class SupplyTank:
    """The finite supply tank and its compressor of the module docstring: pressure P_t (Pa
    abs), starting full (P_tank0) with the compressor off.

    P_tank0 (Pa abs), R (J/(kg K)), volume V_t (m^3), compressor flow m_c (kg/s), band b (Pa)."""

    def __init__(self, P_tank0: float, R: float, volume: float, flow: float, band: float):
        self.pressure, self.running = P_tank0, False
        self.R, self.volume, self.flow = R, volume, flow
        self.cut_in, self.cut_out = P_tank0 - band, P_tank0

    def draw(self, inflow: float, T: float, h: float) -> None:
        """One step of h (s) with the valves drawing inflow (kg/s) at air temperature T (K)."""
        self.pressure, self.running = effects_physics.tank_update(
            self.pressure, self.running, inflow, self.flow, h, self.R, T, self.volume,
            self.cut_in, self.cut_out)


class EffectsPlant:
    """The internal states of the effects (filtered valve voltages, hysteresis elements, sensor
    filters, the supply tank) and the step of a plant with effects; SimulatedRig and simulate()
    drive it."""

    def __init__(self, model, effects: Effects, x0, u0):
        self.model = model
        self.effects = effects
        p = model.params
        self.P_tank0, self.T0 = p.P_tank, p.T
        self.record = model.params_array.copy()
        gas = gas_constants(p)
        self.m_ref = (p.A1_1 + p.A1_2) * p.P_tank * gas.C_ch / gas.sqrt_T
        self.valve = (SecondOrderValve(model.valve_map, model.h, effects.valve_natural_frequency,
                                       effects.valve_damping, u0)
                      if effects.valve_natural_frequency > 0.0 else
                      ValveLag(model.valve_map, model.h, effects.valve_time_constant, u0))
        delay = round(effects.valve_delay / model.h)
        self.delay = CommandDelay(delay, u0) if delay > 0 else None
        self.tank = (SupplyTank(p.P_tank, p.R, effects.tank_volume, effects.compressor_flow,
                                effects.compressor_band)
                     if effects.tank_volume > 0.0 else None)
        self.sensor_decay = lag_factor(model.h, effects.sensor_time_constant)
        self.gain = 1.0 + np.asarray(effects.sensor_gain_error)
        self.offset = np.asarray(effects.sensor_offset)
        self.hysteresis = (MaxwellSlip(effects.hysteresis_band, effects.hysteresis_elements,
                                       effects.hysteresis_travel, p.P_out)
                           if effects.hysteresis_band > 0.0 else None)
        self.bouc_wen = (BoucWen(effects.bouc_wen_band,
                                 effects.bouc_wen_length_travel
                                 if effects.bouc_wen_driver == 'length' else
                                 effects.bouc_wen_pressure_travel, p.P_out)
                         if effects.bouc_wen_band != 0.0 else None)
        self.F_h = np.zeros(2)
        x0 = np.asarray(x0, dtype=float)
        self.P_stages = [x0[2:].copy() for _ in range(effects.sensor_filter_order)]
        self._update_hysteresis(x0)
        self._x_next = np.empty(4)

    def temperature(self, t: float) -> float:
        """T(t) (K)."""
        e = self.effects
        return self.T0 + e.temperature_drift * min(t / e.temperature_drift_time, 1.0)

    def tank_pressure(self, t: float, P, alpha, T: float) -> float:
        """P_tank(t) (Pa abs) over a step from pressures P (2,) with openings alpha (2,): the
        tank's (P_tank0 unless it is finite), drooped and rippled."""
        e = self.effects
        P_tank = self.P_tank0 if self.tank is None else self.tank.pressure
        if e.supply_droop > 0.0:
            self.record['P_tank'], self.record['T'] = P_tank, T
            inflow = effects_physics.supply_inflow(P[0], P[1], alpha[0], alpha[1], self.record)
            P_tank -= e.supply_droop * inflow / self.m_ref
        if e.supply_ripple > 0.0:
            P_tank += e.supply_ripple * math.sin(2.0 * math.pi * e.supply_ripple_frequency * t)
        return P_tank

    @property
    def u_filtered(self) -> np.ndarray:
        """The valves' lagged voltages (spool positions) u_f (V)."""
        return self.valve.u_filtered

    @property
    def P_filtered(self) -> np.ndarray:
        """The transducers' filtered pressures (Pa abs): the last filter stage."""
        return self.P_stages[-1]

    def openings(self, u) -> tuple[float, float]:
        """Openings over the coming step for the held (sanitised) voltages u (V); advances the
        transport delay and the valve spools by one step."""
        if self.delay is not None:
            u = self.delay.delayed(u)
        return self.valve.openings(u)

    def step(self, x, u, t: float):
        """x (4,) at time t (s) -> (x_next (4,), T_f N m, sigma) with voltages u (V) held."""
        model = self.model
        alpha = self.openings(u)
        T = self.temperature(t)
        P_tank = self.tank_pressure(t, x[2:], alpha, T)
        self.record['P_tank'], self.record['T'] = P_tank, T
        if self.tank is not None:
            self.tank.draw(effects_physics.supply_inflow(x[2], x[3], alpha[0], alpha[1],
                                                         self.record), T, model.h)
        T_f, sigma = effects_physics.step_with_effects(
            x, alpha[0], alpha[1], model.h, self.record, model.friction_code, model.force_code,
            model.locked, self.effects.dead_volume, self.F_h[0], self.F_h[1], self._x_next)
        x_next = self._x_next.copy()
        self._update_hysteresis(x_next)
        self.filter_pressures(x_next[2:])
        return x_next, T_f, sigma

    def filter_pressures(self, P) -> None:
        """One sample of the transducers' filters (n first-order stages in cascade) with true
        pressures P (2,) Pa."""
        for j, stage in enumerate(self.P_stages):
            P = P + (stage - P) * self.sensor_decay
            self.P_stages[j] = P

    def _update_hysteresis(self, x) -> None:
        if self.hysteresis is not None:
            F1, F2, _ = self.model.outputs_at(x)
            self.F_h = self.hysteresis.update((F1, F2), x[2:])
        if self.bouc_wen is not None:
            drive = (muscle_lengths.py_func(float(x[0]), self.model.params)
                     if self.effects.bouc_wen_driver == 'length' else x[2:])
            F_bw = self.bouc_wen.update(drive, x[2:])
            self.F_h = F_bw if self.hysteresis is None else self.F_h + F_bw

    def outputs(self, x):
        """(F1 N, F2 N, tau N m) of eq. (6)-(8) with the hysteresis forces."""
        F1, F2, _ = self.model.outputs_at(x)
        F1, F2 = F1 + self.F_h[0], F2 + self.F_h[1]
        return F1, F2, self.model.params.r * math.cos(x[0]) * (F1 - F2)

    def sensed_pressures(self) -> np.ndarray:
        """What the transducers put out before noise and ADC (Pa abs): (1 + g) P_f + o."""
        return self.gain * self.P_filtered + self.offset
