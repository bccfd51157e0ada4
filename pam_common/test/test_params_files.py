"""Params files and -p rules (pam_common.params_files): checked before rclpy.init, one error line.

The check against rcl itself (rclpy.utilities.remove_ros_args runs rcl's parser): every file the
check accepts rcl accepts, every file rcl refuses the check refuses, with a line number. The nodes
themselves (real processes): pam_bringup/test/test_params_files_nodes.py and
test_params_files_cli.py, pam_estimator/test/test_ukf_node_params_files.py.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from pam_common.node_params import ParamSpec, unknown_parameter_warning
from pam_common.params_files import (
    ParamsFileError,
    check_params_file,
    params_files_in,
    rcl_problem,
    ros_args_problem,
)
from pam_common.testing import MALFORMED_PARAMS_FILES, malformed_params_file

ROOT = Path(__file__).resolve().parents[2]

# Files rcl accepts (and the node sections the check finds in them).
ACCEPTED = {
    'empty': ('', []),
    'comment_only': ('# nothing set\n', []),
    'wildcard': ('/**:\n  ros__parameters:\n    rate: 1000.0\n', ['/**']),
    'nested_namespace': ('pam:\n  sim_node:\n    ros__parameters:\n      rate: 1000.0\n',
                         ['pam/sim_node']),
    'flow_style': ('{"/**": {ros__parameters: {a: 1.0, b: [1, 2]}}}\n', ['/**']),
    'dotted_names': ('/**:\n  ros__parameters:\n    qos_overrides:\n      /x:\n        depth: 3\n',
                     ['/**']),
    'two_documents': ('/a:\n  ros__parameters:\n    x: 1\n---\n/b:\n  ros__parameters:\n'
                      '    y: 1\n', ['/a', '/b']),
    'empty_section': ('/pam/pi_node:\n  ros__parameters: {}\n', ['/pam/pi_node']),
    'empty_list_and_strings': ('/**:\n  ros__parameters:\n    a: []\n    b: ""\n    c: null\n'
                               '    d: "x\ty"\n', ['/**']),
}

# Files rcl refuses: a fragment of the one-line error and its line (None: no line).
REFUSED = {
    'value_outside_ros__parameters': ('/**:\n  ros__parameters:\n    a: 1\n  other: 2\n',
                                      "'other' holds the value '2' outside", 4),
    'bad_indentation': ('/**:\n  ros__parameters:\n   a: 1\n  b: 2\n', "'b' holds", 4),
    'no_value': ('/**:\n  ros__parameters:\n    rate:\n', "parameter 'rate' has no value", 3),
    'scalar_parameters': ('/**:\n  ros__parameters: 3\n', 'ros__parameters holds the value', 2),
    'no_node_name': ('ros__parameters:\n  a: 1\n', 'without a node name', 1),
    'root_list': ('- a\n- b\n', 'the file holds a list', 1),
    'unclosed_quote': ('/**:\n  ros__parameters:\n    a: "abc\n', 'not valid YAML', 3),
    'alias': ('/**:\n  ros__parameters:\n    a: &x 1.0\n    b: *x\n', 'aliasing', 4),
    'bad_node_name': ('/pam/sim-node:\n  ros__parameters:\n    a: 1\n', 'node name', None),
}

# rcl accepts these but reads nothing from them: the check refuses them (a mistake, surely).
STRICTER = {
    'root_scalar': ('hello\n', 'the file holds the value', 1),
    'section_without_ros__parameters': ('/pam/sim_node: {}\n', 'has no ros__parameters', 1),
}


def rcl_refuses(path: Path) -> bool:
    from rclpy.utilities import remove_ros_args
    try:
        remove_ros_args(['node', '--ros-args', '--params-file', str(path)])
    except RuntimeError:
        return True
    return False


def written(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f'{name}.yaml'
    path.write_text(text)
    return path


# ---------------------------------------------------------------------------- no process
@pytest.mark.parametrize('name', ACCEPTED)
def test_files_rcl_accepts_pass_with_their_sections(tmp_path, name):
    text, sections = ACCEPTED[name]
    path = written(tmp_path, name, text)
    assert not rcl_refuses(path)
    assert check_params_file(path) == sections
    assert ros_args_problem(['node', '--ros-args', '--params-file', str(path)]) is None


SHIPPED = [p for p in sorted(ROOT.glob('pam_*/config/*.yaml'))
           if 'ros__parameters' in p.read_text()]


@pytest.mark.parametrize('path', SHIPPED, ids=lambda p: p.name)
def test_shipped_params_files_pass(path):
    assert check_params_file(path)
    assert ros_args_problem(['node', '--ros-args', '--params-file', str(path)]) is None


@pytest.mark.parametrize('name', [*REFUSED, *MALFORMED_PARAMS_FILES])
def test_files_rcl_refuses_give_one_line_with_the_line(tmp_path, name):
    if name in REFUSED:
        text, fragment, line = REFUSED[name]
        path = written(tmp_path, name, text)
    else:
        path, line = malformed_params_file(tmp_path, name)
        fragment = ''
    assert rcl_refuses(path)
    problem = ros_args_problem(['node', '--ros-args', '-p', 'x:=1', '--params-file', str(path)])
    assert problem is not None and '\n' not in problem and '.c:' not in problem, problem
    assert problem.startswith(f'params file {path}: ') and fragment in problem, problem
    if line is not None:
        assert problem.endswith(f'(line {line})'), problem


@pytest.mark.parametrize('name', STRICTER)
def test_files_rcl_silently_ignores_are_refused(tmp_path, name):
    text, fragment, line = STRICTER[name]
    path = written(tmp_path, name, text)
    assert not rcl_refuses(path)
    with pytest.raises(ParamsFileError, match=fragment) as info:
        check_params_file(path)
    assert info.value.line == line


def test_tab_and_unclosed_bracket_are_named(tmp_path):
    with pytest.raises(ParamsFileError, match='a tab in the indentation'):
        check_params_file(malformed_params_file(tmp_path, 'tab_indentation')[0])
    with pytest.raises(ParamsFileError, match=r"expected ',' or '\]'"):
        check_params_file(malformed_params_file(tmp_path, 'unclosed_bracket')[0])


def test_params_files_are_found_inside_ros_args_only():
    argv = ['node', '--params-file', 'not_ros.yaml', '--ros-args', '-p', 'a:=1', '--params-file',
            'a.yaml', '--', '--params-file', 'after.yaml', '--ros-args', '--params-file', 'b.yaml']
    assert params_files_in(argv) == ['a.yaml', 'b.yaml']


def test_bad_override_rules_give_one_line():
    assert ros_args_problem(['node', '--ros-args', '-p', 'rate:=1000.0']) is None
    assert ros_args_problem(['node', '--ros-args', '-p', 'rate']) == \
        "cannot parse '-p rate': expected NAME:=VALUE"
    problem = ros_args_problem(['node', '--ros-args', '-p', 'initial_command:=[5.5, 5]'])
    assert problem.startswith("cannot parse '-p initial_command:=[5.5, 5]': Sequence should be")
    assert 'line' not in problem and '.c:' not in problem
    assert 'No file path' in ros_args_problem(['node', '--ros-args', '--params-file'])


def test_rcl_message_is_cut_to_one_line():
    message = ("Failed to parse ROS arguments: Couldn't parse params file: '--params-file x.yaml'."
               " Error: Will not support aliasing at line 4\n, at /project/src/parse.c:893, at "
               "/project/src/rcl/arguments.c:415")
    assert rcl_problem(message) == 'params file x.yaml: Will not support aliasing (line 4)'


def test_unknown_parameter_warning_names_the_closest_name():
    specs = [ParamSpec('kp_angle', 40.0, 'double', 'V/rad', 'gain'),
             ParamSpec('rate', 1000.0, 'double', 'Hz', 'rate')]
    assert unknown_parameter_warning('kp_angel', specs, 'pi_node') == (
        "ignoring unknown parameter 'kp_angel': did you mean 'kp_angle'? (see pi_node --help)")
    assert unknown_parameter_warning('zzz', specs, 'pi_node') == (
        "ignoring unknown parameter 'zzz' (see pi_node --help)")
