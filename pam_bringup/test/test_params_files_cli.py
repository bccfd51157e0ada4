"""pi_node's and pam-bringup's params files, and the controller nodes' parameter names
(pam_common.params_files, declare_parameters): a malformed or missing params file stops them with
exit code 2 and one line on stderr naming the file (and the line), pam-bringup before it starts
any node; an unknown parameter name (on the command line or in a file) is a warning naming the
closest known one."""

from __future__ import annotations

import pytest

from pam_bringup.params_sections import section_keys, sections_for
from pam_common.testing import (
    MALFORMED_PARAMS_FILES,
    STARTUP_TIMEOUT,
    assert_node_refuses_params_file,
    assert_params_file_error,
    malformed_params_file,
)


@pytest.mark.parametrize('kind', MALFORMED_PARAMS_FILES)
def test_pi_node_malformed_params_file_is_one_line(node_process, tmp_path, kind):
    assert_node_refuses_params_file(node_process, tmp_path, 'pi_node', 'pam_controller', kind)


@pytest.mark.parametrize('kind', MALFORMED_PARAMS_FILES)
def test_bringup_refuses_a_malformed_params_file_before_starting(node_process, tmp_path, kind):
    path, line = malformed_params_file(tmp_path, kind)
    run = node_process('pam-bringup', 'pam_bringup', '--params-file', str(path), raw=True)
    assert_params_file_error(run, 'pam-bringup:', path, line)
    assert run.stdout == '', run.stdout        # nothing started


PACKAGE = {'reference_node': 'pam_controller', 'tracking_report': 'pam_bringup'}


@pytest.mark.parametrize('node', ['reference_node', 'tracking_report'])
def test_other_controller_nodes_refuse_through_run_node(node_process, tmp_path, node):
    assert_node_refuses_params_file(node_process, tmp_path, node, PACKAGE[node],
                                    'list_under_ros__parameters')


def test_bringup_reads_nested_namespace_sections(tmp_path):
    path = tmp_path / 'nested.yaml'
    path.write_text('pam:\n  sim_node:\n    ros__parameters:\n      rate: 1000.0\n')
    keys = section_keys(path)
    assert sections_for('/pam/sim_node', keys) == ['pam/sim_node']


def test_pi_node_unknown_parameter_names_warn(node_process, tmp_path):
    path = tmp_path / 'typo.yaml'
    path.write_text('/**:\n  ros__parameters:\n    anti_windp: conditional\n')
    pi = node_process('pi_node', 'pam_controller', '-p', 'kp_angel:=30.0', '--params-file',
                      str(path))
    for name, known in (('kp_angel', 'kp_angle'), ('anti_windp', 'anti_windup')):
        expected = (f"ignoring unknown parameter '{name}': did you mean '{known}'? "
                    '(see pi_node --help)')
        pi.wait_for(lambda expected=expected: expected in pi.stderr, STARTUP_TIMEOUT,
                    f'the warning about {name}')
