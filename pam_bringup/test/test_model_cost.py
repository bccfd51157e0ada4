"""pam_bringup.model_cost: the models' compute per sample, back to back and paced at 1 kHz as
sim_node's sampler paces them, on the scenario's plant with the nominal or an identified UKF."""

import math
import time

import pytest
import yaml

from pam_bringup.model_cost import measure_model_cost
from pam_bringup.stack import default_params_file


def test_each_model_is_timed_and_the_three_paced_at_1_khz():
    start = time.monotonic()
    cost = measure_model_cost('realistic', None, samples=50, paced=200)
    took = time.monotonic() - start
    assert (cost.scenario, cost.model) == ('realistic', 'nominal')
    figures = (cost.sim, cost.ukf, cost.pi, cost.paced, cost.wake_up)
    assert all(math.isfinite(v) and v > 0.0 for v in figures), cost
    assert cost.back_to_back == cost.sim + cost.ukf + cost.pi
    assert cost.with_wake_up == cost.back_to_back + cost.wake_up
    assert took >= 0.399            # twice 200 deadlines 1 ms apart: the pacing is real
    assert cost.paced < 1e-3 and cost.wake_up < 1e-3    # CPU per sample, not the period
    assert cost.as_dict()['back_to_back'] == cost.back_to_back
    assert cost.as_dict()['with_wake_up'] == cost.with_wake_up
    line = cost.line()
    assert line.startswith("the models' compute per sample (the 'realistic' rig, the nominal "
                           'UKF, PI): ') and ' us paced at 1 kHz (of which ' in line, line
    assert line.endswith(' us is one wake-up of a bare sleep loop)'), line


def test_the_scenario_defaults_to_the_stacks():
    stack = yaml.safe_load(default_params_file().read_text())
    expected = stack['/pam/sim_node']['ros__parameters']['scenario']
    assert measure_model_cost(None, None, samples=5, paced=5).scenario == expected


@pytest.mark.parametrize('samples, paced', [(0, 10), (10, 0)])
def test_no_samples_is_refused(samples, paced):
    with pytest.raises(ValueError, match='must be >= 1'):
        measure_model_cost('realistic', None, samples=samples, paced=paced)
