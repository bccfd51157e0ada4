"""The `other_forms` scenario where the tools take a scenario name (pam-calibration-bags,
sim_node's configuration), and benchmarks/cross_forms.py's core path (validation runs on a plant
family through the UKF forms, the table, the worst cell) on a one-second profile."""

import importlib.util
import math
from pathlib import Path

import numpy as np

from pam_driver.sim_config import build_config
from pam_estimator.bag_runs import load_run
from pam_estimator.cli import calibration_bags
from pam_estimator.noise_choice import with_velocity_noise
from pam_estimator.pam_ukf import DEFAULT_TUNING
from pam_model.effects import Effects
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.model_extensions import NO_EXTENSIONS
from pam_model.parameters import load_parameters

BENCHMARK = Path(__file__).resolve().parents[2] / 'benchmarks' / 'cross_forms.py'


def cross_forms(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARK.parent))      # its sibling realistic_targets
    spec = importlib.util.spec_from_file_location('cross_forms', BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_calibration_bags_and_sim_node_take_other_forms(tmp_path):
    assert calibration_bags.body([str(tmp_path), '--angles=0', '--voltages', '0,5,10', '--hold',
                                  '2', '--pair-hold', '0', '--free-duration', '0', '--seed', '4',
                                  '--scenario', 'other_forms']) == 0
    run = load_run(tmp_path / 'locked_0deg')
    assert np.all(np.isfinite(run.p_measured)) and len(run.t) > 5000
    config = build_config({'scenario': 'other_forms'})
    assert config.make_rig().plant is not None
    assert 'Bouc-Wen +2.5 N' in ' '.join(config.summary)


def test_cross_forms_core_path_on_a_short_profile(monkeypatch):
    bench = cross_forms(monkeypatch)
    scenario = load_scenario('other_forms')
    nominal = PamModel()
    plant = PamModel(params=scenario.apply(load_parameters()))
    offsets = Effects(sensor_offset=scenario.effects.sensor_offset)
    chosen = with_velocity_noise(DEFAULT_TUNING, 1e-4)
    forms = bench.estimators(nominal, (plant, offsets), chosen)
    assert forms[bench.NOMINAL] == (nominal, NO_EXTENSIONS, DEFAULT_TUNING)
    assert forms[bench.PAPER] == (plant, NO_EXTENSIONS, DEFAULT_TUNING)
    assert forms[bench.EXTENDED] == (plant, offsets, chosen)
    assert forms[bench.EXTENDED_DEFAULT] == (plant, offsets, DEFAULT_TUNING)
    assert list(forms) == list(bench.FORMS)
    cells = bench.family_cells(scenario, plant, forms, [1, 2], 1.0)
    for form in bench.FORMS:
        for key in ('Q_psi', 'Q_tau'):
            assert len(cells[form][key]) == 2
            assert all(math.isfinite(q) and q > 0.0 for q in cells[form][key])
    table = {'other_forms': cells, 'copy': {f: {'Q_psi': [0.1], 'Q_tau': [0.1]}
                                            for f in bench.FORMS}}
    lines = bench.format_table(table)
    assert len(lines) == 2 + len(bench.FORMS) and '`other_forms`' in lines[0]
    family, form, q_psi, q_tau = bench.worst_cell(table)
    assert family == 'other_forms'
    assert max(q_psi, q_tau) == max(max(*c['Q_psi'], *c['Q_tau']) for c in cells.values())
    after = bench.worst_cell(table, bench.IDENTIFIED)
    assert after[1] in bench.IDENTIFIED
