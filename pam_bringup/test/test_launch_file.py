"""launch/pam_sim.launch.py starts the nodes of pam_bringup.stack, the list pam-bringup starts.

With the launch packages (a full ROS 2 install): the launch description is expanded with the
launch API for every rig and with / without the reference and the controller, and its Node
actions (package, executable, full name) must be stack_nodes() for the same options. The pinned
PyPI wheels have no launch / launch_ros: that test is skipped there, and the one that always runs
checks that the launch file names no node itself (every Node's package, executable and name come
from pam_bringup.stack).
"""

from __future__ import annotations

import ast
import itertools
from pathlib import Path

import pytest

from pam_bringup.stack import DEFAULT_NAMESPACE, RIGS, stack_nodes

LAUNCH_FILE = Path(__file__).resolve().parents[1] / 'launch' / 'pam_sim.launch.py'
NODE_FIELDS = ('package', 'executable', 'name')


def test_the_launch_file_names_no_node_itself():
    tree = ast.parse(LAUNCH_FILE.read_text(), str(LAUNCH_FILE))
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)
             and getattr(n.func, 'id', getattr(n.func, 'attr', None)) == 'Node']
    assert calls, 'no Node action in the launch file'
    for call in calls:
        given = {k.arg: k.value for k in call.keywords}
        for name in NODE_FIELDS:
            assert name in given, f'line {call.lineno}: Node without {name}='
            assert not isinstance(given[name], (ast.Constant, ast.JoinedStr, ast.List)), (
                f'line {call.lineno}: Node {name}= is written in the launch file, not taken '
                'from pam_bringup.stack')
    imported = {alias.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                and n.module == 'pam_bringup.stack' for alias in n.names}
    assert 'stack_nodes' in imported


def launched_nodes(arguments: dict[str, str]) -> list[tuple[str, str, str]]:
    """(package, executable, full node name) of every Node the launch file starts with these
    launch arguments: its entities visited with a LaunchContext as `ros2 launch` does, the Node
    actions expanded but not executed."""
    from launch import LaunchContext
    from launch.launch_description_sources import get_launch_description_from_python_launch_file
    from launch.utilities import normalize_to_list_of_substitutions, perform_substitutions
    from launch_ros.actions import Node

    def text(value) -> str:
        return perform_substitutions(context, normalize_to_list_of_substitutions(value))

    context = LaunchContext()
    context.launch_configurations.update(arguments)
    pending = list(get_launch_description_from_python_launch_file(str(LAUNCH_FILE)).entities)
    found = []
    while pending:
        entity = pending.pop(0)
        if isinstance(entity, Node):
            entity._perform_substitutions(context)   # what Node.execute does first
            found.append((text(entity.node_package), text(entity.node_executable),
                          entity.node_name))
        else:
            pending[:0] = entity.visit(context) or []
    return found


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
