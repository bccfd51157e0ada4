"""pam-robustness as a user runs it, and the closed loop with a plant that has
unmodelled effects. One --quick run is shared by the tests that read it."""

import itertools
import json
import subprocess
from dataclasses import replace

import numpy as np
import pytest

from pam_common.testing import executable
from pam_controller.closed_loop import simulate_closed_loop, simulate_closed_loop_with_effects
from pam_controller.step_metrics import ANGLE_SPAN
from pam_estimator.evaluation import evaluate
from pam_model.effects import NO_EFFECTS, Effects
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.parameters import load_parameters
from pam_model.profiles import step_reference_profile, validation_profile
from pam_model.simulate import simulate


def run(*args):
    return subprocess.run([executable('pam-robustness', 'pam_controller'), *args],
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope='module')
def quick(tmp_path_factory):
    """(completed process, JSON document, directory) of `pam-robustness --quick` with the
    hysteresis and the Monte Carlo rows (all rows: about 50 s of CPU; these: about 15 s)."""
    out = tmp_path_factory.mktemp('robustness')
    result = run('--quick', '--effects', 'hysteresis,parameters', '--json', str(out / 'r.json'),
                 '--plots', str(out / 'plots'))
    assert result.returncode == 0, result.stderr
    return result, json.loads((out / 'r.json').read_text()), out


def rows_of(document, row):
    return [r for r in document['table'] if r['row'] == row and r['statistic'] in ('', 'mean')]


def test_quick_shows_the_error_growing_with_the_hysteresis(quick):
    """The oracle (true parameters: the hysteresis is its only error) grows in every figure; the
    nominal estimator's torque Q grows too (its angle Q is the parameter mismatch's, which the
    hysteresis partly offsets: not monotone). The model extensions take the hysteresis away."""
    result, document, out = quick
    assert document['magnitudes'] == [0.0, 1.0, 2.0]
    hysteresis = rows_of(document, 'hysteresis')
    assert [r['magnitude'] for r in hysteresis] == [0.0, 1.0, 2.0]
    for estimator, figure in (('oracle', 'q_psi'), ('oracle', 'q_tau'), ('oracle', 'ss_error'),
                              ('nominal', 'q_tau')):
        values = [r['figures'][estimator][figure] for r in hysteresis]
        assert all(b >= a - 0.05 for a, b in itertools.pairwise(values)), (estimator, figure,
                                                                           values)
    oracle = [r['figures']['oracle'] for r in hysteresis]
    assert oracle[2]['q_psi'] > oracle[0]['q_psi'] + 2.0
    assert oracle[2]['q_tau'] > oracle[0]['q_tau'] + 2.0
    extended = [r['figures']['oracle+ext'] for r in hysteresis]
    assert extended[2]['q_psi'] < oracle[2]['q_psi'] / 3 and extended[2]['q_tau'] < oracle[2][
        'q_tau'] / 3
    # the printed table carries the same figures
    lines = [line.split() for line in result.stdout.splitlines()
             if line.startswith('hysteresis ')]
    assert [float(cells[1]) for cells in lines] == [0.0, 1.0, 2.0]
    assert float(lines[2][3]) == pytest.approx(hysteresis[2]['figures']['nominal']['q_tau'],
                                               abs=0.006)
    assert 'what matters at 1 x the realistic value, oracle estimator' in result.stdout
    assert 'elapsed' in result.stdout
    for figure in ('q_psi', 'q_tau', 'ss_error', 'settling'):
        assert (out / 'plots' / f'robustness_{figure}.png').stat().st_size > 10_000


def test_zero_magnitude_is_the_base_plant(quick):
    """Every row at magnitude 0 gives the figures pam-evaluate's UKF and the batch closed loop
    give on the base plant ('mild'), computed here independently."""
    _, document, _ = quick
    base = load_scenario('mild')
    plant = PamModel(params=base.apply(load_parameters()))
    profile = validation_profile(1, 12.0, plant.h)
    expected = {}
    for name, model in (('nominal', PamModel()), ('oracle', plant)):
        figures = {}
        for locked, figure in ((False, 'q_psi'), (True, 'q_tau')):
            sim = simulate(replace(plant, locked=locked), profile.u, (0.0, 0.0, 4.5e5, 4.5e5),
                           base.sensor, 1)
            figures[figure] = 100.0 * evaluate(sim, model)[0]['ukf'].Q
        reference = step_reference_profile('angle', 0, 16.0, 8.0, plant.h).value
        loop, = simulate_closed_loop(plant, model, reference, [(40.0, 50.0)],
                                     sensor=base.sensor, seed=1)
        figures['ss_error'] = loop.report(ANGLE_SPAN, 2.0).worst_error
        expected[name] = figures
    expected['oracle+ext'] = expected['oracle']       # no effect: no extension
    zero = [r for r in document['table'] if r['magnitude'] == 0.0]
    assert len(zero) == len(document['rows']) + 1     # the Monte Carlo row: mean and worst
    for row in zero:
        for name, figures in expected.items():
            for figure, value in figures.items():
                assert row['figures'][name][figure] == pytest.approx(value, rel=1e-9), (
                    row['row'], name, figure)


@pytest.mark.parametrize('mode', ['angle', 'torque'])
def test_the_effects_loop_without_effects_is_the_batch_loop(mode):
    """simulate_closed_loop_with_effects (EffectsPlant stepped in Python) with no effect gives
    the compiled loop's run sample for sample; with hysteresis it does not."""
    base = load_scenario('mild')
    locked = mode == 'torque'
    plant = PamModel(params=base.apply(load_parameters()), locked=locked)
    reference = step_reference_profile(mode, 0, 10.0, 5.0, plant.h).value
    gains = (40.0, 50.0) if mode == 'angle' else (6.0, 8.0)
    batch, = simulate_closed_loop(plant, PamModel(locked=locked), reference, [gains],
                                  sensor=base.sensor, mode=mode, seed=4)
    kwargs = dict(sensor=base.sensor, mode=mode, seed=4)
    effects_run = simulate_closed_loop_with_effects(plant, NO_EFFECTS, PamModel(locked=locked),
                                                    reference, gains, **kwargs)
    for name in ('truth', 'estimate', 'commands'):
        np.testing.assert_allclose(getattr(effects_run, name), getattr(batch, name), rtol=0,
                                   atol=1e-9, err_msg=name)
    hysteresis = simulate_closed_loop_with_effects(plant, Effects(hysteresis_band=2.0),
                                                   PamModel(locked=locked), reference, gains,
                                                   **kwargs)
    assert np.max(np.abs(hysteresis.truth - batch.truth)) > 1e-3


@pytest.mark.parametrize('args, words', [
    (['--magnitudes', 'x'], 'comma-separated numbers'),
    (['--magnitudes', '-1'], 'in [0, 100]'),
    (['--effects', 'hysteresis,wobble'], "unknown effect 'wobble'"),
    (['--monte-carlo', '-1'], '--monte-carlo must be >= 0'),
    (['--closed-loop', '5'], '--closed-loop must hold two steps'),
    (['--duration', '0'], 'must be > 0'),
    (['--base', '/nonexistent/scenario.yaml'], '/nonexistent/scenario.yaml'),
])
def test_bad_arguments_exit_2_with_one_line(args, words):
    result = run(*args)
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and words in result.stderr, result.stderr
    assert 'Traceback' not in result.stderr
