"""Real processes: sim_node and driver_node refuse a malformed params file with exit code 2 and
one line on stderr, so do the nodes of the other packages that go through run_node; a bad -p rule
is one line; an unknown parameter name in a file warns, naming the closest known one
(pam_common.params_files and node_params; the checks without processes: pam_common's
test_params_files.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from pam_common.testing import (
    MALFORMED_PARAMS_FILES,
    STARTUP_TIMEOUT,
    assert_node_refuses_params_file,
)


def written(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f'{name}.yaml'
    path.write_text(text)
    return path


# ---------------------------------------------------------------------------- real processes
@pytest.mark.parametrize('kind', MALFORMED_PARAMS_FILES)
@pytest.mark.parametrize('node', ['sim_node', 'driver_node'])
def test_node_refuses_a_malformed_params_file_in_one_line(node_process, tmp_path, node, kind):
    assert_node_refuses_params_file(node_process, tmp_path, node, 'pam_driver', kind)


@pytest.mark.parametrize('node, package', [('profile_player', 'pam_controller'),
                                           ('bag_record', 'pam_bag'), ('bag_play', 'pam_bag')])
def test_every_node_refuses_through_run_node(node_process, tmp_path, node, package):
    assert_node_refuses_params_file(node_process, tmp_path, node, package, 'tab_indentation')


def test_bad_override_rule_is_one_line(node_process):
    process = node_process('sim_node', 'pam_driver', '-p', 'initial_command:=[5.5, 5]')
    assert process.wait_exit(STARTUP_TIMEOUT) == 2
    assert process.stderr.splitlines() == [
        "[sim_node] error: cannot parse '-p initial_command:=[5.5, 5]': Sequence should be of "
        "same type. Value type 'integer' do not belong"], process.stderr


def test_unknown_name_in_a_params_file_warns_with_the_closest_name(node_process, tmp_path):
    path = written(tmp_path, 'typo', '/**:\n  ros__parameters:\n    timing: lockstep\n'
                   '    rat: 500.0\n')
    sim = node_process('sim_node', 'pam_driver', '--params-file', str(path))
    expected = "ignoring unknown parameter 'rat': did you mean 'rate'? (see sim_node --help)"
    sim.wait_for(lambda: expected in sim.stderr, STARTUP_TIMEOUT, 'the unknown-name warning')
