"""The plants pam-robustness sweeps, no ROS, no running.

Each sweep scales one unmodelled effect of pam_model.effects (or all of them, or the parameter
deviations) by a magnitude m, on top of a base mismatch scenario (default 'mild'):

* an effect row sets its fields to m x their value in the 'realistic' scenario
  (pam_model/data/mismatch_realistic.yaml) and keeps every other field of the base's effects;
  m = 0 switches that effect off (with base 'mild': the base plant itself);
* 'all' scales every effect of the realistic scenario at once (m = 1 on 'mild' is 'realistic');
* 'parameters' is the Monte Carlo row: N plants whose parameters deviate from the BASE plant's by
  m x PARAMETER_SPREAD x z, z ~ N(0, 1) per plant and key (relative for the factors, in N for the
  force intercepts): the spread of the 'mild' scenario's deviations, drawn with random signs.
  m = 0 gives N copies of the base plant.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pam_model.effects import Effects
from pam_model.mismatch import MismatchScenario, load_scenario
from pam_model.parameters import Parameters, field_name

#: Effect rows: name -> the Effects fields it scales (the ripple's frequency and the drift's
#: time stay at the realistic values: only the amplitudes scale).
EFFECT_FIELDS = {
    'valve_lag': ('valve_time_constant',),
    'dead_volume': ('dead_volume',),
    'supply': ('supply_droop', 'supply_ripple'),
    'hysteresis': ('hysteresis_band',),
    'temperature': ('temperature_drift',),
    'sensor_offset_gain': ('sensor_offset', 'sensor_gain_error'),
    'sensor_filter': ('sensor_time_constant',),
}
#: Fields a row sets to the realistic value when it is on (m > 0), unscaled.
HELD_FIELDS = {'supply': ('supply_ripple_frequency',), 'temperature': ('temperature_drift_time',)}
ALL = 'all'
PARAMETERS = 'parameters'
ROWS = (*EFFECT_FIELDS, ALL, PARAMETERS)

#: Standard deviation of the Monte Carlo deviations at magnitude 1: relative (factor - 1) for
#: the coefficients, N for the force intercepts; the sizes of the 'mild' scenario's deviations.
PARAMETER_SPREAD = {'mu_s': 0.2, 'mu_p': 0.3, 'A1': 0.15, 'A2': 0.1, 'k1': 0.05, 'k2': 0.05}
INTERCEPT_SPREAD = {'pam1.p_w2': 2.0, 'pam2.p_w2': 1.5}      # N
#: The largest relative deviation drawn (a factor stays within 1 +- this: no negative friction).
DEVIATION_LIMIT = 0.9


@dataclass(frozen=True)
class Plant:
    """One plant of a sweep: its row, magnitude, parameters and effects (draw: Monte Carlo
    index, 0 for the effect rows)."""

    row: str
    magnitude: float
    params: Parameters
    effects: Effects
    draw: int = 0


def scaled(value, m: float):
    """value x m for a number or a pair."""
    if isinstance(value, tuple):
        return tuple(m * v for v in value)
    return m * value


def effects_at(row: str, m: float, base: Effects, realistic: Effects) -> Effects:
    """The base's effects with `row`'s fields (every effect's for ALL) at m x realistic."""
    rows = tuple(EFFECT_FIELDS) if row == ALL else (row,)
    changes = {name: scaled(getattr(realistic, name), m) for r in rows for name in EFFECT_FIELDS[r]}
    if m > 0.0:
        changes.update({name: getattr(realistic, name) for r in rows
                        for name in HELD_FIELDS.get(r, ())})
    return replace(base, **changes)


def parameter_draws(base: Parameters, m: float, count: int, rng) -> list[Parameters]:
    """`count` parameter sets deviating from `base` by m x the spread (module doc)."""
    draws = []
    for _ in range(count):
        changes = {}
        for key, spread in PARAMETER_SPREAD.items():
            factor = 1.0 + float(np.clip(m * spread * rng.standard_normal(), -DEVIATION_LIMIT,
                                         DEVIATION_LIMIT))
            for name in field_name(key):
                changes[name] = getattr(base, name) * factor
        for key, spread in INTERCEPT_SPREAD.items():
            offset = m * spread * rng.standard_normal()
            for name in field_name(key):
                changes[name] = getattr(base, name) + offset
        draws.append(base.replace(**changes))
    return draws


def sweep_plants(rows, magnitudes, base: MismatchScenario, nominal: Parameters,
                 monte_carlo: int, seed: int) -> list[Plant]:
    """Every plant of the sweep, in row order, magnitudes ascending within a row."""
    realistic = load_scenario('realistic').effects
    base_params = base.apply(nominal)
    rng = np.random.default_rng(seed)
    plants = []
    for row in rows:
        for m in magnitudes:
            if row == PARAMETERS:
                plants += [Plant(row, m, params, base.effects, i) for i, params in
                           enumerate(parameter_draws(base_params, m, monte_carlo, rng))]
            else:
                plants.append(Plant(row, m, base_params, effects_at(row, m, base.effects,
                                                                    realistic)))
    return plants
