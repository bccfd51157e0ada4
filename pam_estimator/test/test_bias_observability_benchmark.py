"""benchmarks/bias_observability.py's core on a short profile: the information about each bias
from the pressures, on the model itself (no ROS)."""

import importlib.util
from pathlib import Path

import numpy as np

from pam_model.model import PamModel
from pam_model.profiles import validation_profile

BENCHMARK = Path(__file__).resolve().parents[2] / 'benchmarks' / 'bias_observability.py'
SECONDS = 2.0


def benchmark():
    spec = importlib.util.spec_from_file_location('bias_observability', BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def posterior_stds(module, locked: bool, parameters: bool) -> dict:
    model = PamModel(locked=locked)
    openings = model.openings(validation_profile(1, SECONDS, model.h).u)
    items = module.unknowns(model, parameters)
    S = module.sensitivities(model, openings, items)
    C = module.posterior(S, items, len(openings))
    return {item.name: (float(np.sqrt(C[j, j])), item.prior_std) for j, item in enumerate(items)}


def test_a_locked_joint_learns_nothing_about_the_torque_bias_and_a_free_one_does():
    module = benchmark()
    locked = posterior_stds(module, locked=True, parameters=False)
    std, prior = locked['b_tau']
    assert abs(std - prior) < 1e-6 * prior          # no information at all
    assert locked['b1'][0] < 0.5 * locked['b1'][1]  # the offsets: some
    free = posterior_stds(module, locked=False, parameters=True)
    assert free['b_tau'][0] < 0.5 * free['b_tau'][1]
    assert set(free) >= set(module.FLOW_PARAMETERS)
