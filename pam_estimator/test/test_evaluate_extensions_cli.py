"""pam-evaluate --extensions FILE and --supply as a user runs them (docs/model_extensions.md): the
extensions of an extensions.yaml reach both estimators, a bag's measured supply pressure reaches
the UKF; the errors are one line and exit code 2."""

import re
import subprocess

import numpy as np
import pytest

from pam_common.testing import executable
from pam_estimator.bag_runs import load_bag_run, write_run_bag
from pam_model.effects import Effects
from pam_model.model import PamModel
from pam_model.model_extensions import save_extensions
from pam_model.parameters import load_parameters
from pam_model.profiles import validation_profile
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate

RIG = Effects(valve_time_constant=0.005, dead_volume=6.0e-6, hysteresis_band=2.0,
              sensor_offset=(2000.0, -3000.0), sensor_gain_error=(0.005, -0.005))
X0 = (0.0, 0.0, 4.5e5, 4.5e5)
SECONDS = 5.0


def evaluate(*args):
    return subprocess.run([executable('pam-evaluate', 'pam_estimator'), *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def q_percent(stdout: str, label: str) -> float:
    """Q (%) of the whole-run row `label` ('model alone' or 'UKF')."""
    return float(re.search(rf'^{label}\s+\S+\s+\S+\s+(\S+) %', stdout, re.M).group(1))


def locked_run(params=None, effects=None):
    model = PamModel(params=params or load_parameters('default'), locked=True)
    profile = validation_profile(1, SECONDS, model.h)
    return simulate(model, profile.u, X0, PressureSensor(2000.0, 12), 1, effects=effects)


def test_an_extensions_file_reaches_both_estimators(tmp_path):
    path = tmp_path / 'locked.npz'
    locked_run(effects=RIG).save(path)
    extensions = tmp_path / 'extensions.yaml'
    save_extensions(RIG, extensions)
    plain, carried = evaluate(path), evaluate(path, '--extensions', extensions)
    assert plain.returncode == 0 and carried.returncode == 0, plain.stderr + carried.stderr
    assert 'model extensions: none' in plain.stdout
    assert f'model extensions: {RIG.describe()} ({extensions})' in carried.stdout
    for label in ('model alone', 'UKF'):
        assert q_percent(carried.stdout, label) < 0.7 * q_percent(plain.stdout, label), label


def test_a_bags_supply_pressure_reaches_the_ukf(tmp_path):
    """The plant's supply sits 150 kPa under the model's P_tank: the UKF that reads the bag's
    supply pressure does better than the one that assumes P_tank."""
    params = load_parameters('default')
    plant = params.replace(P_tank=params.P_tank - 1.5e5)
    run = locked_run(params=plant)
    supply = np.full(len(run.t), plant.P_tank)
    bag = write_run_bag(run, tmp_path / 'supplied', supply=supply)
    assert np.array_equal(load_bag_run(bag).supply, supply)
    assert load_bag_run(write_run_bag(run, tmp_path / 'plain')).supply is None
    nominal, measured = evaluate(bag), evaluate(bag, '--supply')
    assert nominal.returncode == 0 and measured.returncode == 0, nominal.stderr + measured.stderr
    assert 'supply pressure: measured' in measured.stdout
    assert q_percent(measured.stdout, 'UKF') < 0.7 * q_percent(nominal.stdout, 'UKF')
    assert q_percent(measured.stdout, 'model alone') == q_percent(nominal.stdout, 'model alone')


@pytest.mark.parametrize('what, message', [('npz', '--supply needs a bag'),
                                           ('plain', 'no /pam/supply_pressure in the bag')])
def test_supply_without_a_supply_topic_is_one_line(tmp_path, what, message):
    run = locked_run()
    path = (run.save(tmp_path / 'run.npz') if what == 'npz'
            else write_run_bag(run, tmp_path / 'plain'))
    result = evaluate(path, '--supply')
    assert result.returncode == 2 and message in result.stderr, result.stderr
    assert 'Traceback' not in result.stderr


def test_a_bad_extensions_file_is_one_line(tmp_path):
    path = tmp_path / 'run.npz'
    locked_run().save(path)
    bad = tmp_path / 'extensions.yaml'
    bad.write_text('extensions:\n  temperature_drift: 5.0\n')
    result = evaluate(path, '--extensions', bad)
    assert result.returncode == 2 and 'is a state of the rig' in result.stderr, result.stderr
    assert 'Traceback' not in result.stderr
