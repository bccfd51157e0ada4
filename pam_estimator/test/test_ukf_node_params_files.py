"""ukf_node's params files and parameter names (pam_common.params_files, declare_parameters):
a malformed or missing params file stops it with exit code 2 and one line on stderr naming the
file (and the line); an unknown parameter name is a warning naming the closest known one."""

from __future__ import annotations

import pytest

from pam_common.testing import (
    MALFORMED_PARAMS_FILES,
    STARTUP_TIMEOUT,
    assert_node_refuses_params_file,
)


@pytest.mark.parametrize('kind', MALFORMED_PARAMS_FILES)
def test_malformed_params_file_is_one_line(node_process, tmp_path, kind):
    assert_node_refuses_params_file(node_process, tmp_path, 'ukf_node', 'pam_estimator', kind)


def test_unknown_parameter_name_warns(node_process):
    ukf = node_process('ukf_node', 'pam_estimator', '-p', 'nis_gat:=3.0')
    expected = ("ignoring unknown parameter 'nis_gat': did you mean 'nis_gate'? "
                '(see ukf_node --help)')
    ukf.wait_for(lambda: expected in ukf.stderr, STARTUP_TIMEOUT, 'the unknown-name warning')
