"""pam-identify's and pam-evaluate's names for the scenario and the valve map
(docs/glossary.md), with the former names kept as aliases to the same value."""

from pam_estimator.cli import evaluate, identify


def test_identify_takes_the_names_and_their_aliases():
    new = identify.parse_args(['run', '-o', 'out', '--truth-scenario', 'mild',
                               '--prior-valve-map', 'k.csv'])
    old = identify.parse_args(['run', '-o', 'out', '--truth-mismatch', 'mild',
                               '--kappa-prior', 'k.csv'])
    assert vars(new) == vars(old)
    assert (new.truth_scenario, new.prior_valve_map) == ('mild', 'k.csv')


def test_evaluate_takes_the_valve_map_and_its_alias():
    assert vars(evaluate.parse_args(['run', '--valve-map', 'k.csv'])) == vars(
        evaluate.parse_args(['run', '--kappa', 'k.csv']))
    assert evaluate.parse_args(['run']).valve_map == 'default'
