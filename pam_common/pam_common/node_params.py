"""Parameter tables shared by the PAM nodes: declaration with descriptors, checks, --help text.

A node lists its parameters as ParamSpec rows. The pure part (no ROS: checks, usage text) is
tested without a ROS graph; declare_parameters() turns the rows into declared ROS parameters
with descriptors (description, unit, range, read-only) and returns their values.
Errors name the parameter: ConfigError("parameter 'joint_mode': unknown value ...").
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

from pam_model.valve_voltage import U_MAX, U_MIN  # V, the valve voltage range


class ConfigError(ValueError):
    """A node parameter has a bad value; the message names the parameter."""


@dataclass(frozen=True)
class Deferred:
    """A default known only when first needed, e.g. read from an installed file: a parameter
    table built at import time must not read it then (importing a node's config module needs no
    ROS environment). `resolve()` is called at each use: cache it if it is costly."""

    resolve: Callable[[], Any]


@dataclass(frozen=True)
class ParamSpec:
    """One ROS parameter of a node. `default` may be Deferred: default_value() resolves it."""

    name: str
    default: Any
    type_name: str          # 'string', 'double', 'integer', 'bool', 'double[]', 'integer[]'
    unit: str
    description: str
    choices: tuple = ()
    range: tuple | None = None
    read_only: bool = True
    #: old names still accepted (a params file or -p rule of an earlier release), each mapped
    #: to this one with a warning; giving two of them different values is a ConfigError
    aliases: tuple = ()

    def default_value(self) -> Any:
        """The default, a Deferred one resolved now."""
        return self.default.resolve() if isinstance(self.default, Deferred) else self.default

    def default_text(self) -> str:
        default = self.default_value()
        if isinstance(default, bool):
            return 'true' if default else 'false'
        if isinstance(default, list):
            return '[' + ', '.join(repr(v) for v in default) + ']'
        return repr(default)


@dataclass(frozen=True)
class NodeConfig:
    """Base of a node's checked configuration, frozen and built once: one field per row of its
    parameter table, of the same name (the table keeps the default, unit, range and text: each
    written once), lists as tuples. A subclass declares the fields with their types and may add
    properties derived from them."""

    @classmethod
    def from_values(cls, values: Mapping[str, Any]):
        """From check_all's (or a node's own check's) values: every field's row, nothing else
        read. ValueError names a missing one (a table and its config that disagree)."""
        names = cls.parameter_names()
        missing = [n for n in names if n not in values]
        if missing:
            raise ValueError(f'{cls.__name__}: no value for {", ".join(missing)}')
        return cls(**{n: tuple(values[n]) if isinstance(values[n], list) else values[n]
                      for n in names})

    @classmethod
    def parameter_names(cls) -> list[str]:
        return [f.name for f in fields(cls)]


#: The row every node's parameter table holds: the hardware_id of its /diagnostics status
#: (pam_common.diagnostics.DiagnosticsPublisher; here, without ROS, for the ROS-free tables).
HARDWARE_ID_PARAM = ParamSpec(
    'hardware_id', '', 'string', '',
    "hardware_id of the node's /diagnostics status; '' (the default): the node's namespace, "
    'e.g. /pam, so the nodes of one stack share it and two stacks differ.')


def defaults(specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """The default value of every parameter (lists copied)."""
    values = {s.name: s.default_value() for s in specs}
    return {name: (list(v) if isinstance(v, list) else v) for name, v in values.items()}


def renamed_overrides(specs: Sequence[ParamSpec], overrides: Mapping[str, Any]
                      ) -> tuple[dict[str, Any], list[tuple[str, str]]]:
    """The overrides with every old name (a spec's aliases) replaced by the spec's name, and the
    (old, new) pairs replaced. ConfigError when an old name and the new one (or two old ones)
    are given different values."""
    result = dict(overrides)
    renamed = []
    for spec in specs:
        for alias in spec.aliases:
            if alias not in result:
                continue
            value = result.pop(alias)
            if spec.name in result and result[spec.name] != value:
                fail(spec.name, f"given twice with different values, as '{spec.name}' "
                     f"({result[spec.name]!r}) and by its old name '{alias}' ({value!r})")
            result[spec.name] = value
            renamed.append((alias, spec.name))
    return result, renamed


def renamed_warning(old: str, new: str) -> str:
    return f"parameter '{old}' is the old name of '{new}': read as {new} (rename it)"


def merge_overrides(specs: Sequence[ParamSpec], overrides: Mapping[str, Any] | None) -> dict:
    """Defaults updated with overrides (old names read as the new ones); an unknown name is a
    ConfigError."""
    values = defaults(specs)
    overrides, _ = renamed_overrides(specs, overrides or {})
    unknown = sorted(set(overrides or {}) - set(values))
    if unknown:
        raise ConfigError(f'unknown parameter {unknown[0]!r}')
    values.update(overrides or {})
    for spec in specs:
        value = values[spec.name]
        if spec.type_name == 'string' and not isinstance(value, str):
            fail(spec.name, f'expected a string, got {value!r}')
        if spec.type_name == 'bool' and not isinstance(value, bool):
            fail(spec.name, f'expected true or false, got {value!r}')
    return values


def fail(name: str, message: str):
    raise ConfigError(f"parameter '{name}': {message}")


def check_choice(spec: ParamSpec, value) -> str:
    if value not in spec.choices:
        fail(spec.name, f'unknown value {value!r}; choose one of: {", ".join(spec.choices)}')
    return value


def check_array(name: str, value, length: int, meaning: str) -> list[float]:
    """A list of `length` finite floats."""
    try:
        array = [float(v) for v in value]
    except (TypeError, ValueError):
        fail(name, f'expected {length} numbers {meaning}, got {value!r}')
    if len(array) != length:
        fail(name, f'expected {length} numbers {meaning}, got {len(array)}: {array}')
    if not all(math.isfinite(v) for v in array):
        fail(name, f'values must be finite, got {array}')
    return array


def check_number(spec: ParamSpec, value, integer: bool = False):
    """A finite number inside spec.range (an int if integer)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        fail(spec.name, f'expected a{"n integer" if integer else " number"}, got {value!r}')
    if integer and not float(value).is_integer():
        fail(spec.name, f'expected an integer, got {value!r}')
    if not math.isfinite(value):
        fail(spec.name, f'must be finite, got {value!r}')
    if spec.range is not None:
        low, high = spec.range
        if not low <= value <= high:
            fail(spec.name, f'{value!r} is out of range [{low}, {high}]')
    return int(value) if integer else float(value)


def check_command(name: str, value) -> list[float]:
    """[u1, u2] inside the valve range."""
    command = check_array(name, value, 2, '[u1 V, u2 V]')
    if not all(U_MIN <= u <= U_MAX for u in command):
        fail(name, f'voltages must be in [{U_MIN}, {U_MAX}] V, got {command}')
    return command


def check_state(name: str, value) -> list[float]:
    """[psi, psi_dot, P1, P2] with positive absolute pressures."""
    state = check_array(name, value, 4, '[psi rad, psi_dot rad/s, P1 Pa, P2 Pa]')
    if state[2] <= 0.0 or state[3] <= 0.0:
        fail(name, f'pressures are absolute and must be > 0 Pa, got {state[2:]}')
    return state


def check_all(specs: Sequence[ParamSpec], values: dict) -> dict:
    """Apply the generic checks: choices, numbers in range. Returns values (updated in place)."""
    for spec in specs:
        if spec.choices:
            check_choice(spec, values[spec.name])
        elif spec.type_name in ('double', 'integer'):
            values[spec.name] = check_number(spec, values[spec.name],
                                             integer=spec.type_name == 'integer')
    return values


def wants_help(argv: Sequence[str]) -> bool:
    """True if -h/--help appears among the program's own arguments (before any --ros-args)."""
    for arg in list(argv)[1:]:
        if arg == '--ros-args':
            return False
        if arg in ('-h', '--help'):
            return True
    return False


def cli_preamble(argv: Sequence[str], prog: str, usage: str) -> int | None:
    """Before rclpy starts: --help prints `usage` (exit code 0); an argument that is not a ROS
    argument, a bad params file or -p rule (params_files) is an error (exit code 2).
    None: go on."""
    import sys
    if wants_help(argv):
        sys.stdout.write(usage)
        return 0
    from .params_files import report_ros_args_problem
    code = report_ros_args_problem(argv, prog)
    if code is not None:
        return code
    from rclpy.utilities import remove_ros_args
    leftover = remove_ros_args(list(argv))[1:]
    if leftover:
        sys.stderr.write(f'{prog}: error: unknown argument {leftover[0]!r}; parameters are set '
                         f'with --ros-args -p NAME:=VALUE (see {prog} --help)\n')
        return 2
    return None


def usage_text(prog: str, summary: Sequence[str], specs: Sequence[ParamSpec],
               examples: Sequence[str] = ()) -> str:
    """--help text: usage line, the node's summary lines, every parameter, examples."""
    lines = [f'usage: {prog} [-h] [--ros-args [-p NAME:=VALUE]... [--params-file FILE] '
             '[-r __ns:=/NAMESPACE]]', '', *summary, '',
             'Parameters (name (type[, unit]) = default):']
    for spec in specs:
        kind = spec.type_name + (f', {spec.unit}' if spec.unit else '')
        extra = ''
        if spec.choices:
            extra = '  {' + ', '.join(spec.choices) + '}'
        elif spec.range:
            extra = f'  [{spec.range[0]} .. {spec.range[1]}]'
        lines.append(f'  {spec.name} ({kind}) = {spec.default_text()}{extra}'
                     + (f'  (old name: {", ".join(spec.aliases)})' if spec.aliases else ''))
        lines.extend(textwrap.wrap(spec.description, width=96, initial_indent=' ' * 6,
                                   subsequent_indent=' ' * 6))
    if examples:
        lines += ['', 'Examples:'] + [f'  {e}' for e in examples]
    return '\n'.join(lines) + '\n'


# --- ROS side ----------------------------------------------------------------------------------

def descriptor(spec: ParamSpec):
    """The rcl_interfaces ParameterDescriptor of a spec."""
    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
        ParameterType,
    )
    types = {'string': ParameterType.PARAMETER_STRING,
             'double': ParameterType.PARAMETER_DOUBLE,
             'integer': ParameterType.PARAMETER_INTEGER,
             'bool': ParameterType.PARAMETER_BOOL,
             'double[]': ParameterType.PARAMETER_DOUBLE_ARRAY,
             'integer[]': ParameterType.PARAMETER_INTEGER_ARRAY}
    description = spec.description + (f' Unit: {spec.unit}.' if spec.unit else '')
    result = ParameterDescriptor(name=spec.name, type=types[spec.type_name],
                                 description=description, read_only=spec.read_only)
    if spec.choices:
        result.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    if spec.range is not None and spec.type_name == 'double':
        result.floating_point_range = [FloatingPointRange(
            from_value=float(spec.range[0]), to_value=float(spec.range[1]), step=0.0)]
    elif spec.range is not None and spec.type_name == 'integer':
        result.integer_range = [IntegerRange(
            from_value=int(spec.range[0]), to_value=int(spec.range[1]), step=1)]
    return result


def _type_hint(spec: ParamSpec, value) -> str:
    if spec.type_name == 'double' and isinstance(value, int) and not isinstance(value, bool):
        return f' (write {value}.0)'
    if spec.type_name == 'double[]':
        return ' (write every element with a decimal point, e.g. [0.0, 0.0, 450000.0, 450000.0])'
    if spec.type_name == 'integer[]':
        return ' (write a list of integers, e.g. [0] or [0, 1])'
    return ''


def override_value(node, name: str):
    """The value given for `name` on the command line or in a params file (None if none).

    rclpy has no public accessor for the overrides: this reads Node._parameter_overrides."""
    override = getattr(node, '_parameter_overrides', {}).get(name)
    return override.value if override is not None else None


def unknown_overrides(node, specs: Sequence[ParamSpec]) -> list[str]:
    """Names given on the command line or in a params file that no spec declares (typos)."""
    known = ({spec.name for spec in specs} | {a for spec in specs for a in spec.aliases}
             | {'use_sim_time', 'start_type_description_service'})
    return sorted(name for name in getattr(node, '_parameter_overrides', {})
                  if name not in known and not name.startswith('qos_overrides.'))


def unknown_parameter_warning(name: str, specs: Sequence[ParamSpec], prog: str) -> str:
    """The warning about an override no spec declares, with the closest known name."""
    import difflib
    close = difflib.get_close_matches(name, [spec.name for spec in specs], n=1, cutoff=0.6)
    hint = f": did you mean '{close[0]}'?" if close else ''
    return f"ignoring unknown parameter '{name}'{hint} (see {prog} --help)"


#: The array types and their rclpy Parameter.Type names (an empty default is declared by type).
ARRAY_TYPES = {'double[]': 'DOUBLE_ARRAY', 'integer[]': 'INTEGER_ARRAY'}


def _give_empty_value(node, spec: ParamSpec, array_type: str) -> None:
    """An array parameter declared by its type (empty default, no override) has no value, and
    rclpy's get_parameters service then answers nothing for a request naming it (`ros2 param
    dump` fails on the node): give it the empty array of its type, then make it read-only as its
    spec says (rclpy refuses to set a read-only parameter, so it is declared writable first:
    see declare_parameters)."""
    from rclpy.parameter import Parameter
    node.set_parameters([Parameter(spec.name, getattr(Parameter.Type, array_type), [])])
    if spec.read_only:
        node.set_descriptor(spec.name, descriptor(spec))


def _rename_overrides(node, specs: Sequence[ParamSpec]) -> None:
    """An override given by an old name (ParamSpec.aliases) becomes the override of the new
    name, with a warning, so the node declares and reports only the new one. rclpy has no
    public accessor for the overrides: this edits Node._parameter_overrides."""
    from rclpy.parameter import Parameter
    overrides = getattr(node, '_parameter_overrides', None)
    if not overrides or not any(spec.aliases for spec in specs):
        return
    given = {name: parameter.value for name, parameter in overrides.items()}
    _, renamed = renamed_overrides(specs, given)
    for old, new in renamed:
        overrides[new] = Parameter(new, value=overrides.pop(old).value)
        node.get_logger().warning(renamed_warning(old, new))


def declare_parameters(node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """Declare every spec on the node with its descriptor and return the values; call it once,
    with the node's whole table.

    A value of the wrong type (an override from the command line or a params file) becomes a
    ConfigError naming the parameter, with a hint (e.g. 'write 1000.0'); a value outside the
    descriptor's range a ConfigError naming the range. An override no spec declares (a typo)
    is logged as a warning naming the closest known name.
    """
    import rclpy.exceptions
    from rclpy.parameter import Parameter
    for name in unknown_overrides(node, specs):     # first: a typo may explain an error below
        node.get_logger().warning(unknown_parameter_warning(name, specs, node.get_name()))
    _rename_overrides(node, specs)
    values = {}
    for spec in specs:
        # an empty list has no element type: declare such a parameter by its type instead
        array_type = ARRAY_TYPES.get(spec.type_name)
        default = spec.default_value()
        empty_array = array_type and not default
        if empty_array:
            default = getattr(Parameter.Type, array_type)
        try:
            writable = descriptor(spec)
            if empty_array:
                writable.read_only = False      # read-only once it has a value
            value = node.declare_parameter(spec.name, default, writable).value
            if value is None and array_type:
                _give_empty_value(node, spec, array_type)
            values[spec.name] = [] if value is None and array_type else value
        except rclpy.exceptions.InvalidParameterTypeException as exc:
            value = override_value(node, spec.name)
            raise ConfigError(f"parameter '{spec.name}': expected {spec.type_name}, got "
                              f'{value!r}{_type_hint(spec, value)}') from exc
        except rclpy.exceptions.InvalidParameterValueException as exc:
            value = override_value(node, spec.name)
            if spec.range is not None:
                raise ConfigError(f"parameter '{spec.name}': {value!r} is out of range "
                                  f'[{spec.range[0]}, {spec.range[1]}]') from exc
            raise ConfigError(f"parameter '{spec.name}': {exc}") from exc
    return values
