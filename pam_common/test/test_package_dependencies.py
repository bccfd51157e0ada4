"""Each package.xml declares what its package's code needs, and nothing else, with the rosdep key
(Jazzy, Ubuntu 24.04) that installs it: the imports of the installed code (and the packages it
names to run or to find: `node_process('sim_node', 'pam_driver')`, `Node(package=...)`) as
exec_depend or depend, those of the tests (the package's test/ folder and its test support
module testing.py, with what the other packages' test support modules it imports need) as
test_depend unless exec already has them (REP 149: a test_depend does not repeat an exec key).
Found by reading the sources with ast, so a lazy import inside a function counts too. A declared
key nothing needs fails as well, except the build tools (TOOL_KEYS). pam_interfaces (rosidl) is
held against the types its .msg files use. Test dependencies form no cycle with the others: colcon
orders the packages by every dependency, test ones included, and refuses a cycle."""

from __future__ import annotations

import ast
import collections
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = sorted(p.parent for p in ROOT.glob('*/package.xml'))
WORKSPACE = frozenset(p.name for p in PACKAGES)

#: Python module (top level) -> the rosdep key of what installs it (rosdistro python.yaml /
#: base.yaml for Jazzy; the *-pip keys install from PyPI; python3-foxglove-sdk-pip,
#: python3-mcap-pip, python3-mcap-ros2-support-pip and python3-zstandard are ours:
#: rosdep/pam.yaml).
PYTHON_KEYS = {
    'catkin_pkg': 'python3-catkin-pkg',
    'filterpy': 'python3-filterpy-pip',
    'foxglove': 'python3-foxglove-sdk-pip',
    'matplotlib': 'python3-matplotlib',
    'mcap': 'python3-mcap-pip',
    'mcap_ros2': 'python3-mcap-ros2-support-pip',
    'numba': 'python3-numba',
    'numpy': 'python3-numpy',
    'pytest': 'python3-pytest',
    'rosbags': 'python3-rosbags-pip',
    'rosdep2': 'python3-rosdep',
    'ruamel': 'python3-ruamel.yaml',
    'ruff': 'python3-ruff-pip',
    'scipy': 'python3-scipy',
    'serial': 'python3-serial',
    'websockets': 'python3-websockets',
    'yaml': 'python3-yaml',
    'yourdfpy': 'python3-yourdfpy-pip',
    'zstandard': 'python3-zstandard',
}
#: ROS packages (released for Jazzy) imported by their package name: the key is that name.
ROS_PACKAGES = frozenset({
    'ament_index_python', 'builtin_interfaces', 'diagnostic_msgs', 'geometry_msgs', 'launch',
    'launch_ros', 'rcl_interfaces', 'rclpy', 'rosgraph_msgs', 'rosidl_parser', 'sensor_msgs',
    'std_msgs', 'std_srvs'})
#: Declared for the build or the layout, never imported: no use to find in the code.
TOOL_KEYS = frozenset({'ament_cmake', 'rosidl_default_generators', 'rosidl_default_runtime'})
#: Calls that run a package's executable or read its installed files, given the package's name.
RUNS_OR_FINDS = frozenset({
    'node_process', 'NodeProcess', 'executable', 'find_executable', 'installed_config',
    'assert_node_refuses_params_file', 'Node', 'NodeSpec', 'FindPackageShare',
    'get_package_share_directory', 'get_package_prefix'})
TEST_SUPPORT = 'testing.py'     # a package's test support module: tests only import it
NOT_SCANNED = {'setup.py'}      # build files: setuptools is the build type's, not a dependency


@dataclass
class Needs:
    """What a package's code needs: key -> the files (relative to the repository) needing it."""

    exec: dict = field(default_factory=lambda: collections.defaultdict(set))
    test: dict = field(default_factory=lambda: collections.defaultdict(set))
    unknown: list = field(default_factory=list)     # 'file: module' with no key in the tables


def key_for(module: str) -> str | None:
    """The rosdep key of top-level module `module`; None for the standard library; KeyError if
    neither table knows it."""
    if module in sys.stdlib_module_names:
        return None
    if module in ROS_PACKAGES or module in WORKSPACE:
        return module
    return PYTHON_KEYS[module]


def imported_modules(tree: ast.AST) -> set[str]:
    """Top-level names of every absolute import in `tree` (in functions too)."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {alias.name.split('.')[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split('.')[0])
    return found


def support_imports(tree: ast.AST) -> set[str]:
    """The workspace packages whose test support module (`<package>.testing`) `tree` imports."""
    found = set()
    for node in ast.walk(tree):
        names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                 [f'{node.module}.{a.name}' for a in node.names] + [node.module]
                 if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else [])
        found |= {n.split('.')[0] for n in names
                  if n.split('.')[:2] == [n.split('.')[0], 'testing']}
    return found & WORKSPACE


def named_packages(tree: ast.AST) -> set[str]:
    """Workspace packages the code runs or whose installed files it reads: a string constant
    equal to a package name given to a call of RUNS_OR_FINDS (`node_process('sim_node',
    'pam_driver')`, `Node(package='pam_driver')`, `get_package_share_directory(...)`) or joined
    into an installed path after 'share' or 'lib' (`prefix / 'share' / 'pam_interfaces'`).
    Names held as data (tests reading the source tree) do not count."""
    values = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and (getattr(node.func, 'id', None) or
                                           getattr(node.func, 'attr', None)) in RUNS_OR_FINDS:
            values += [*node.args, *(k.value for k in node.keywords)]
        elif (isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div)
              and isinstance(node.left, ast.BinOp) and isinstance(node.left.right, ast.Constant)
              and node.left.right.value in ('share', 'lib')):
            values.append(node.right)
    return {v.value for v in values
            if isinstance(v, ast.Constant) and isinstance(v.value, str)} & WORKSPACE


def python_files(folder: Path) -> tuple[list[Path], list[Path]]:
    """(installed code, test code) of an ament_python package folder: the test code is its
    test/ folder and its test support module(s)."""
    installed, tests = [], []
    for path in sorted(folder.rglob('*.py')):
        parts = path.relative_to(folder).parts
        if (parts[0] in ('build', 'install', 'log')
                or (parts[-1] in NOT_SCANNED and len(parts) == 1)):
            continue
        if any(p.endswith('.egg-info') or p == '__pycache__' for p in parts):
            continue
        (tests if parts[0] == 'test' or parts[-1] == TEST_SUPPORT else installed).append(path)
    return installed, tests


def support_needs(package: str) -> set[str]:
    """Keys the test support module of workspace package `package` needs besides the package
    and what comes with it (its exec dependencies): those a test importing it must declare."""
    path = ROOT / package / package / TEST_SUPPORT
    if not path.is_file():
        return set()
    tree = ast.parse(path.read_text(), str(path))
    keys = {key_for(m) for m in imported_modules(tree) if m != package} - {None}
    return (keys | named_packages(tree)) - {package} - declared(ROOT / package)[0]


def scan(folder: Path) -> Needs:
    """What the Python code of the package in `folder` needs."""
    needs = Needs()
    installed, tests = python_files(folder)
    for path in installed + tests:
        where = needs.test if path in tests else needs.exec
        rel = str(path.relative_to(folder.parent))
        tree = ast.parse(path.read_text(), str(path))
        local = {p.stem for p in path.parent.glob('*.py')} if path in tests else set()
        for module in imported_modules(tree) - local - {folder.name}:
            try:
                key = key_for(module)
            except KeyError:
                needs.unknown.append(f'{rel}: import {module}')
                continue
            if key is not None:
                where[key].add(rel)
        for package in named_packages(tree) - {folder.name}:
            where[package].add(rel)
        if path in tests:
            for package in support_imports(tree) - {folder.name}:
                for key in support_needs(package):
                    needs.test[key].add(f'{rel} (via {package}.testing)')
    return needs


def msg_needs(folder: Path) -> dict:
    """Packages whose types the .msg files of the interface package in `folder` use."""
    needs = collections.defaultdict(set)
    for path in sorted((folder / 'msg').glob('*.msg')):
        for line in path.read_text().splitlines():
            field_type = line.split('#')[0].split()[:1]
            if field_type and '/' in field_type[0]:
                needs[field_type[0].split('/')[0]].add(str(path.relative_to(folder.parent)))
    return needs


def declared(folder: Path):
    from catkin_pkg.package import parse_package
    package = parse_package(folder / 'package.xml')
    return ({d.name for d in package.exec_depends}, {d.name for d in package.test_depends},
            {d.name for d in package.build_depends})


def manifest_problems(folder: Path) -> list[str]:
    """One line per difference between the package.xml in `folder` and what its code needs."""
    exec_keys, test_keys, build_keys = declared(folder)
    xml = f'{folder.name}/package.xml'
    problems = []
    if not (folder / 'setup.py').exists():       # ament_cmake interface package
        for key, files in sorted(msg_needs(folder).items()):
            if key not in build_keys or key not in exec_keys:
                problems.append(f'{xml}: <depend>{key}</depend> missing (used by '
                                f'{", ".join(sorted(files))})')
        for key in sorted((exec_keys | build_keys) - TOOL_KEYS - set(msg_needs(folder))):
            problems.append(f'{xml}: {key} declared, but no message uses it')
        return problems
    needs = scan(folder)
    problems += [f'{u}: no rosdep key known (add the module to PYTHON_KEYS or ROS_PACKAGES of '
                 f'{Path(__file__).name})' for u in needs.unknown]
    for key, files in sorted(needs.exec.items()):
        if key not in exec_keys:
            problems.append(f'{xml}: <exec_depend>{key}</exec_depend> missing (imported or run '
                            f'by {", ".join(sorted(files))})')
    for key, files in sorted(needs.test.items()):
        if key not in exec_keys | test_keys:
            problems.append(f'{xml}: <test_depend>{key}</test_depend> missing (imported or run '
                            f'by {", ".join(sorted(files))})')
    for key in sorted(exec_keys - TOOL_KEYS - set(needs.exec)):
        problems.append(f'{xml}: exec_depend {key} declared, but no installed code imports or '
                        'runs it' + (' (only tests: make it a test_depend)'
                                     if key in needs.test else ''))
    for key in sorted(test_keys - set(needs.test)):
        problems.append(f'{xml}: test_depend {key} declared, but no test imports or runs it')
    for key in sorted(test_keys & exec_keys):
        problems.append(f'{xml}: {key} is both an exec and a test dependency (REP 149: the '
                        'exec one suffices)')
    return problems


@pytest.mark.parametrize('folder', PACKAGES, ids=lambda p: p.name)
def test_package_xml_declares_what_the_code_needs(folder):
    problems = manifest_problems(folder)
    assert not problems, '\n'.join(problems)


def colcon_order_problems(packages) -> list[str]:
    """What colcon would refuse to order: it makes a package wait for its direct dependencies of
    every kind (test ones too) and, from there on, their exec dependencies (recursively); two
    packages that wait for each other are a cycle. `packages`: the parsed package.xml files."""
    def names(deps):
        return {d.name for d in deps} & {p.name for p in packages}
    direct = {p.name: names([*p.build_depends, *p.buildtool_depends, *p.exec_depends,
                             *p.test_depends]) for p in packages}
    run = {p.name: names(p.exec_depends) for p in packages}
    waits = {}
    for name, deps in direct.items():
        seen, queue = set(), list(deps)
        while queue:
            dep = queue.pop()
            if dep not in seen and dep != name:
                seen.add(dep)
                queue += run[dep]
        waits[name] = seen
    return [f'{a} and {b} wait for each other (a test or exec dependency of one on the other)'
            for a in sorted(waits) for b in sorted(waits[a]) if a < b and a in waits[b]]


def test_colcon_can_order_the_packages():
    """A test of pam_controller that ran pam-bringup (which runs pi_node) would make
    pam_controller and pam_bringup each wait for the other: colcon stops with 'Unable to order
    packages topologically'."""
    from catkin_pkg.package import parse_package
    problems = colcon_order_problems([parse_package(p / 'package.xml') for p in PACKAGES])
    assert not problems, '\n'.join(problems)


def test_the_order_check_finds_a_test_dependency_cycle():
    from catkin_pkg.package import Dependency, Package
    controller = Package(name='controller', exec_depends=[Dependency('estimator')],
                         test_depends=[Dependency('bringup')])
    bringup = Package(name='bringup', exec_depends=[Dependency('controller')])
    estimator = Package(name='estimator')
    assert colcon_order_problems([controller, bringup, estimator]) == [
        'bringup and controller wait for each other (a test or exec dependency of one on the '
        'other)']
    controller.test_depends = []
    assert colcon_order_problems([controller, bringup, estimator]) == []


# --------------------------------------------------------------------- the check itself
PACKAGE_XML = """<?xml version="1.0"?>
<package format="3">
  <name>{name}</name><version>0.1.0</version><description>d</description>
  <maintainer email="m@x.invalid">m</maintainer><license>Apache-2.0</license>
  {deps}
  <export><build_type>ament_python</build_type></export>
</package>
"""


def make_package(tmp_path: Path, deps: str, files: dict) -> Path:
    """A package pam_demo in `tmp_path` with the dependencies `deps` and the files `files`."""
    folder = tmp_path / 'pam_demo'
    for name, text in {'package.xml': PACKAGE_XML.format(name='pam_demo', deps=deps),
                       'setup.py': 'import setuptools\n', **files}.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text)
    return folder


def test_the_check_names_a_missing_key_and_its_importing_file(tmp_path):
    folder = make_package(tmp_path, '<exec_depend>rclpy</exec_depend>', {
        'pam_demo/__init__.py': '',
        'pam_demo/node.py': 'import rclpy\n\ndef f():\n    import numpy as np\n    return np\n',
        'pam_demo/tool.py': 'from ruamel.yaml import YAML\nfrom std_msgs.msg import Header\n'})
    assert manifest_problems(folder) == [
        'pam_demo/package.xml: <exec_depend>python3-numpy</exec_depend> missing (imported or run '
        'by pam_demo/pam_demo/node.py)',
        'pam_demo/package.xml: <exec_depend>python3-ruamel.yaml</exec_depend> missing (imported '
        'or run by pam_demo/pam_demo/tool.py)',
        'pam_demo/package.xml: <exec_depend>std_msgs</exec_depend> missing (imported or run by '
        'pam_demo/pam_demo/tool.py)']


def test_the_check_sorts_test_imports_and_finds_unused_keys(tmp_path):
    folder = make_package(tmp_path, '\n'.join([
        '<exec_depend>python3-numpy</exec_depend>', '<exec_depend>python3-scipy</exec_depend>',
        '<exec_depend>python3-yaml</exec_depend>', '<test_depend>python3-yaml</test_depend>']), {
        'pam_demo/__init__.py': 'import numpy\n',
        'pam_demo/testing.py': 'import pytest\n',
        'test/test_a.py': 'import yaml\nimport test_b\nfrom pam_demo import testing\n',
        'test/test_b.py': 'import mcap_ros2\nimport somethingelse\n\n\ndef test_x(node_process):\n'
                          '    node_process("sim_node", "pam_driver")\n'})
    problems = manifest_problems(folder)
    assert problems == [
        'pam_demo/test/test_b.py: import somethingelse: no rosdep key known (add the module to '
        f'PYTHON_KEYS or ROS_PACKAGES of {Path(__file__).name})',
        'pam_demo/package.xml: <test_depend>pam_driver</test_depend> missing (imported or run by '
        'pam_demo/test/test_b.py)',
        'pam_demo/package.xml: <test_depend>python3-mcap-ros2-support-pip</test_depend> missing '
        '(imported or run by pam_demo/test/test_b.py)',
        'pam_demo/package.xml: <test_depend>python3-pytest</test_depend> missing (imported or run '
        'by pam_demo/pam_demo/testing.py)',
        'pam_demo/package.xml: exec_depend python3-scipy declared, but no installed code imports '
        'or runs it',
        'pam_demo/package.xml: exec_depend python3-yaml declared, but no installed code imports '
        'or runs it (only tests: make it a test_depend)',
        'pam_demo/package.xml: python3-yaml is both an exec and a test dependency (REP 149: the '
        'exec one suffices)']


def test_the_tables_name_keys_that_exist():
    """Every key of PYTHON_KEYS is a rosdep key (of the rosdistro copy in ../shared/rosdistro or
    of rosdep/pam.yaml) and every ROS_PACKAGES entry a package released for Jazzy."""
    import yaml
    rosdistro = ROOT.parent / 'shared' / 'rosdistro'
    if not (rosdistro / 'jazzy' / 'distribution.yaml').is_file():
        pytest.skip(f'no rosdistro copy at {rosdistro}')
    rules = {}
    for path in (rosdistro / 'rosdep' / 'base.yaml', rosdistro / 'rosdep' / 'python.yaml',
                 ROOT / 'rosdep' / 'pam.yaml'):
        rules.update(yaml.safe_load(path.read_text()))
    assert not set(PYTHON_KEYS.values()) - set(rules)
    distribution = yaml.safe_load((rosdistro / 'jazzy' / 'distribution.yaml').read_text())
    released = {name for repo_name, repo in distribution['repositories'].items()
                if 'release' in repo
                for name in repo['release'].get('packages', [repo_name])}
    assert not ROS_PACKAGES - released
    assert not TOOL_KEYS - released
