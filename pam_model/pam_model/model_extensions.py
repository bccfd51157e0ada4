"""The estimator's answers to a real rig: the unmodelled effects of
``pam_model.effects`` that the ESTIMATOR's model may carry too, each off by default, identified by
pam-identify where the calibration runs reveal them and written to ``extensions.yaml`` beside the
identified ``params.yaml``.

The paper's model (MODEL.md) stays the default and the reference: with no extensions the UKF and
the model alone compute exactly what they computed before. An extension set is an
:class:`pam_model.effects.Effects` (the same equations and units, documented there) restricted to
what an estimator can know about its own rig:

* ``valve_time_constant`` tau_v (s): the valve spool's first-order lag of the command;
* ``dead_volume`` V_d (m^3 per muscle): the air line's volume in eq. (4);
* ``hysteresis_band`` B (N at 500 kPa), ``hysteresis_travel`` Delta (N), ``hysteresis_elements``
  n: the Maxwell-slip force hysteresis added to eq. (6), driven by the nominal force;
* ``bouc_wen_band`` B_w (N at 500 kPa, signed: the loop's orientation), ``bouc_wen_driver``
  ('length' or 'pressure'), ``bouc_wen_length_travel`` (m) / ``bouc_wen_pressure_travel`` (Pa):
  the Bouc-Wen force hysteresis added to eq. (6), driven by the muscle's length or pressure;
* ``sensor_offset`` [o1, o2] (Pa), ``sensor_gain_error`` [g1, g2] (fraction): the transducers'
  reading (1 + g) P + o, inverted before the UKF's update.

The supply pressure's droop and ripple and the air temperature's drift are the rig's state, not
its constants: an estimator can only measure them (the optional supply-pressure channel), so they
are refused here.

File layout (YAML): ``extensions:`` a mapping of the keys above; an empty mapping or a missing
file section means none.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, fields
from pathlib import Path

import yaml

from .effects import Effects
from .parameters import ParameterError, read_yaml

#: The Effects fields an estimator's model may carry.
ESTIMATOR_FIELDS = ('valve_time_constant', 'dead_volume', 'hysteresis_band',
                    'hysteresis_travel', 'hysteresis_elements', 'bouc_wen_band',
                    'bouc_wen_driver', 'bouc_wen_length_travel', 'bouc_wen_pressure_travel',
                    'sensor_offset', 'sensor_gain_error')

#: No extension: the paper's model.
NO_EXTENSIONS = Effects()


def extensions_from_dict(data: Mapping, source: str) -> Effects:
    """Validate the `extensions` mapping; ParameterError naming the key and the source."""
    if data is None:
        return NO_EXTENSIONS
    if not isinstance(data, Mapping):
        raise ParameterError(f'{source}: extensions must be a mapping, got '
                             f'{type(data).__name__}')
    known = {f.name for f in fields(Effects)}
    for key in map(str, data):
        if key in known and key not in ESTIMATOR_FIELDS:
            raise ParameterError(f'{source}: extensions: {key!r} is a state of the rig, not a '
                                 f'constant of the model (an estimator can only measure it); '
                                 f'allowed: {", ".join(ESTIMATOR_FIELDS)}')
    try:
        return Effects.from_dict(data)
    except ValueError as exc:
        raise ParameterError(f'{source}: extensions: {exc}') from exc


def load_extensions(path: str | Path | None) -> Effects:
    """The extensions of a YAML file; None or '' gives NO_EXTENSIONS."""
    if path is None or str(path) == '':
        return NO_EXTENSIONS
    path = Path(path)
    data = read_yaml(path)
    unknown = sorted(set(map(str, data)) - {'extensions', 'name'})
    if unknown:
        raise ParameterError(f'{path}: unknown key {unknown[0]!r} (known: extensions, name)')
    return extensions_from_dict(data.get('extensions'), str(path))


def extensions_to_dict(ext: Effects) -> dict:
    """The non-default estimator fields of ext, YAML-ready (pairs as lists)."""
    default = asdict(NO_EXTENSIONS)
    out = {}
    for key in ESTIMATOR_FIELDS:
        value = getattr(ext, key)
        if value != default[key]:
            out[key] = list(value) if isinstance(value, tuple) else value
    return out


def save_extensions(ext: Effects, path: str | Path, name: str = 'identified') -> None:
    """Write the layout load_extensions reads."""
    Path(path).write_text(yaml.safe_dump({'name': name, 'extensions': extensions_to_dict(ext)},
                                         sort_keys=False))
