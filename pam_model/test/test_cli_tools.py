"""pam-simulate and pam-kappa as a user runs them: real processes, real files."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pam_model.simulate import SimulationResult
from pam_model.valve_map import load_valve_map


def tool(name):
    """The installed console script, looked up as pam_common.executables looks up node
    executables (pam_model's tests import nothing of ROS): in the first AMENT_PREFIX_PATH prefix
    that indexes pam_model, <prefix>/lib/pam_model/<name> (colcon, apt) or <prefix>/bin/<name>
    (the project venv); with no such prefix, next to this interpreter, then on PATH."""
    prefixes = [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    indexed = [p for p in prefixes
               if (p / 'share/ament_index/resource_index/packages/pam_model').is_file()]
    if indexed:
        places = [indexed[0] / 'lib' / 'pam_model' / name, indexed[0] / 'bin' / name]
    else:
        places = [Path(sys.executable).parent / name, Path(shutil.which(name) or name)]
    found = next((str(p) for p in places if p.is_file() and os.access(p, os.X_OK)), None)
    assert found is not None, (f'{name} not found in {", ".join(map(str, places))}: run the '
                               'set-up (make setup)')
    return found


def run(*args):
    return subprocess.run(list(args), capture_output=True, text=True, timeout=120,
                          env={**os.environ})


@pytest.mark.parametrize('name', ['pam-simulate', 'pam-kappa'])
def test_help(name):
    result = run(tool(name), '--help')
    assert result.returncode == 0
    assert 'usage:' in result.stdout


def test_pam_simulate_writes_a_run(tmp_path):
    out = tmp_path / 'run.npz'
    result = run(tool('pam-simulate'), '-o', str(out), '--duration', '5', '--mismatch', 'mild',
                 '--seed', '3')
    assert result.returncode == 0, result.stderr
    assert 'mismatch \'mild\'' in result.stdout
    data = SimulationResult.load(out)
    assert len(data.t) == 5000
    assert np.any(data.p_measured != data.x[:, 2:])           # the mild sensor model is applied


def test_pam_simulate_runs_the_realistic_plant(tmp_path):
    """--mismatch realistic: the plant with unmodelled effects, sample by sample."""
    out = tmp_path / 'run.npz'
    result = run(tool('pam-simulate'), '-o', str(out), '--duration', '2', '--mismatch',
                 'realistic')
    assert result.returncode == 0, result.stderr
    assert "mismatch 'realistic'" in result.stdout and 'hysteresis +-2 N' in result.stdout
    data = SimulationResult.load(out)
    assert len(data.t) == 2000 and np.all(np.isfinite(data.table()))


def test_pam_simulate_bad_parameter_file(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('r_p: 0.006\n')
    result = run(tool('pam-simulate'), '-o', str(tmp_path / 'x.csv'), '--params', str(bad))
    assert result.returncode == 2
    assert 'missing key' in result.stderr and str(bad) in result.stderr
    assert 'Traceback' not in result.stderr


def test_pam_kappa_from_a_csv(tmp_path):
    curve = tmp_path / 'curve.csv'
    curve.write_text('voltage_V,pressure_Pa_abs\n0,101300\n5,340000\n10,710000\n')
    out = tmp_path / 'kappa.csv'
    result = run(tool('pam-kappa'), str(curve), '-o', str(out))
    assert result.returncode == 0, result.stderr
    valve_map = load_valve_map(out)
    assert list(valve_map.u) == [0.0, 5.0, 10.0]
    assert valve_map(5.0) == pytest.approx(0.3238, abs=1e-4)


def test_pam_kappa_rejects_garbage(tmp_path):
    curve = tmp_path / 'curve.csv'
    curve.write_text('voltage_V,pressure\n0,abc\n10,710000\n')
    result = run(tool('pam-kappa'), str(curve))
    assert result.returncode == 2 and 'two numbers' in result.stderr
