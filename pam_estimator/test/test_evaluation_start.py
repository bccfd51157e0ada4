"""The offline evaluation's start and its post-transient metrics: the model alone and the UKF
start from one state (start_state: the measured angle and velocity and the FIRST MEASURED
pressures by default; the run's recorded x[0] on request), and pam-evaluate on a shipped bag
prints the whole-run table and the same metrics after the initial transient."""

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pam_common.testing import executable
from pam_estimator.bag_runs import load_run
from pam_estimator.evaluation import (
    STARTS,
    evaluate,
    run_model_alone,
    run_ukf,
    start_state,
    table_after,
)
from pam_model.model import PamModel
from pam_model.profiles import validation_profile
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate

BAG = Path(__file__).resolve().parents[2] / 'bags' / 'validation_mild_locked'
TRUE_X0 = (0.1, 0.2, 4.5e5, 4.0e5)


def noisy_run(duration=0.3):
    """A pam-simulate-like run: x holds the TRUE state, p_measured the noisy sensor readings."""
    profile = validation_profile(0, duration)
    return simulate(PamModel(), profile.u, TRUE_X0, sensor=PressureSensor(2000.0, 12), seed=3)


def test_the_default_start_is_what_the_rig_measures_at_sample_0():
    run = noisy_run()
    assert not np.allclose(run.p_measured[0], run.x[0, 2:])    # the sensor's noise is there
    x0 = start_state(run)
    assert STARTS[0] == 'measured'
    assert x0.tolist() == [0.1, 0.2, *run.p_measured[0].tolist()]
    assert start_state(run, 'recorded').tolist() == list(TRUE_X0)   # the behaviour before
    with pytest.raises(ValueError, match='start must be one of measured, recorded'):
        start_state(run, 'true')


@pytest.mark.parametrize('start', STARTS)
def test_the_model_alone_and_the_ukf_start_from_the_same_state(start):
    run = noisy_run()
    x0 = start_state(run, start)
    _, alone, ukf = evaluate(run, PamModel(), start=start)
    assert alone.x[0].tolist() == x0.tolist() and ukf.x[0].tolist() == x0.tolist()
    # the defaults of the two runners are that start too
    model = PamModel()
    assert run_model_alone(run, model).x[0].tolist() == start_state(run).tolist()
    assert run_ukf(run, model).x[0].tolist() == start_state(run).tolist()


def test_a_bag_holds_the_measured_pressures_so_both_starts_agree():
    run = load_run(BAG)
    assert start_state(run, 'measured').tolist() == start_state(run, 'recorded').tolist()


def rows(text: str) -> list[tuple[str, float, float, float]]:
    """(label, I, M, Q %) of every model alone / UKF row, in print order."""
    found = re.findall(r'^(model alone|UKF) +(\S+) +(\S+) +(\S+) %', text, flags=re.MULTILINE)
    return [(label, float(i), float(m), float(q)) for label, i, m, q in found]


def test_pam_evaluate_prints_the_whole_run_and_after_the_transient_on_a_shipped_bag():
    result = subprocess.run([executable('pam-evaluate', 'pam_estimator'), str(BAG),
                             '--transient', '2.5'], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "start 'measured'" in out, out
    assert ('after the initial transient (t >= 2.5 s; the paper\'s figures cover the whole '
            'run):') in out, out
    printed = rows(out)
    assert [r[0] for r in printed] == ['model alone', 'UKF'] * 2, out
    # the same computation in-process: the headline (whole run), then t >= 2.5 s
    run = load_run(BAG)
    table, alone, ukf = evaluate(run, PamModel())
    after = table_after(run, alone, ukf, 2.5)
    expected = [table['model'], table['ukf'], after['model'], after['ukf']]
    for (_, i, m, q), want in zip(printed, expected, strict=True):
        assert (i, m) == pytest.approx((want.I, want.M), abs=1e-4), out   # printed %.4f
        assert q == pytest.approx(100 * want.Q, abs=0.006), out               # printed %.2f
    assert after['ukf'].I != table['ukf'].I                 # another window, not a copy


def test_pam_evaluate_refuses_a_bad_transient():
    result = subprocess.run([executable('pam-evaluate', 'pam_estimator'), str(BAG),
                             '--transient', '-1'], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert '--transient must be a finite number of seconds >= 0, got -1' in result.stderr
