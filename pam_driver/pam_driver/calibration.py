"""Calibration of the DAQ board: raw counts <-> SI units, loaded from YAML and validated at load.

No ROS in here. Chains (see config/driver_calibration.yaml for the file layout):

    pressure  ADC counts -> V = counts * adc_vref / (2^adc_bits - 1)
              -> gauge Pa = (V - zero_volts) * pascal_per_volt -> absolute Pa = gauge + atmosphere
              (channels p1, p2 and, optional, supply: the supply line's transducer, PROTOCOL.md
              1.1; a file without a pressure.supply section loads as before, has_supply False)
    encoder   counts -> rad = sign * (counts - zero_counts) * 2 pi / counts_per_rev
    torque    ADC counts -> V (same ADC) -> N m = (V - zero_volts) * newton_metre_per_volt
    valve     V <-> DAC counts, linear between volts_at_zero (0 counts) and volts_at_full_scale
              (2^dac_bits - 1 counts)

Every error raises CalibrationError naming the file and the key, e.g.
"driver_calibration.yaml: key 'pressure.p1.pascal_per_volt': must be > 0, got -1".
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

FORMAT_VERSION = 1
SUPPLY = 2      # the channel index of the supply transducer (P1 0, P2 1), when calibrated


class CalibrationError(ValueError):
    """The calibration file is missing, unreadable or has a bad value (message names the key)."""


@dataclass(frozen=True)
class PressureChannel:
    zero_volts: float
    pascal_per_volt: float
    valid_volts: tuple       # (min, max): readings outside are a sensor fault


@dataclass(frozen=True)
class Calibration:
    source: str
    adc_bits: int
    adc_vref: float
    atmosphere: float                 # Pa
    channels: tuple                   # (PressureChannel p1, p2[, supply]): index 0, 1, SUPPLY
    encoder_counts_per_rev: float
    encoder_zero_counts: int
    encoder_sign: int
    torque_zero_volts: float
    torque_nm_per_volt: float
    dac_bits: int
    valve_volts_at_zero: float
    valve_volts_at_full_scale: float

    # ---- ADC ---------------------------------------------------------------------------------
    @property
    def adc_full_scale(self) -> int:
        return (1 << self.adc_bits) - 1

    @property
    def dac_full_scale(self) -> int:
        return (1 << self.dac_bits) - 1

    def adc_volts(self, counts: int) -> float:
        return counts * self.adc_vref / self.adc_full_scale

    def adc_counts(self, volts: float) -> int:
        return min(max(round(volts / self.adc_vref * self.adc_full_scale), 0), self.adc_full_scale)

    # ---- pressure ----------------------------------------------------------------------------
    @property
    def has_supply(self) -> bool:
        """The file calibrates the supply transducer (channel SUPPLY)."""
        return len(self.channels) > SUPPLY

    def pressure_volts(self, channel: int, pressure_abs: float) -> float:
        ch = self.channels[channel]
        return ch.zero_volts + (pressure_abs - self.atmosphere) / ch.pascal_per_volt

    def pressure(self, channel: int, counts: int) -> float:
        """Absolute pressure (Pa) of channel 0 (P1), 1 (P2) or SUPPLY from ADC counts."""
        ch = self.channels[channel]
        return (self.adc_volts(counts) - ch.zero_volts) * ch.pascal_per_volt + self.atmosphere

    def pressure_counts(self, channel: int, pressure_abs: float) -> int:
        return self.adc_counts(self.pressure_volts(channel, pressure_abs))

    def pressure_resolution(self, channel: int) -> float:
        """Pa per ADC count."""
        return self.adc_vref / self.adc_full_scale * self.channels[channel].pascal_per_volt

    def pressure_volts_valid(self, channel: int, counts: int) -> bool:
        low, high = self.channels[channel].valid_volts
        return low <= self.adc_volts(counts) <= high

    # ---- encoder and torque ------------------------------------------------------------------
    def angle(self, counts: int) -> float:
        return (self.encoder_sign * (counts - self.encoder_zero_counts) * 2.0 * math.pi
                / self.encoder_counts_per_rev)

    def encoder_counts(self, angle: float) -> int:
        return (round(self.encoder_sign * angle * self.encoder_counts_per_rev / (2.0 * math.pi))
                + self.encoder_zero_counts)

    @property
    def angle_resolution(self) -> float:
        return 2.0 * math.pi / self.encoder_counts_per_rev

    def torque(self, counts: int) -> float:
        return (self.adc_volts(counts) - self.torque_zero_volts) * self.torque_nm_per_volt

    def torque_counts(self, torque: float) -> int:
        return self.adc_counts(self.torque_zero_volts + torque / self.torque_nm_per_volt)

    @property
    def torque_resolution(self) -> float:
        return self.adc_vref / self.adc_full_scale * abs(self.torque_nm_per_volt)

    # ---- valves ------------------------------------------------------------------------------
    def dac_counts(self, volts: float) -> int:
        span = self.valve_volts_at_full_scale - self.valve_volts_at_zero
        counts = round((volts - self.valve_volts_at_zero) / span * self.dac_full_scale)
        return min(max(counts, 0), self.dac_full_scale)

    def valve_volts(self, counts: int) -> float:
        span = self.valve_volts_at_full_scale - self.valve_volts_at_zero
        return self.valve_volts_at_zero + counts * span / self.dac_full_scale


# ---- loading -----------------------------------------------------------------------------------
class _Reader:
    def __init__(self, source: str, data: Mapping):
        self.source = source
        self.data = data

    def fail(self, key: str, message: str):
        raise CalibrationError(f"{self.source}: key '{key}': {message}")

    def get(self, key: str) -> Any:
        node: Any = self.data
        for part in key.split('.'):
            if not isinstance(node, Mapping) or part not in node:
                self.fail(key, 'missing')
            node = node[part]
        return node

    def number(self, key: str, low=None, high=None, positive=False, nonzero=False) -> float:
        value = self.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f'expected a number, got {value!r}')
        value = float(value)
        if not math.isfinite(value):
            self.fail(key, f'must be finite, got {value!r}')
        if positive and value <= 0.0:
            self.fail(key, f'must be > 0, got {value:g}')
        if nonzero and value == 0.0:
            self.fail(key, 'must not be 0')
        if (low is not None and value < low) or (high is not None and value > high):
            self.fail(key, f'{value:g} is out of range [{low}, {high}]')
        return value

    def integer(self, key: str, low: int, high: int) -> int:
        value = self.get(key)
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f'expected an integer, got {value!r}')
        if not low <= value <= high:
            self.fail(key, f'{value} is out of range [{low}, {high}]')
        return value


def from_mapping(data: Any, source: str = '<mapping>') -> Calibration:
    """A validated Calibration from the parsed YAML mapping."""
    if not isinstance(data, Mapping):
        raise CalibrationError(f'{source}: expected a mapping at the top level, got '
                               f'{type(data).__name__}')
    r = _Reader(source, data)
    version = r.integer('format_version', 0, 1000)
    if version != FORMAT_VERSION:
        r.fail('format_version', f'unsupported version {version}; this driver reads '
                                 f'{FORMAT_VERSION}')
    adc_bits = r.integer('adc.bits', 8, 24)
    vref = r.number('adc.vref_volts', positive=True)
    atmosphere = r.number('pressure.atmosphere_pa', 50e3, 120e3)
    channels = []
    pressure = r.get('pressure')
    optional = ('supply',) if isinstance(pressure, Mapping) and 'supply' in pressure else ()
    for name in ('p1', 'p2', *optional):
        key = f'pressure.{name}'
        zero = r.number(f'{key}.zero_volts', 0.0, vref)
        gain = r.number(f'{key}.pascal_per_volt', positive=True)
        valid = r.get(f'{key}.valid_volts')
        if (not isinstance(valid, (list, tuple)) or len(valid) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                           and math.isfinite(v) for v in valid)):
            r.fail(f'{key}.valid_volts', f'expected [min, max] in V, got {valid!r}')
        if not 0.0 <= valid[0] < valid[1] <= vref:
            r.fail(f'{key}.valid_volts', f'need 0 <= min < max <= adc.vref_volts ({vref:g}), '
                                         f'got {list(valid)}')
        channels.append(PressureChannel(zero, gain, (float(valid[0]), float(valid[1]))))
    cpr = r.number('encoder.counts_per_rev', positive=True)
    zero_counts = r.integer('encoder.zero_counts', -(1 << 31), (1 << 31) - 1)
    sign = r.integer('encoder.sign', -1, 1)
    if sign == 0:
        r.fail('encoder.sign', 'must be +1 or -1')
    t_zero = r.number('torque.zero_volts', 0.0, vref)
    t_gain = r.number('torque.newton_metre_per_volt', nonzero=True)
    dac_bits = r.integer('valve.dac_bits', 8, 16)
    v0 = r.number('valve.volts_at_zero')
    v1 = r.number('valve.volts_at_full_scale')
    if v1 <= v0:
        r.fail('valve.volts_at_full_scale', f'must be > valve.volts_at_zero ({v0:g}), got {v1:g}')
    if v0 > 0.0 or v1 < 10.0:
        r.fail('valve.volts_at_full_scale', f'the DAC must span the valve range 0-10 V, spans '
                                            f'[{v0:g}, {v1:g}] V')
    return Calibration(source=source, adc_bits=adc_bits, adc_vref=vref, atmosphere=atmosphere,
                       channels=tuple(channels), encoder_counts_per_rev=cpr,
                       encoder_zero_counts=zero_counts, encoder_sign=sign,
                       torque_zero_volts=t_zero, torque_nm_per_volt=t_gain, dac_bits=dac_bits,
                       valve_volts_at_zero=v0, valve_volts_at_full_scale=v1)


def default_path() -> Path:
    """The calibration shipped with the package (installed share/, else the source tree)."""
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('pam_driver'))
        path = share / 'config' / 'driver_calibration.yaml'
        if path.exists():
            return path
    except Exception:  # noqa: BLE001 - no ament index: fall back to the source tree
        pass
    for path in (Path(sys.prefix) / 'share' / 'pam_driver' / 'config' / 'driver_calibration.yaml',
                 Path(__file__).resolve().parent.parent / 'config' / 'driver_calibration.yaml'):
        if path.exists():
            return path
    return path


def load(path: str | Path | None = None) -> Calibration:
    """Load and validate a calibration file ('' or None or 'default': the shipped one)."""
    path = default_path() if path in (None, '', 'default') else Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise CalibrationError(f'{path}: cannot read: {exc.strerror or exc}') from exc
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise CalibrationError(f'{path}: invalid YAML: {exc}') from exc
    return from_mapping(data, str(path))
