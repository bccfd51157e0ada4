"""pam_bringup.json_file: the tools' JSON result files are strict JSON, written whole."""

from __future__ import annotations

import json
import math

import numpy as np

from pam_bringup.demo_workflow import comparison_lines
from pam_bringup.json_file import write_json


def test_non_finite_numbers_become_null_and_numpy_scalars_plain(tmp_path):
    path = write_json(tmp_path / 'summary.json',
                      {'worst_settling_time_s': math.inf, 'nan': np.float64('nan'),
                       'samples': np.int64(64001), 'steps': ({'ss': np.float64(0.25)},),
                       'ok': True})
    text = path.read_text()
    assert 'Infinity' not in text and 'NaN' not in text, text
    assert json.loads(text, parse_constant=lambda c: 1 / 0) == {
        'worst_settling_time_s': None, 'nan': None, 'samples': 64001,
        'steps': [{'ss': 0.25}], 'ok': True}
    assert not (tmp_path / 'summary.json.tmp').exists()


def test_a_step_that_never_settled_reads_never_in_the_comparison():
    report = {'worst_steady_state_error_pct': 0.3, 'worst_settling_time_s': None,
              'estimation': {'whole': {'I': 0.1, 'M': 0.2, 'Q_pct': 0.5}}}
    line = comparison_lines({'identified': report})[1]
    assert line.startswith('identified') and 'never' in line, line
