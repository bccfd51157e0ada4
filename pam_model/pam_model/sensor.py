"""Pressure sensor model: additive white Gaussian noise, then an ADC's quantisation and range."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, vectorize


@vectorize(['float64(float64, float64, float64, float64)'], cache=True)
def adc_reading(P, resolution, range_min, range_max):
    """What an ADC reports for pressure P (Pa): clipped to [range_min, range_max] and rounded to
    a multiple of resolution (Pa) above range_min (resolution 0: no rounding). A ufunc, so it
    serves arrays from numpy and scalars inside compiled loops alike."""
    reading = min(max(P, range_min), range_max)
    if resolution > 0.0:
        reading = range_min + np.round((reading - range_min) / resolution) * resolution
    return reading


@njit(cache=True)
def adc_readings(P, resolution, range_min, range_max):
    """adc_reading of every pressure of the 1-D array P (Pa), in one compiled call (the ufunc's
    dispatch from Python costs more than the readings of a sample)."""
    out = np.empty_like(P)
    for i in range(P.size):
        out[i] = adc_reading(P[i], resolution, range_min, range_max)
    return out


@dataclass(frozen=True)
class PressureSensor:
    """noise_std (Pa) of white noise; an ADC of `bits` bits over [range_min, range_max] (Pa abs).

    bits = 0 means no quantisation (the reading is only clipped to the range).
    """

    noise_std: float = 0.0
    bits: int = 0
    range_min: float = 0.0
    range_max: float = 1.0e6

    def __post_init__(self):
        if not (math.isfinite(self.noise_std) and self.noise_std >= 0.0):
            raise ValueError(f'pressure noise std must be >= 0 Pa, got {self.noise_std!r}')
        if not (isinstance(self.bits, int) and 0 <= self.bits <= 32):
            raise ValueError(f'quantisation bits must be an integer in 0..32, got {self.bits!r}')
        if not (math.isfinite(self.range_min) and math.isfinite(self.range_max)
                and self.range_max > self.range_min):
            raise ValueError(f'sensor range must be finite with max > min, got '
                             f'[{self.range_min!r}, {self.range_max!r}]')

    @property
    def resolution(self) -> float:
        """One ADC count (Pa), or 0 without quantisation."""
        if self.bits == 0:
            return 0.0
        return (self.range_max - self.range_min) / (2 ** self.bits - 1)

    def measure(self, P, rng: np.random.Generator) -> np.ndarray:
        """Readings (Pa abs) of true pressures P (any shape)."""
        P = np.asarray(P, dtype=float)
        noisy = P + self.noise_std * rng.standard_normal(P.shape) if self.noise_std else P
        if noisy.ndim == 1:
            return adc_readings(noisy, self.resolution, self.range_min, self.range_max)
        return adc_reading(noisy, self.resolution, self.range_min, self.range_max)

    @classmethod
    def from_dict(cls, data: dict) -> PressureSensor:
        """From the `sensor` section of a mismatch scenario YAML."""
        known = {'pressure_noise_std', 'quantisation_bits', 'range_min', 'range_max'}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f'unknown sensor key {unknown[0]!r} '
                             f'(known: {", ".join(sorted(known))})')
        return cls(noise_std=float(data.get('pressure_noise_std', 0.0)),
                   bits=int(data.get('quantisation_bits', 0)),
                   range_min=float(data.get('range_min', 0.0)),
                   range_max=float(data.get('range_max', 1.0e6)))
