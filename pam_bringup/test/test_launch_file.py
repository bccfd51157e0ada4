"""launch/pam_sim.launch.py starts the nodes of pam_bringup.stack, the list pam-bringup starts, each
with the params file pam_bringup.params_namespace.stack_params gives for its namespace.

With the launch packages (a full ROS 2 install): the launch description is expanded with the launch
API for every rig and with / without the reference and the controller, and its Node actions
(package, executable, full name) must be stack_nodes() for the same options; under
namespace:=joint2 every Node is /joint2/<node> and its one --params-file gives it the parameters
the default file gives /pam/<node>; with composed:=true (the default) one pam_container Node
without a node name carries the stack's options and the namespace's params file. The launch-API
tests passed against the Jazzy branches of ros2/launch and ros2/launch_ros (with osrf_pycommon from
PyPI and an import stand-in for composition_interfaces). The pinned PyPI wheels have no launch /
launch_ros: those tests are skipped there, and the ones that always run check that the launch file
names no node itself (every Node's package, executable and name come from pam_bringup.stack), that
its Nodes take their namespace and params file from one stack_params call, and what that call gives
for the launch's own arguments (namespace:=joint2, the relative form the launch argument takes).
"""

from __future__ import annotations

import ast
import itertools
from pathlib import Path

import pytest

from pam_bringup.params_namespace import file_sections, stack_params
from pam_bringup.params_sections import key_pattern
from pam_bringup.stack import (
    CONTAINER,
    DEFAULT_NAMESPACE,
    RIGS,
    container_options,
    default_params_file,
    stack_nodes,
)

LAUNCH_FILE = Path(__file__).resolve().parents[1] / 'launch' / 'pam_sim.launch.py'
NODE_FIELDS = ('package', 'executable', 'name')


def test_the_launch_file_names_no_node_itself():
    tree = ast.parse(LAUNCH_FILE.read_text(), str(LAUNCH_FILE))
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)
             and getattr(n.func, 'id', getattr(n.func, 'attr', None)) == 'Node']
    assert calls, 'no Node action in the launch file'
    for call in calls:
        given = {k.arg: k.value for k in call.keywords}
        container = ast.unparse(given.get('executable', ast.Constant(''))) == 'CONTAINER.name'
        for name in NODE_FIELDS:
            if container and name == 'name':    # the composing process: no name= (a node-name
                assert name not in given        # remap would rename every node inside)
                continue
            assert name in given, f'line {call.lineno}: Node without {name}='
            assert not isinstance(given[name], (ast.Constant, ast.JoinedStr, ast.List)), (
                f'line {call.lineno}: Node {name}= is written in the launch file, not taken '
                'from pam_bringup.stack')
    imported = {alias.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                and n.module == 'pam_bringup.stack' for alias in n.names}
    assert 'stack_nodes' in imported


def file_parameters(path, fqn: str) -> dict[str, str]:
    """{parameter: YAML text of its value} a node of full name `fqn` takes from the params file
    `path`: the sections whose key matches it, in file order, a later one winning (rcl's rules,
    held with real nodes by test_params_namespace)."""
    values = {}
    for key, params in file_sections(path):
        if key_pattern(key).match(fqn):
            values.update((name, str(node.value)) for name, node in params)
    return values


def expanded_nodes(arguments: dict[str, str]) -> list[tuple[str, str, str, list]]:
    """(package, executable, full node name, its parameter arguments: [(file or -p rule,
    is_file)]) of every Node the launch file starts with these launch arguments: its entities
    visited with a LaunchContext as `ros2 launch` does, the Node actions expanded but not
    executed."""
    from launch import LaunchContext
    from launch.launch_description_sources import get_launch_description_from_python_launch_file
    from launch.utilities import normalize_to_list_of_substitutions, perform_substitutions
    from launch_ros.actions import Node

    def text(value) -> str:
        return perform_substitutions(context, normalize_to_list_of_substitutions(value))

    context = LaunchContext()
    context.launch_configurations.update({'composed': 'false', **arguments})
    pending = list(get_launch_description_from_python_launch_file(str(LAUNCH_FILE)).entities)
    found = []
    while pending:
        entity = pending.pop(0)
        if isinstance(entity, Node):
            entity._perform_substitutions(context)   # what Node.execute does first
            # what it passes as --params-file / -p (launch_ros keeps it private)
            parameters = list(entity._Node__expanded_parameter_arguments or [])
            found.append((text(entity.node_package), text(entity.node_executable),
                          entity.node_name, parameters,
                          [text(a) for a in entity._Node__arguments or []]))
        else:
            pending[:0] = entity.visit(context) or []
    return found


def launched_nodes(arguments: dict[str, str]) -> list[tuple[str, str, str]]:
    """(package, executable, full node name) of every Node the launch file starts."""
    return [node[:3] for node in expanded_nodes(arguments)]


@pytest.mark.parametrize('rig, reference, controller',
                         list(itertools.product(sorted(RIGS), (True, False), (True, False))))
@pytest.mark.parametrize('namespace', ['pam', 'joint2'])
def test_composed_the_launch_file_starts_one_container(rig, reference, controller, namespace):
    """composed:=true (the default): one pam_container Node, no node name (a remap would
    rename every node inside), in the namespace, with the stack's options and the namespace's
    params file (the /pam sections' values for each node of the stack)."""
    pytest.importorskip('launch_ros', reason='no launch_ros (not in the PyPI wheels): the launch '
                                             'file is checked on a full ROS 2 install')
    source = LAUNCH_FILE.parents[1] / 'config' / 'bringup.yaml'
    arguments = {'rig': rig, 'use_reference': str(reference).lower(),
                 'use_controller': str(controller).lower(), 'params_file': str(source),
                 'namespace': namespace, 'composed': 'true'}
    [(package, executable, fqn, parameters, options)] = expanded_nodes(arguments)
    assert (package, executable) == (CONTAINER.package, CONTAINER.name)
    assert fqn == f'/{namespace}/<node_name_unspecified>'
    assert options == container_options(rig, reference=reference, controller=controller)
    assert len(parameters) == 1 and parameters[0][1], parameters     # one --params-file
    for node in stack_nodes(rig, reference=reference, controller=controller):
        expected = file_parameters(source, f'{DEFAULT_NAMESPACE}/{node.name}')
        assert expected and file_parameters(parameters[0][0],
                                            f'/{namespace}/{node.name}') == expected


@pytest.mark.parametrize('rig, reference, controller',
                         list(itertools.product(sorted(RIGS), (True, False), (True, False))))
def test_the_launch_file_starts_the_stack_nodes(rig, reference, controller):
    pytest.importorskip('launch_ros', reason='no launch_ros (not in the PyPI wheels): the launch '
                                             'file is checked on a full ROS 2 install')
    arguments = {'rig': rig, 'use_reference': str(reference).lower(),
                 'use_controller': str(controller).lower(),
                 'params_file': str(LAUNCH_FILE.parents[1] / 'config' / 'bringup.yaml')}
    expected = [(n.package, n.name, f'{DEFAULT_NAMESPACE}/{n.name}')
                for n in stack_nodes(rig, reference=reference, controller=controller)]
    assert launched_nodes(arguments) == expected


def stack_actions_tree() -> ast.FunctionDef:
    tree = ast.parse(LAUNCH_FILE.read_text(), str(LAUNCH_FILE))
    imported = {alias.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                and n.module == 'pam_bringup.params_namespace' for alias in n.names}
    assert 'stack_params' in imported
    return next(n for n in ast.walk(tree)
                if isinstance(n, ast.FunctionDef) and n.name == 'stack_actions')


def test_the_launch_files_nodes_take_namespace_and_params_file_from_stack_params():
    """In stack_actions: `params = stack_params(<params_file>, namespace, ...)`, and every Node
    gets `namespace=namespace` and `parameters=[str(params.file)]`."""
    function = stack_actions_tree()
    calls = [n for n in ast.walk(function) if isinstance(n, ast.Assign)
             and isinstance(n.value, ast.Call)
             and getattr(n.value.func, 'id', '') == 'stack_params']
    assert len(calls) == 1, 'stack_actions must call stack_params once, its result named'
    result = calls[0].targets[0].id
    params_file, namespace = calls[0].value.args[:2]
    assert 'params_file' in ast.unparse(params_file)
    assert isinstance(namespace, ast.Name), ast.unparse(namespace)
    nodes = [n for n in ast.walk(function) if isinstance(n, ast.Call)
             and getattr(n.func, 'id', '') == 'Node']
    assert nodes
    for node in nodes:
        given = {k.arg: k.value for k in node.keywords}
        assert ast.unparse(given['namespace']) == namespace.id, ast.unparse(given['namespace'])
        assert ast.unparse(given['parameters']) == f'[str({result}.file)]', (
            ast.unparse(given['parameters']))


@pytest.mark.parametrize('rig', sorted(RIGS))
def test_stack_params_for_the_launch_arguments(tmp_path, rig):
    """What stack_actions' call gives for namespace:=joint2 (the launch argument's relative
    form; launch_ros makes it /joint2) and for the default namespace:=pam, with the default
    params_file: each node of the stack gets, in its namespace, the /pam section's values."""
    nodes = [node.name for node in stack_nodes(rig)]
    source = default_params_file()
    for argument in ('joint2', DEFAULT_NAMESPACE.lstrip('/')):
        params = stack_params(source, '/' + argument, nodes, tmp_path)
        assert params.warnings == ()
        assert (params.file == source) == (argument == 'pam')
        for name in nodes:
            expected = file_parameters(source, f'{DEFAULT_NAMESPACE}/{name}')
            assert expected and file_parameters(params.file, f'/{argument}/{name}') == expected
    assert file_parameters(source, '/joint2/sim_node') == {}     # what the nodes got before


@pytest.mark.parametrize('rig, reference, controller',
                         list(itertools.product(sorted(RIGS), (True, False), (True, False))))
def test_the_launch_file_applies_the_parameters_in_another_namespace(rig, reference,
                                                                       controller):
    pytest.importorskip('launch_ros', reason='no launch_ros (not in the PyPI wheels): the launch '
                                             'file is checked on a full ROS 2 install')
    source = LAUNCH_FILE.parents[1] / 'config' / 'bringup.yaml'
    arguments = {'rig': rig, 'use_reference': str(reference).lower(),
                 'use_controller': str(controller).lower(), 'params_file': str(source),
                 'namespace': 'joint2'}
    launched = expanded_nodes(arguments)
    assert [n[:3] for n in launched] == [
        (n.package, n.name, f'/joint2/{n.name}')
        for n in stack_nodes(rig, reference=reference, controller=controller)]
    for _, name, fqn, parameters, _ in launched:
        assert len(parameters) == 1 and parameters[0][1], parameters   # one --params-file
        expected = file_parameters(source, f'{DEFAULT_NAMESPACE}/{name}')
        assert expected and file_parameters(parameters[0][0], fqn) == expected, fqn
