"""Table II parameters of the antagonistic PAM joint: the record, YAML loading and validation.

All values are SI (m, kg, s, Pa absolute, N, N·m, K). The YAML layout is flat for the joint and
gas constants and has one section per muscle (``pam1``, ``pam2``) for the force coefficients of
eq. (7) and the effective areas of that muscle's valve. Inside the code each per-muscle value
carries the muscle index as suffix: ``p_w2_2`` is PAM2's p_w2, ``A1_1`` is valve 1's charging area.

Two sets ship with the package (MODEL.md section 3):
``default``  Table II with PAM2's p_w2 corrected to +15.75 N (the muscles are near twins);
``printed``  Table II exactly as printed (p_w2 = -15.75 N), kept for reference.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import NamedTuple

import yaml

#: Keys of the flat (joint, gas, friction) part of the YAML file, in Parameters order.
JOINT_KEYS = ('r_p', 'r', 'L0', 'M', 'g', 'P_tank', 'P_out', 'k', 'R', 'T', 'J', 'k_s', 'c_s',
              'k1', 'k2', 'D1', 'D2', 'D3', 'mu_p', 'mu_s', 'F_r', 'f_s', 'f_k', 'xdot_k')
#: Keys of each muscle section (``pam1``, ``pam2``).
MUSCLE_KEYS = ('p_v1', 'p_v2', 'p_w1', 'p_w2', 'A1', 'A2')
MUSCLE_SECTIONS = ('pam1', 'pam2')

#: Physical constraints by YAML key (muscle keys without section). Others need only be finite.
_STRICTLY_POSITIVE = {'r_p', 'r', 'L0', 'g', 'P_out', 'R', 'T', 'J', 'k1', 'A1', 'A2',
                      'xdot_k'}
_NON_NEGATIVE = {'M', 'k_s', 'c_s', 'k2', 'mu_p', 'mu_s', 'F_r', 'f_s', 'f_k'}

#: Names of the built-in parameter sets.
BUILTIN_SETS = {'default': 'params_default.yaml', 'printed': 'params_printed.yaml'}


class ParameterError(ValueError):
    """A parameter file is malformed or holds an impossible value; the message names key and
    file."""


class Parameters(NamedTuple):
    """Table II of the paper, SI units. A NamedTuple of floats, so compiled kernels can take it."""

    r_p: float      # m, shaft radius
    r: float        # m, seesaw radius
    L0: float       # m, muscle length at psi = 0
    M: float        # kg, mass loading the shaft
    g: float        # m/s^2
    P_tank: float   # Pa abs, supply pressure
    P_out: float    # Pa abs, exhaust pressure (atmosphere)
    k: float        # -, ratio of specific heats
    R: float        # J/(kg K)
    T: float        # K
    J: float        # kg m^2, joint inertia
    k_s: float      # N m/rad, joint spring
    c_s: float      # N m s/rad, viscous friction
    k1: float       # -, eq. (4) mass-flow gain
    k2: float       # -, eq. (4) volume-change gain
    D1: float       # m, volume polynomial
    D2: float       # m^2
    D3: float       # m^3
    mu_p: float     # N m Pa^2, pressure-dependent tube friction (T'_p)
    mu_s: float     # -, shaft Coulomb coefficient
    F_r: float      # N, simple Coulomb law (Table III) force at r_p
    f_s: float      # N m, Tondu static friction
    f_k: float      # N m, Tondu kinetic friction
    xdot_k: float   # rad/s, Tondu Stribeck velocity
    p_v1_1: float   # m, PAM1 force coefficients, eq. (7)
    p_v2_1: float   # m^2
    p_w1_1: float   # N/m
    p_w2_1: float   # N
    A1_1: float     # m^2, valve 1 effective area, charging
    A2_1: float     # m^2, valve 1 effective area, discharging
    p_v1_2: float   # PAM2, same meaning
    p_v2_2: float
    p_w1_2: float
    p_w2_2: float
    A1_2: float
    A2_2: float

    def to_dict(self) -> dict:
        """The YAML layout (flat joint keys, one section per muscle)."""
        d = {key: getattr(self, key) for key in JOINT_KEYS}
        for i, section in enumerate(MUSCLE_SECTIONS, start=1):
            d[section] = {key: getattr(self, f'{key}_{i}') for key in MUSCLE_KEYS}
        return d

    def replace(self, **changes: float) -> Parameters:
        """A copy with some fields changed (field names as in the NamedTuple)."""
        return self._replace(**changes)

    def as_record_array(self):
        """A 1-element numpy structured array with the same field names.

        Compiled kernels read ``p = p_array[0]`` like the NamedTuple (``p.r``); passing the array
        from Python costs ~0.3 us instead of ~2.5 us for unboxing 36 tuple fields.
        """
        import numpy as np
        dtype = np.dtype([(name, np.float64) for name in self._fields])
        return np.array([tuple(self)], dtype=dtype)


def field_name(key: str) -> list[str]:
    """Map a YAML key ('k1', 'pam2.p_w2' or a bare muscle key 'A1') to Parameters field names."""
    if key in JOINT_KEYS:
        return [key]
    if '.' in key:
        section, sub = key.split('.', 1)
        if section in MUSCLE_SECTIONS and sub in MUSCLE_KEYS:
            return [f'{sub}_{MUSCLE_SECTIONS.index(section) + 1}']
    elif key in MUSCLE_KEYS:
        return [f'{key}_{i}' for i in (1, 2)]
    raise KeyError(key)


def yaml_key(field: str) -> str:
    """The YAML key of a Parameters field ('A1_2' -> 'pam2.A1', 'k1' -> 'k1')."""
    base, _, index = field.rpartition('_')
    if base in MUSCLE_KEYS and index in ('1', '2'):
        return f'{MUSCLE_SECTIONS[int(index) - 1]}.{base}'
    return field


def check_number(key: str, value, source: str) -> float:
    """A YAML scalar as float. Numeric strings pass: YAML 1.1 reads '1e-5' (no dot) as a string."""
    if isinstance(value, (int, float, str)) and not isinstance(value, bool):
        try:
            return float(value)
        except ValueError:
            pass
    raise ParameterError(f'{source}: key {key!r}: expected a number, got {value!r}')


def _check_keys(mapping: Mapping, expected, where: str, source: str, optional=()) -> None:
    if not isinstance(mapping, Mapping):
        raise ParameterError(f'{source}: {where} must be a mapping, got {type(mapping).__name__}')
    unknown = sorted(set(mapping) - set(expected) - set(optional))
    missing = [key for key in expected if key not in mapping]
    if unknown:
        raise ParameterError(f'{source}: unknown key {where}{unknown[0]!r}'
                             f' (known: {", ".join(expected)})')
    if missing:
        raise ParameterError(f'{source}: missing key {where}{missing[0]!r}')


def parameters_from_dict(data: Mapping, source: str = '<dict>') -> Parameters:
    """Validate the YAML layout and build Parameters. Raises ParameterError naming key and
    source."""
    _check_keys(data, JOINT_KEYS + MUSCLE_SECTIONS, '', source, optional=('name',))
    fields = {key: check_number(key, data[key], source) for key in JOINT_KEYS}
    for i, section in enumerate(MUSCLE_SECTIONS, start=1):
        _check_keys(data[section], MUSCLE_KEYS, f'{section}.', source)
        for key in MUSCLE_KEYS:
            fields[f'{key}_{i}'] = check_number(f'{section}.{key}', data[section][key], source)
    return validate_parameters(Parameters(**fields), source)


def validate_parameters(p: Parameters, source: str = '<parameters>') -> Parameters:
    """Check that every value is finite and physically possible; the error names key and source."""
    for field, value in p._asdict().items():
        key = yaml_key(field)
        base = key.rsplit('.', 1)[-1]
        if not math.isfinite(value):
            raise ParameterError(f'{source}: key {key!r}: must be finite, got {value!r}')
        if base in _STRICTLY_POSITIVE and value <= 0.0:
            raise ParameterError(f'{source}: key {key!r}: must be > 0, got {value!r}')
        if base in _NON_NEGATIVE and value < 0.0:
            raise ParameterError(f'{source}: key {key!r}: must be >= 0, got {value!r}')
    if p.k <= 1.0:
        raise ParameterError(f"{source}: key 'k': ratio of specific heats must be > 1, got {p.k!r}")
    if p.P_tank <= p.P_out:
        raise ParameterError(f"{source}: key 'P_tank': must exceed P_out ({p.P_out!r} Pa),"
                             f' got {p.P_tank!r}')
    if p.r >= p.L0:
        raise ParameterError(f"{source}: key 'r': seesaw radius must be below L0, got {p.r!r}")
    volume_L0 = p.D1 * p.L0 ** 2 + p.D2 * p.L0 + p.D3
    if volume_L0 <= 0.0:
        raise ParameterError(f"{source}: keys 'D1', 'D2', 'D3': muscle volume at L0 must be"
                             f' > 0, got {volume_L0!r} m^3')
    return p


def read_yaml(path: Path) -> Mapping:
    try:
        text = path.read_text()
    except OSError as exc:
        raise ParameterError(f'{path}: cannot read parameter file: {exc.strerror}') from exc
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ParameterError(f'{path}: not valid YAML: {exc}') from exc
    if not isinstance(data, Mapping):
        raise ParameterError(f'{path}: expected a mapping of parameters, got {type(data).__name__}')
    return data


def data_path(filename: str) -> Path:
    """Path of a data file shipped inside the pam_model package."""
    return Path(str(resources.files('pam_model') / 'data' / filename))


def resolve_parameter_file(name_or_path: str | Path) -> Path:
    """'default' / 'printed' name the shipped sets; anything else is a file path."""
    if str(name_or_path) in BUILTIN_SETS:
        return data_path(BUILTIN_SETS[str(name_or_path)])
    return Path(name_or_path)


def load_parameters(name_or_path: str | Path = 'default') -> Parameters:
    """Load and validate a Table II YAML file (or a built-in set by name: 'default', 'printed')."""
    path = resolve_parameter_file(name_or_path)
    return parameters_from_dict(read_yaml(path), str(path))


def save_parameters(p: Parameters, path: str | Path, name: str = 'custom') -> None:
    """Write Parameters in the YAML layout that load_parameters reads."""
    data = {'name': name, **p.to_dict()}
    Path(path).write_text(yaml.safe_dump(data, sort_keys=False))
