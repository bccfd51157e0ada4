"""The UKF's velocity process noise chosen on free calibration runs (noise_choice), and the
tuning.yaml pam-identify writes with it.

Free runs of 60 s (the campaign's, seed 3) on the 'mild' parameters with its sensor noise. The
estimator's model is the plant's parameters: without unmodelled effects the tuning's own noise
must win (the larger ones scored 0.0182 / 0.0286 / 0.1006 deg against 0.0172); with a Bouc-Wen
loop driven by the length in the plant AND in the estimator (its memory follows the posterior and
lags the plant's), a larger noise wins by more than MARGIN (seen 1e-3: 14 % below the own).
"""

import math

import pytest
import yaml

from pam_estimator.calibration_runs import (
    TUNING_FILE,
    identified_tuning,
    identified_ukf_parameters,
)
from pam_estimator.noise_choice import (
    CANDIDATES,
    MARGIN,
    choose_velocity_noise,
    pick,
    with_velocity_noise,
)
from pam_estimator.pam_ukf import DEFAULT_TUNING
from pam_model.effects import Effects
from pam_model.identification.campaign import CampaignPlan, records_of, simulate_campaign
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.model_extensions import NO_EXTENSIONS
from pam_model.parameters import load_parameters

OWN = DEFAULT_TUNING.Q[1]
LOOP = Effects(bouc_wen_band=2.5, bouc_wen_driver='length', bouc_wen_length_travel=1e-3)


FREE_PLAN = CampaignPlan(lock_angles=(), free_duration=60.0, seed=3)


def free_runs(effects, plan=FREE_PLAN):
    truth = load_scenario('mild').apply(load_parameters())
    return truth, records_of(simulate_campaign(PamModel(params=truth),
                                               load_scenario('mild').sensor, plan,
                                               effects=effects))


def test_a_right_model_keeps_the_tunings_own_noise():
    truth, runs = free_runs(Effects())
    choice = choose_velocity_noise(runs, PamModel(params=truth), NO_EXTENSIONS)
    assert list(choice.scores) == [OWN, *CANDIDATES]
    assert choice.q_velocity == OWN and choice.tuning() == DEFAULT_TUNING
    assert min(choice.scores, key=choice.scores.get) == OWN, choice.scores
    assert math.degrees(choice.scores[OWN]) < 0.03, choice.scores


def test_a_loop_whose_memory_lags_asks_for_more_velocity_noise():
    truth, runs = free_runs(LOOP)
    choice = choose_velocity_noise(runs, PamModel(params=truth), LOOP)
    assert choice.q_velocity > OWN, choice
    assert choice.scores[choice.q_velocity] < (1.0 - MARGIN) * choice.scores[OWN], choice.scores
    assert choice.tuning().Q == (DEFAULT_TUNING.Q[0], choice.q_velocity, *DEFAULT_TUNING.Q[2:])
    lines = choice.report()
    assert len([line for line in lines if 'Q(psi_dot)' in line]) == 4
    assert sum('<- chosen' in line for line in lines) == 1 and 'below the tuning' in lines[-1]


def test_nothing_to_choose_on_without_a_free_run():
    truth, runs = free_runs(Effects(), CampaignPlan(lock_angles=(0.0,), hold=2.0, pair_hold=0.0,
                                                    voltages=(4.0, 5.0, 6.0), free_duration=0.0,
                                                    seed=3))
    assert all(r.locked for r in runs)
    assert choose_velocity_noise(runs, PamModel(params=truth), NO_EXTENSIONS) is None


def test_the_rule_a_larger_noise_must_beat_the_own_by_the_margin():
    just_under = 1.0 - MARGIN + 0.001
    assert pick({OWN: 1.0, 1e-5: just_under, 1e-4: 1.2}, OWN)[0] == OWN
    q, why = pick({OWN: 1.0, 1e-5: 0.99, 1e-4: 1.0 - MARGIN - 0.001}, OWN)
    assert q == 1e-4 and f'>= {100 * MARGIN:g} % needed' in why
    assert pick({OWN: 0.5, 1e-5: 0.6}, OWN) == (OWN, "the tuning's own gives the lowest angle "
                                                     'RMS')


def test_tuning_yaml_round_trip_and_errors(tmp_path):
    assert identified_tuning(tmp_path) == DEFAULT_TUNING            # no file: the default
    assert 'process_noise' not in identified_ukf_parameters(tmp_path)
    chosen = with_velocity_noise(DEFAULT_TUNING, 1e-4)
    (tmp_path / TUNING_FILE).write_text(yaml.safe_dump({'name': 'x',
                                                        'process_noise': list(chosen.Q)}))
    assert identified_tuning(tmp_path) == chosen
    assert identified_ukf_parameters(tmp_path)['process_noise'] == list(chosen.Q)
    for text, words in (('process_noise: [1, 2]', 'needs 4'),
                        ('process_noise: [1, .nan, 1, 1]', 'finite'),
                        ('process_noise: three', 'list of 4 numbers'),
                        ('noise: [1, 1, 1, 1]', "unknown key 'noise'"),
                        ('process_noise: [1, 1', 'not valid YAML')):
        (tmp_path / TUNING_FILE).write_text(text)
        with pytest.raises(ValueError, match=words) as error:
            identified_tuning(tmp_path)
        assert TUNING_FILE in str(error.value)
