"""The packages' layout (docs/architecture.md "Architecture"), read from the sources with ast (an
import inside a function counts):

(a) production code never imports test support: no installed module (a package's modules and
    launch files, test support modules excepted) imports a package's `testing` module;
(b) imports run one way: pam_model imports no ROS and no other pam package; pam_common only
    pam_model (and pam_interfaces); pam_estimator, pam_controller and pam_bringup nothing from
    pam_driver; nothing but pam_bringup imports pam_bringup (ALLOWED lists every arrow);
(c) one stamp conversion: no `sec * 1_000_000_000 + nanosec`, divmod(ns, 10**9) or `ns // 10**9`
    anywhere (packages, their tests, benchmarks, scripts) but pam_common/stamps.py;
(d) topic names and QoS profiles are written once: no node passes a string literal as a topic,
    no module but pam_common/qos.py builds a QoSProfile (bag_record and bag_play build theirs
    from what the publishers or the bag offer); the names are the stack's interface, pinned here;
(e) every node (a class deriving from rclpy's Node) goes through the skeleton: its main() calls
    node_main (or component_main, for a node module's COMPONENT), its parameters come from
    parameter_values, and nothing outside pam_common calls the pieces (declare_parameters,
    cli_preamble, wants_help, run_node, run_nodes) itself.

Each scanner is also run on a small bad source, so a check that cannot fail would show.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = sorted(p.parent.name for p in ROOT.glob('pam_*/package.xml'))
TEST_SUPPORT = 'testing'          # a package's test support module: tests only import it

#: Which pam packages each package's installed code may import (the layout's arrows).
ALLOWED = {
    'pam_model': set(),
    'pam_description': set(),
    'pam_interfaces': set(),
    'pam_common': {'pam_model', 'pam_interfaces'},
    'pam_bag': {'pam_model', 'pam_interfaces', 'pam_common'},
    'pam_driver': {'pam_model', 'pam_interfaces', 'pam_common'},
    'pam_estimator': {'pam_model', 'pam_interfaces', 'pam_common', 'pam_bag'},
    'pam_controller': {'pam_model', 'pam_interfaces', 'pam_common', 'pam_bag', 'pam_estimator'},
    'pam_bringup': {'pam_model', 'pam_interfaces', 'pam_common', 'pam_bag', 'pam_estimator',
                    'pam_controller'},
}
ROS_MODULES = {'rclpy', 'rcl_interfaces', 'builtin_interfaces', 'std_msgs', 'std_srvs',
               'diagnostic_msgs', 'rosgraph_msgs', 'sensor_msgs', 'geometry_msgs', 'launch',
               'launch_ros', 'ament_index_python', 'rosidl_parser', 'rosidl_runtime_py',
               'pam_interfaces'}
STAMPS = ROOT / 'pam_common' / 'pam_common' / 'stamps.py'
STAMP_FIELDS = {'sec', 'nanosec', 'secs', 'nsecs'}
QOS_MODULE = ROOT / 'pam_common' / 'pam_common' / 'qos.py'
#: Their subscriptions' or publishers' QoS follows what each recorded topic offers.
QOS_FROM_THE_BAG = {ROOT / 'pam_bag' / 'pam_bag' / 'bag_record.py',
                    ROOT / 'pam_bag' / 'pam_bag' / 'bag_play.py'}
NODES = {'sim_node', 'driver_node', 'ukf_node', 'pi_node', 'reference_node', 'profile_player',
         'bag_record', 'bag_play', 'tracking_report', 'foxglove_view'}
#: The skeleton's pieces: a node calls node_main and parameter_values, not these.
PIECES = {'declare_parameters', 'cli_preamble', 'wants_help', 'run_node', 'run_nodes'}


# ---------------------------------------------------------------------------- the files
def production_files(package: str) -> list[Path]:
    """The installed Python files of a package (its module tree and launch files), test support
    modules left out."""
    folder = ROOT / package
    files = sorted((folder / package).rglob('*.py')) + sorted((folder / 'launch').glob('*.py'))
    return [f for f in files if f.stem != TEST_SUPPORT and '__pycache__' not in f.parts]


def every_python_file() -> list[Path]:
    """Every Python file of the repository we write: packages (tests too), benchmarks, scripts."""
    places = [ROOT / p for p in PACKAGES] + [ROOT / 'benchmarks', ROOT / 'scripts']
    return sorted(f for place in places if place.is_dir() for f in place.rglob('*.py')
                  if '__pycache__' not in f.parts and 'build' not in f.relative_to(ROOT).parts)


def module_package(path: Path) -> str:
    """The dotted package a file's relative imports start from ('pam_driver' for
    pam_driver/pam_driver/sim_node.py)."""
    parts = path.relative_to(ROOT).parts
    if len(parts) > 2 and parts[0] == parts[1]:
        return '.'.join(parts[1:-1])
    return parts[0]


def parse(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), str(path))


# ---------------------------------------------------------------------------- the scanners
def imported_names(tree: ast.AST, package: str) -> set[str]:
    """Every module a tree imports, dotted, relative imports resolved against `package`;
    `from a import b` gives both 'a' and 'a.b' (b may be a module)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split('.')
                base = base[:len(base) - node.level + 1]
                module = '.'.join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            names.add(module)
            names.update(f'{module}.{alias.name}' for alias in node.names)
    return names


def imports_of_test_support(tree: ast.AST, package: str) -> list[str]:
    """(a): the test support modules imported."""
    return sorted({'.'.join(name.split('.')[:2]) for name in imported_names(tree, package)
                   if name.startswith('pam_') and name.split('.')[1:2] == [TEST_SUPPORT]})


def wrong_way_imports(tree: ast.AST, package: str) -> list[str]:
    """(b): the imports of `package`'s code that do not run one way."""
    top = package.split('.')[0]
    wrong = set()
    for name in imported_names(tree, package):
        first = name.split('.')[0]
        if first.startswith('pam_') and first != top and first not in ALLOWED[top]:
            wrong.add(first)
        if top == 'pam_model' and first in ROS_MODULES:
            wrong.add(first)
    return sorted(wrong)


def _is_ns_per_s(node: ast.AST) -> bool:
    if isinstance(node, ast.Constant) and not isinstance(node.value, bool):
        return node.value in (1_000_000_000, 1e9)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
        return (isinstance(node.left, ast.Constant) and node.left.value == 10
                and isinstance(node.right, ast.Constant) and node.right.value == 9)
    return isinstance(node, ast.Name) and node.id == 'NS_PER_S'


def _names_a_stamp_field(node: ast.AST) -> bool:
    return any((isinstance(n, ast.Attribute) and n.attr in STAMP_FIELDS)
               or (isinstance(n, ast.Name) and n.id in STAMP_FIELDS) for n in ast.walk(node))


def _converts_a_stamp(node: ast.AST) -> bool:
    """sec * 1e9 + nanosec (a sum naming a stamp's field), divmod(x, 1e9), x // 1e9, x % 1e9."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        return _names_a_stamp_field(node) and any(
            isinstance(side, ast.BinOp) and isinstance(side.op, ast.Mult)
            and (_is_ns_per_s(side.left) or _is_ns_per_s(side.right))
            for side in (node.left, node.right))
    if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.FloorDiv, ast.Mod)):
        return _is_ns_per_s(node.right)
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            and node.func.id == 'divmod' and len(node.args) == 2 and _is_ns_per_s(node.args[1]))


def stamp_conversions(tree: ast.AST) -> list[int]:
    """(c): the lines that convert a stamp (1e9 written 10**9, 1_000_000_000 or NS_PER_S too)."""
    return sorted({node.lineno for node in ast.walk(tree) if _converts_a_stamp(node)})


def _called(node: ast.AST) -> str | None:
    """The name a call calls (f(...) or x.f(...))."""
    if isinstance(node, ast.Call):
        if isinstance(node.func, ast.Name):
            return node.func.id
        if isinstance(node.func, ast.Attribute):
            return node.func.attr
    return None


def literal_topics(tree: ast.AST) -> list[int]:
    """(d): lines creating a publisher or subscription with a string literal as its topic."""
    lines = []
    for node in ast.walk(tree):
        if _called(node) in ('create_publisher', 'create_subscription'):
            topic = node.args[1] if len(node.args) > 1 else next(
                (k.value for k in node.keywords if k.arg == 'topic'), None)
            if isinstance(topic, (ast.Constant, ast.JoinedStr)):
                lines.append(node.lineno)
    return lines


def qos_profiles_built(tree: ast.AST) -> list[int]:
    """(d): lines building a QoSProfile."""
    return [node.lineno for node in ast.walk(tree) if _called(node) == 'QoSProfile']


#: the node base classes: rclpy's Node, and pam_common.links' LinkedNode (a Node that takes
#: part in a composed process's in-process links), which defines no node of its own
NODE_BASES = {'Node', 'LinkedNode'}


def node_classes(tree: ast.AST) -> list[str]:
    """The node classes: deriving from rclpy's Node or pam_common.links.LinkedNode (not
    LinkedNode itself)."""
    return [node.name for node in ast.walk(tree) if isinstance(node, ast.ClassDef)
            and node.name not in NODE_BASES
            and any(isinstance(b, ast.Name) and b.id in NODE_BASES for b in node.bases)]


def skeleton_problems(tree: ast.AST) -> list[str]:
    """(e): how a node module departs from the skeleton."""
    problems = []
    main = next((node for node in tree.body if isinstance(node, ast.FunctionDef)
                 and node.name == 'main'), None)
    if main is None or not {'node_main', 'component_main'} & {_called(n) for n in ast.walk(main)}:
        problems.append('main() does not call node_main')
    calls = {_called(n) for n in ast.walk(tree)}
    if 'parameter_values' not in calls:
        problems.append('its parameters do not come from parameter_values')
    problems += [f'calls {piece} itself' for piece in sorted(PIECES & calls)]
    return problems


# ---------------------------------------------------------------------------- the scanners fail
BAD = '''
import rclpy
from pam_common.testing import probe
from pam_driver import sim_node
from .. import testing
stamp = msg.sec * 1_000_000_000 + msg.nanosec
sec, nanosec = divmod(ns, 10**9)
sec = ns // 1e9
pub = node.create_publisher(Pressures, 'pressures', QoSProfile(depth=10))
def main():
    if wants_help(sys.argv):
        return 0
    return run_node(Thing, 'thing')
class Thing(Node):
    def __init__(self):
        self.values = declare_parameters(self, PARAMETERS)
'''


def test_the_scanners_find_each_violation():
    tree = ast.parse(BAD)
    assert imports_of_test_support(tree, 'pam_controller.sub') == [
        'pam_common.testing', 'pam_controller.testing']
    assert wrong_way_imports(tree, 'pam_estimator') == ['pam_driver']
    assert wrong_way_imports(tree, 'pam_model') == ['pam_common', 'pam_driver', 'rclpy']
    assert wrong_way_imports(tree, 'pam_common') == ['pam_driver']
    assert stamp_conversions(tree) == [6, 7, 8]
    assert literal_topics(tree) == [9]
    assert qos_profiles_built(tree) == [9]
    assert node_classes(tree) == ['Thing']
    assert skeleton_problems(tree) == [
        'main() does not call node_main', 'its parameters do not come from parameter_values',
        'calls declare_parameters itself', 'calls run_node itself', 'calls wants_help itself']


def test_the_scanners_pass_good_code():
    good = ast.parse('from pam_common.stamps import stamp_ns\nt = stamp_ns(msg.header.stamp)\n'
                     'end = start + k * 2 * 10**9\nspan = hold * 1e9\n'
                     'pub = node.create_publisher(Pressures, PRESSURES, SAMPLE_QOS)\n'
                     'def main(args=None):\n    return node_main(N, "n", "usage", args)\n'
                     'values = parameter_values(node, PARAMETERS)\n')
    assert imports_of_test_support(good, 'pam_driver') == []
    assert wrong_way_imports(good, 'pam_bag') == []
    assert stamp_conversions(good) == []
    assert literal_topics(good) == [] and qos_profiles_built(good) == []
    assert skeleton_problems(good) == []


# ---------------------------------------------------------------------------- the tree
def test_the_packages_are_the_ones_the_arrows_name():
    assert set(PACKAGES) == set(ALLOWED)


@pytest.mark.parametrize('package', PACKAGES)
def test_production_code_never_imports_test_support(package):
    found = {str(f.relative_to(ROOT)): imports_of_test_support(parse(f), module_package(f))
             for f in production_files(package)}
    assert not {f: names for f, names in found.items() if names}


@pytest.mark.parametrize('package', PACKAGES)
def test_imports_run_one_way(package):
    found = {str(f.relative_to(ROOT)): wrong_way_imports(parse(f), module_package(f))
             for f in production_files(package)}
    assert not {f: names for f, names in found.items() if names}


def test_one_stamp_conversion():
    files = every_python_file()
    assert STAMPS in files and stamp_conversions(parse(STAMPS))    # it is seen where it is
    found = {str(f.relative_to(ROOT)): stamp_conversions(parse(f)) for f in files if f != STAMPS}
    assert not {f: lines for f, lines in found.items() if lines}


def topic_and_qos_problems(path: Path) -> list[str]:
    """(d) for one file."""
    tree = parse(path)
    problems = [f'line {line}: a topic name as a literal' for line in literal_topics(tree)]
    if path != QOS_MODULE and path not in QOS_FROM_THE_BAG:
        problems += [f'line {line}: a QoSProfile built' for line in qos_profiles_built(tree)]
    return problems


@pytest.mark.parametrize('package', PACKAGES)
def test_topic_names_and_qos_are_written_once(package):
    found = {str(f.relative_to(ROOT)): topic_and_qos_problems(f)
             for f in production_files(package)}
    assert not {f: problems for f, problems in found.items() if problems}


def test_the_topic_names_and_profiles_stay_as_they_are():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

    from pam_common import qos, topics
    assert (topics.DEFAULT_NAMESPACE, topics.PRESSURES, topics.JOINT_MEASURED,
            topics.VALVE_COMMAND, topics.ESTIMATE, topics.CONTROLLER_STATE, topics.REFERENCE,
            topics.APPLIED_COMMAND, topics.DIAGNOSTICS, topics.CLOCK) == (
        '/pam', 'pressures', 'joint_measured', 'valve_command', 'estimate', 'controller_state',
        'reference', '~/applied_command', '/diagnostics', '/clock')
    assert (topics.JOINT_STATES, topics.ESTIMATE_JOINT_STATES) == (
        'joint_states', 'estimate/joint_states')          # sensor_msgs/JointState
    assert topics.absolute(topics.PRESSURES) == '/pam/pressures'
    assert topics.absolute(topics.ESTIMATE, '/x/') == '/x/estimate'
    assert topics.absolute(topics.CLOCK, '/x') == '/clock'
    for profile, depth in ((qos.SAMPLE_QOS, 100), (qos.LATEST_QOS, 10), (qos.CLOCK_QOS, 10),
                           (qos.RECORD_QOS, 5000)):
        assert (profile.reliability, profile.history, profile.depth, profile.durability) == (
            ReliabilityPolicy.RELIABLE, HistoryPolicy.KEEP_LAST, depth,
            DurabilityPolicy.VOLATILE)


def node_modules() -> dict[str, Path]:
    """Every module that defines a node, by module name."""
    return {f.stem: f for package in PACKAGES for f in production_files(package)
            if node_classes(parse(f))}


def test_the_nodes_are_found():
    assert set(node_modules()) == NODES


@pytest.mark.parametrize('node', sorted(NODES))
def test_every_node_goes_through_the_skeleton(node):
    path = node_modules()[node]
    assert skeleton_problems(parse(path)) + topic_and_qos_problems(path) == []


def test_nothing_outside_pam_common_calls_the_pieces_itself():
    found = {}
    for package in PACKAGES:
        if package == 'pam_common':
            continue
        for f in production_files(package):
            calls = {_called(n) for n in ast.walk(parse(f))} & PIECES
            if calls:
                found[str(f.relative_to(ROOT))] = sorted(calls)
    assert not found


# ---------------------------------------------------------------------------- configs and cores
#: The 1 kHz nodes' shape: a frozen config dataclass built once from the parameter table (its
#: module and class) and the cores that hold the decisions (their modules), all without ROS, so
#: they are tested by calling them (no spinning).
CONFIG_AND_CORE = {
    'sim_node': ('pam_driver/pam_driver/sim_config.py', 'SimConfig',
                 'pam_driver/pam_driver/sim_core.py'),
    'ukf_node': ('pam_estimator/pam_estimator/ukf_config.py', 'UkfConfig',
                 'pam_estimator/pam_estimator/estimator_core.py'),
    'pi_node': ('pam_controller/pam_controller/pi_config.py', 'PiConfig',
                'pam_controller/pam_controller/control_loop.py'),
    'driver_node': ('pam_driver/pam_driver/driver_config.py', 'DriverConfig',
                    'pam_driver/pam_driver/driver_core.py',
                    'pam_driver/pam_driver/serial_session.py',
                    'pam_driver/pam_driver/driver_health.py'),
}
#: pam_common's modules a ROS-free config or core may import (they import no ROS themselves)
ROS_FREE_COMMON = {'pam_common.node_params', 'pam_common.realtime_knobs', 'pam_common.realtime',
                   'pam_common.levels',
                   'pam_common.joint_states', 'pam_common.joint_description',
                   'pam_common.sample_gaps', 'pam_common.latency', 'pam_common.run_health',
                   'pam_common.timing', 'pam_common'}


#: ROS as a runtime: ament_index_python (a file lookup in the install's index, used lazily for
#: the URDF's joint name: pam_common.joint_description) runs without it
ROS_RUNTIME = ROS_MODULES - {'ament_index_python'}


def ros_imports(tree: ast.AST, package: str) -> list[str]:
    """The ROS modules (ROS_RUNTIME), and the pam_common modules outside ROS_FREE_COMMON, a
    tree imports."""
    found = set()
    for name in imported_names(tree, package):
        first = name.split('.')[0]
        if first in ROS_RUNTIME:
            found.add(first)
        elif first == 'pam_common' and '.'.join(name.split('.')[:2]) not in ROS_FREE_COMMON:
            found.add('.'.join(name.split('.')[:2]))
    return sorted(found)


def frozen_dataclasses(tree: ast.AST) -> set[str]:
    """The classes decorated @dataclass(frozen=True)."""
    return {node.name for node in ast.walk(tree) if isinstance(node, ast.ClassDef) and any(
        isinstance(d, ast.Call) and getattr(d.func, 'id', None) == 'dataclass'
        and any(k.arg == 'frozen' and getattr(k.value, 'value', False) for k in d.keywords)
        for d in node.decorator_list)}


def test_the_config_and_core_scanners_fail():
    bad = ast.parse('import rclpy\nfrom pam_common.diagnostics import OK\n'
                    'from dataclasses import dataclass\n@dataclass\nclass C:\n    x: int\n')
    assert ros_imports(bad, 'pam_driver') == ['pam_common.diagnostics', 'rclpy']
    assert frozen_dataclasses(bad) == set()
    good = ast.parse('from pam_common.levels import OK\nfrom dataclasses import dataclass\n'
                     '@dataclass(frozen=True)\nclass C:\n    x: int\n')
    assert ros_imports(good, 'pam_driver') == [] and frozen_dataclasses(good) == {'C'}


def import_time(tree: ast.Module) -> ast.Module:
    """What runs when the module is imported: its statements without the functions' bodies."""
    class Strip(ast.NodeTransformer):
        def visit_FunctionDef(self, node):
            return None
        visit_AsyncFunctionDef = visit_FunctionDef
    return Strip().visit(tree)


def test_the_ros_free_common_modules_import_no_ros():
    """Importing them loads no ROS (some of their functions, which only nodes call, do)."""
    assert ros_imports(import_time(ast.parse('def f():\n    import rclpy\n')), 'x') == []
    for name in sorted(ROS_FREE_COMMON - {'pam_common'}):
        path = ROOT / 'pam_common' / 'pam_common' / f"{name.split('.')[1]}.py"
        assert ros_imports(import_time(parse(path)), 'pam_common') == [], name


@pytest.mark.parametrize('node', sorted(CONFIG_AND_CORE))
def test_every_1khz_node_has_a_frozen_config_and_a_ros_free_core(node):
    config_file, config_class, *core_files = (ROOT / p if p.endswith('.py') else p
                                              for p in CONFIG_AND_CORE[node])
    assert config_class in frozen_dataclasses(parse(config_file))
    for path in {config_file, *core_files}:
        assert ros_imports(parse(path), module_package(path)) == [], path


@pytest.mark.parametrize('node', sorted(NODES))
def test_no_node_keeps_its_parameters_in_a_dict(node):
    """Each node reads its parameters from its frozen config (self.config.<name>), built once by
    its check (parameter_values(..., check=build_config)), not from a mutable dict of values."""
    text = node_modules()[node].read_text()
    assert 'self.values =' not in text and "self.values['" not in text, node
    assert 'parameter_values(self, PARAMETERS, check=' in text, node
