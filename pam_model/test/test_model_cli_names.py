"""One name per concept on the command line (docs/glossary.md): the scenario and the valve map
have their names, and the former names still work as aliases, to the same value."""

import argparse

from pam_model.cli.common import add_model_arguments


def parse(argv):
    parser = argparse.ArgumentParser()
    add_model_arguments(parser)
    return parser.parse_args(argv)


def test_the_scenario_and_the_valve_map_take_their_former_names_too():
    new = parse(['--scenario', 'mild', '--valve-map', 'kappa.csv'])
    old = parse(['--mismatch', 'mild', '--kappa', 'kappa.csv'])
    assert vars(new) == vars(old)
    assert (new.scenario, new.valve_map) == ('mild', 'kappa.csv')
    assert (parse([]).scenario, parse([]).valve_map) == ('', 'default')


def test_the_help_gives_the_name_and_the_alias():
    parser = argparse.ArgumentParser()
    add_model_arguments(parser)
    text = parser.format_help()
    assert '--scenario NAME|FILE, --mismatch NAME|FILE' in text
    assert '--valve-map FILE, --kappa FILE' in text
