"""ROS parameter files and -p overrides, checked before rclpy.init: one-line errors.

rclpy.init() parses `--params-file FILE` and `-p NAME:=VALUE` with rcl's YAML parser and fails on
a bad one with a traceback and a vague 'Error parsing a event near line 3'. ros_args_problem()
checks them first: every params file with PyYAML on libyaml (the parser rcl uses) for the syntax
(the line of the error, a tab in the indentation named as such) and the layout rcl expects

    <node name or namespace>:        # '/**', '/pam/sim_node', or nested: pam: {sim_node: ...}
      ros__parameters:
        <name>: <value>              # a scalar, a list of scalars, or a mapping (dotted names)

then rcl's own parse of the whole argument list (rclpy.utilities.remove_ros_args: no context is
initialised), whose verdict decides the rest (e.g. a list of mixed types, a YAML alias, an invalid
node name), its message cut to one line. The check is a little stricter than rcl where rcl
silently ignores a file: a file that is a list or a bare value, or a node section without
ros__parameters, is an error here.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Sequence
from pathlib import Path

PARAMETERS_KEY = 'ros__parameters'
# rcl's messages: "... at line 3", "... near line 3", "... at line_num 3"
_RCL_LINE = re.compile(r'\s*(?:near|at)\s+line(?:_num)?\s+(\d+)')
_RCL_SOURCE = re.compile(r',?\s*at\s+\S+\.c:\d+')     # ", at /project/src/parse.c:782"
_RCL_PARAMS_FILE = re.compile(r"Couldn't parse params file: '--params-file (.*)'\. Error: (.*)",
                              re.S)
_RCL_OVERRIDE = re.compile(r"Couldn't parse parameter override rule: '(.*)'\. Error: (.*)", re.S)


class ParamsFileError(ValueError):
    """A params file that rcl would refuse (or that sets nothing); str() is one line."""

    def __init__(self, path, problem: str, line: int | None = None):
        self.path = str(path)
        self.problem = problem
        self.line = line
        super().__init__(f'params file {self.path}: {problem}'
                         + (f' (line {line})' if line is not None else ''))


def _kind(node) -> str:
    import yaml
    if isinstance(node, yaml.SequenceNode):
        return 'a list'
    if isinstance(node, yaml.MappingNode):
        return 'a mapping'
    return f'the value {node.value!r}' if node.value else 'no value'


def _line(node) -> int:
    return node.start_mark.line + 1


def _syntax_error(path, text: str, exc) -> ParamsFileError:
    """One line from a yaml.MarkedYAMLError: the problem, its context, the line."""
    mark = exc.problem_mark or exc.context_mark
    if mark is None:
        return ParamsFileError(path, f'not valid YAML: {exc}'.replace('\n', ' '))
    lines = text.splitlines()
    line = mark.line + 1
    if line > len(lines) and exc.context_mark is not None:   # at the end of the file: an
        line = exc.context_mark.line + 1                     # unclosed bracket or quote
    source = lines[line - 1] if line <= len(lines) else ''
    if '\t' in source[:len(source) - len(source.lstrip())]:
        return ParamsFileError(path, 'a tab in the indentation (YAML indents with spaces only)',
                               line)
    problem = exc.problem or 'not valid YAML'
    if exc.context:
        problem += f' {exc.context}'
    return ParamsFileError(path, f'not valid YAML: {problem}', line)


def _check_parameters(path, mapping, prefix: str) -> None:
    """The values under ros__parameters: scalars, lists, or mappings (dotted names)."""
    import yaml
    for key, value in mapping.value:
        if not isinstance(key, yaml.ScalarNode):
            raise ParamsFileError(path, f'{_kind(key)} as a parameter name', _line(key))
        name = prefix + key.value
        if isinstance(value, yaml.MappingNode):
            _check_parameters(path, value, name + '.')
        elif isinstance(value, yaml.ScalarNode) and not value.style and not value.value:
            # a plain empty scalar (`name:`); style is None (PyYAML) or '' (libyaml) when plain
            raise ParamsFileError(path, f"parameter '{name}' has no value", _line(key))


def _sections(path, mapping, names: list[str]) -> list[str]:
    """The node sections below `mapping` (names: the keys above it), checked."""
    import yaml
    sections = []
    for key, value in mapping.value:
        if not isinstance(key, yaml.ScalarNode):
            raise ParamsFileError(path, f'{_kind(key)} as a node name', _line(key))
        if key.value == PARAMETERS_KEY:
            if not names:
                raise ParamsFileError(path, f'{PARAMETERS_KEY} without a node name above it '
                                      "(e.g. '/**:' for every node)", _line(key))
            if not isinstance(value, yaml.MappingNode):
                raise ParamsFileError(path, f'{PARAMETERS_KEY} holds {_kind(value)}; it must map '
                                      'parameter names to values (name: value)', _line(value))
            _check_parameters(path, value, '')
            sections.append('/'.join(names))
        elif isinstance(value, yaml.MappingNode):
            below = _sections(path, value, [*names, key.value])
            if not below:
                raise ParamsFileError(path, f"'{key.value}' has no {PARAMETERS_KEY}",
                                      _line(key))
            sections += below
        else:
            raise ParamsFileError(path, f"'{key.value}' holds {_kind(value)} outside "
                                  f'{PARAMETERS_KEY} (a node section is <node>: '
                                  f'{{{PARAMETERS_KEY}: {{name: value}}}})', _line(value))
    return sections


def check_params_file(path) -> list[str]:
    """The node sections of a params file ('/**', '/pam/sim_node', nested keys joined with
    '/'); ParamsFileError (one line, with the line number where there is one) if it cannot be
    read, is not YAML, or is not laid out as rcl expects. rcl's parse judges the values."""
    import yaml
    file = Path(path)
    if not file.exists():
        raise ParamsFileError(path, 'not found')
    if file.is_dir():
        raise ParamsFileError(path, 'is a directory, not a file')
    try:
        text = file.read_text(encoding='utf-8')
    except OSError as exc:
        raise ParamsFileError(path, f'cannot read it: {exc.strerror}') from exc
    except UnicodeDecodeError as exc:
        raise ParamsFileError(path, f'not UTF-8 text: {exc.reason}') from exc
    loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)   # libyaml, as rcl
    try:
        documents = list(yaml.compose_all(text, Loader=loader))   # rcl reads every document
    except yaml.MarkedYAMLError as exc:
        raise _syntax_error(path, text, exc) from exc
    except yaml.YAMLError as exc:
        raise ParamsFileError(path, f'not valid YAML: {exc}'.replace('\n', ' ')) from exc
    sections = []
    for root in documents:
        if root is None:
            continue
        if not isinstance(root, yaml.MappingNode):
            raise ParamsFileError(path, f'the file holds {_kind(root)}; it must map node names '
                                  f'to {PARAMETERS_KEY} sections', _line(root))
        sections += _sections(path, root, [])
    return sections


def params_files_in(argv: Sequence[str]) -> list[str]:
    """The FILE of every `--params-file FILE` inside the --ros-args sections of argv."""
    files, in_ros = [], False
    args = list(argv)
    for i, arg in enumerate(args):
        if arg == '--ros-args':
            in_ros = True
        elif arg == '--' and in_ros:
            in_ros = False
        elif in_ros and arg == '--params-file' and i + 1 < len(args):
            files.append(args[i + 1])
    return files


def rcl_problem(message: str) -> str:
    """rcl's error message about the ROS arguments as one line, without its C source places."""
    text = ' '.join(str(message).split())
    text = _RCL_SOURCE.sub('', text)
    for prefix in ('Failed to parse ROS arguments: ', 'failed to initialize rcl: '):
        text = text.removeprefix(prefix)
    match = _RCL_PARAMS_FILE.fullmatch(text) or _RCL_OVERRIDE.fullmatch(text)
    if not match:
        return text
    problem = match.group(2).rstrip('.')
    line = _RCL_LINE.search(problem)
    if line:
        problem = (problem[:line.start()] + problem[line.end():]).rstrip(' .,')
    if match.re is _RCL_OVERRIDE:       # a -p rule: its line is always 1
        if 'lexeme' in problem:         # e.g. '-p name' without :=
            problem = 'expected NAME:=VALUE'
        return f'cannot parse {match.group(1)!r}: {problem}'
    return str(ParamsFileError(match.group(1), problem, int(line.group(1)) if line else None))


def ros_args_problem(argv: Sequence[str]) -> str | None:
    """The first problem of the params files and -p overrides in argv (one line), or None."""
    for path in params_files_in(argv):
        try:
            check_params_file(path)
        except ParamsFileError as exc:
            return str(exc)
    from rclpy.utilities import remove_ros_args
    try:
        remove_ros_args(list(argv))
    except RuntimeError as exc:       # rclpy's RCLInvalidROSArgsError
        return rcl_problem(str(exc))
    return None


def report_ros_args_problem(argv: Sequence[str], name: str) -> int | None:
    """Before rclpy.init: a problem of the ROS arguments is printed as `[name] error: ...`
    (one line on stderr) and gives exit code 2; None: go on."""
    problem = ros_args_problem(argv)
    if problem is None:
        return None
    print(f'[{name}] error: {problem}', file=sys.stderr, flush=True)
    return 2
