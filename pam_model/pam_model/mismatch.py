"""Plant mismatch scenarios: a plant parameter set that differs from the nominal one by factors and
offsets, plus the plant's pressure sensor model and its unmodelled effects (pam_model.effects, all
off unless an `effects:` section sets them), read from YAML (see data/mismatch_mild.yaml,
data/mismatch_realistic.yaml and data/mismatch_other_forms.yaml, whose effects have other forms).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from .effects import NO_EFFECTS, Effects
from .parameters import (
    ParameterError,
    Parameters,
    check_number,
    data_path,
    field_name,
    read_yaml,
    validate_parameters,
)
from .sensor import PressureSensor

BUILTIN_SCENARIOS = {'mild': 'mismatch_mild.yaml', 'strong': 'mismatch_strong.yaml',
                     'realistic': 'mismatch_realistic.yaml', 'harsh': 'mismatch_harsh.yaml',
                     'other_forms': 'mismatch_other_forms.yaml'}


@dataclass(frozen=True)
class MismatchScenario:
    """factors and offsets by YAML key ('mu_s', 'A1' for both valves, 'pam1.p_w2' for one
    muscle); the plant's sensor; its unmodelled effects (off by default)."""

    name: str
    factors: Mapping[str, float]
    offsets: Mapping[str, float]
    sensor: PressureSensor
    effects: Effects = NO_EFFECTS

    def apply(self, nominal: Parameters) -> Parameters:
        """The plant set: nominal value * factor + offset for every key named."""
        changes = {}
        for key, factor in self.factors.items():
            for name in field_name(key):
                changes[name] = getattr(nominal, name) * factor
        for key, offset in self.offsets.items():
            for name in field_name(key):
                changes[name] = changes.get(name, getattr(nominal, name)) + offset
        return validate_parameters(nominal.replace(**changes), f'mismatch scenario {self.name!r}')


def scenario_from_dict(data: Mapping, source: str) -> MismatchScenario:
    """Validate the YAML layout of a scenario; errors name the key and the source."""
    known = {'name', 'factors', 'offsets', 'sensor', 'effects'}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ParameterError(f'{source}: unknown key {unknown[0]!r} '
                             f'(known: {", ".join(sorted(known))})')
    tables = {}
    for section in ('factors', 'offsets'):
        table = data.get(section) or {}
        if not isinstance(table, Mapping):
            raise ParameterError(f'{source}: {section} must be a mapping')
        for key, value in table.items():
            try:
                field_name(str(key))
            except KeyError:
                raise ParameterError(f'{source}: unknown parameter key {section}.{key!r}') from None
            number = check_number(f'{section}.{key}', value, source)
            if not math.isfinite(number):
                raise ParameterError(f'{source}: key {section}.{key!r}: must be finite')
        tables[section] = {str(k): float(v) for k, v in table.items()}
    try:
        sensor = PressureSensor.from_dict(data.get('sensor') or {})
    except ValueError as exc:
        raise ParameterError(f'{source}: sensor: {exc}') from exc
    try:
        effects = Effects.from_dict(data.get('effects') or {})
    except ValueError as exc:
        raise ParameterError(f'{source}: effects: {exc}') from exc
    return MismatchScenario(name=str(data.get('name', Path(source).stem)),
                            factors=tables['factors'], offsets=tables['offsets'], sensor=sensor,
                            effects=effects)


def load_scenario(name_or_path: str | Path) -> MismatchScenario:
    """A scenario by built-in name (BUILTIN_SCENARIOS) or YAML path."""
    path = (data_path(BUILTIN_SCENARIOS[str(name_or_path)])
            if str(name_or_path) in BUILTIN_SCENARIOS else Path(name_or_path))
    return scenario_from_dict(read_yaml(path), str(path))


NOMINAL = MismatchScenario(name='nominal', factors={}, offsets={}, sensor=PressureSensor())
