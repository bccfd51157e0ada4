"""The stack's params file made to apply in another namespace (pam-bringup --namespace, the
launch file's namespace:=). No launch import: the launch file and pam-bringup both call
stack_params() (which checks the file as every node does: pam_common.params_files, rcl's parse
through rclpy.utilities, no ROS context).

The stack's params files key each node's section by its full name in the default namespace
(`/pam/sim_node:`). rcl matches the keys against the node's full name, so with the stack in
/joint2 no such section applies and the nodes run on their defaults. for_namespace() writes the
file again for the namespace, and every node gets that copy with --params-file instead:

- a section keyed under the default namespace (`/pam/<node>`, `/pam/*`, nested
  `pam: {<node>: ...}`) is re-keyed to the namespace (`/joint2/<node>`), in its place;
- every other section is kept as it is: `/**`, `/**/<node>`, `/*/<node>`, and the sections of
  other explicit namespaces (`/joint3/sim_node` still applies in /joint3 only);
- where the file has its own section for the namespace (`/joint2/sim_node:`), that section's
  parameters win over the re-keyed default one's, wherever the two stand in the file (the two
  are then one section, at the place of the first of them, as rcl makes of a key given twice).

rcl's rules this keeps (rcl_yaml_param_parser; rclpy's Node.get_parameters): all the params files
of a node are parsed into one table of sections, in order of each key's first appearance (a key
given again adds to its section; a parameter given again takes the later value); the node then
takes, in that order, every section whose key matches its full name, a later one overriding an
earlier one. Specificity plays no part: of `/**/sim_node:` and `/joint2/sim_node:` in one file
the one further down wins. A re-keyed section keeps its place, so it stands against the `/**`
sections as the default one did. The copy has one flat key per section (`pam: {sim_node:}`
becomes `/pam/sim_node:`, or its re-keyed name; keys that differ only by the leading '/' are one
section) and dotted parameter names (`gains: {kp: 1}` becomes `gains.kp: 1`, as rcl reads it);
every value keeps its YAML text and style, so rcl types it as before. Comments are not kept.
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from pam_common.params_files import PARAMETERS_KEY, check_params_file, ros_args_problem

from .params_sections import section_warning
from .stack import DEFAULT_NAMESPACE, normal_namespace

_STR = 'tag:yaml.org,2002:str'
_MAP = 'tag:yaml.org,2002:map'


def rekeyed(key: str, namespace: str, default: str = DEFAULT_NAMESPACE) -> str | None:
    """`key` (a section key, leading '/' optional) moved from namespace `default` to
    `namespace` ('/pam/sim_node' -> '/joint2/sim_node'); None for a key that is not under
    `default` (`/**`, `/**/sim_node`, `/joint3/sim_node`, `/pam` itself). Both namespaces as
    normal_namespace() writes them."""
    tokens = [t for t in key.split('/') if t]
    base = [t for t in default.split('/') if t]
    if len(tokens) <= len(base) or tokens[:len(base)] != base:
        return None
    return '/' + '/'.join([t for t in namespace.split('/') if t] + tokens[len(base):])


def _parameters(mapping, prefix: str = '') -> list:
    """(dotted name, value node) of every parameter below a ros__parameters mapping node."""
    import yaml
    out = []
    for key, value in mapping.value:
        name = prefix + key.value
        if isinstance(value, yaml.MappingNode):
            out += _parameters(value, name + '.')
        else:
            out.append((name, value))
    return out


def _sections(mapping, names: list[str]) -> list:
    """(key with a leading '/', [(parameter, value node)]) of every section below `mapping`,
    in file order (a file check_params_file passed)."""
    import yaml
    out = []
    for key, value in mapping.value:
        if key.value == PARAMETERS_KEY:
            out.append(('/' + '/'.join(n.strip('/') for n in names).strip('/'),
                        _parameters(value)))
        elif isinstance(value, yaml.MappingNode):
            out += _sections(value, [*names, key.value])
    return out


def file_sections(path) -> list:
    """The sections of a params file, every document in order: (key, [(parameter, value
    node)]); ParamsFileError (a ValueError: one line, with the line number where there is one)
    for a file that is not laid out as rcl expects (check_params_file)."""
    import yaml
    check_params_file(path)
    text = Path(path).read_text(encoding='utf-8')
    loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
    sections = []
    for root in yaml.compose_all(text, Loader=loader):
        if root is not None:
            sections += _sections(root, [])
    return sections


def for_namespace(sections: list, namespace: str,
                  default: str = DEFAULT_NAMESPACE) -> tuple[dict, list[str]]:
    """The sections as they apply in `namespace`: ({key: {parameter: value node}} in rcl's
    order, the keys re-keyed from `default`). A section of the file for the re-keyed key itself
    wins, parameter by parameter, over the re-keyed one."""
    explicit: dict[str, set] = {}
    for key, params in sections:
        if rekeyed(key, namespace, default) is None:
            explicit.setdefault(key, set()).update(name for name, _ in params)
    table: dict[str, dict] = {}
    moved = []
    for key, params in sections:
        new_key = rekeyed(key, namespace, default)
        if new_key is None:
            table.setdefault(key, {}).update(params)
            continue
        if key not in moved:
            moved.append(key)
        own = explicit.get(new_key, set())
        table.setdefault(new_key, {}).update((n, v) for n, v in params if n not in own)
    return table, moved


def params_yaml(table: dict, header: str = '') -> str:
    """YAML text of a section table (for_namespace): one flat key per section, the values
    written back from their nodes unchanged."""
    import yaml

    def scalar(text):
        return yaml.ScalarNode(_STR, text)

    root = yaml.MappingNode(_MAP, [
        (scalar(key), yaml.MappingNode(_MAP, [(scalar(PARAMETERS_KEY), yaml.MappingNode(
            _MAP, [(scalar(name), value) for name, value in params.items()]))]))
        for key, params in table.items()])
    dumper = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)
    return header + yaml.serialize(root, Dumper=dumper, width=100)


@dataclass(frozen=True)
class StackParams:
    """The params file every node of a stack gets, and what to tell the user about it."""

    #: the file for --params-file: the user's own file, or its copy for the namespace
    file: Path
    #: the user's file
    source: Path
    #: keys of the user's file re-keyed to the namespace (empty: `file` is `source`)
    moved: tuple[str, ...]
    #: one line per node no section (but `/**`) applies to (params_sections.section_warning)
    warnings: tuple[str, ...]

    def describe(self) -> str:
        """'params file F' (, with its sections moved to the namespace: the copy)."""
        if not self.moved:
            return f'params file {self.source}'
        return (f'params file {self.source} (its {", ".join(self.moved)} applied to the '
                f'namespace: {self.file})')


def stack_params(params_file, namespace: str, node_names, directory: Path,
                 default: str = DEFAULT_NAMESPACE) -> StackParams:
    """The params file for the stack's nodes `node_names` in `namespace`: `params_file` itself in
    the default namespace or when none of its sections is under the default one, else its copy
    for the namespace written into `directory` (a per-run directory the caller removes at exit).
    ValueError (one line) for an invalid namespace or a params file rcl would refuse."""
    source = Path(params_file)
    namespace = normal_namespace(namespace)
    default = normal_namespace(default)
    problem = ros_args_problem(['pam_bringup', '--ros-args', '--params-file', str(source)])
    if problem is not None:       # the nodes' own check, naming the user's file, not the copy
        raise ValueError(problem)
    sections = file_sections(source)
    moved: list[str] = []
    file = source
    keys = [key for key, _ in sections]
    if namespace != default:
        table, moved = for_namespace(sections, namespace, default)
        if moved:
            label = namespace.strip('/').replace('/', '.') or 'root'
            file = Path(directory) / f'{source.stem}.{label}.yaml'
            file.write_text(params_yaml(table, (
                f'# {source} for the namespace {namespace}: its sections under {default} '
                f're-keyed (pam_bringup.params_namespace)\n')), encoding='utf-8')
            keys = list(table)
    base = '' if namespace == '/' else namespace
    warnings = [w for w in (section_warning(f'{base}/{name}', keys) for name in node_names)
                if w is not None]
    return StackParams(file, source, tuple(moved), tuple(warnings))


def run_directory(prefix: str) -> Path:
    """A new temporary directory, removed when this process exits (atexit): for the copies of a
    launch's params files."""
    path = Path(tempfile.mkdtemp(prefix=prefix))
    atexit.register(shutil.rmtree, path, ignore_errors=True)
    return path
