"""Unit tests of pam_driver.sim_config: parameter table, validation, --help text (no ROS)."""

import dataclasses
import math

import pytest

import pam_driver.sim_config as sim_config
from pam_common.testing import assert_takes_exactly
from pam_driver.sim_config import (
    PARAMETERS,
    ConfigError,
    build_config,
    defaults,
    usage_text,
    wants_help,
)
from pam_model.model_choices import ForceModel, FrictionLaw

CONTRACT = ('plant_parameters', 'scenario', 'friction_law', 'force_model', 'joint_mode',
            'initial_state', 'initial_command', 'pressure_noise_std', 'quantisation_bits',
            'seed', 'timing', 'rate', 'publish_clock', 'lockstep_timeout', 'frame_id')


def test_contract_parameters_and_defaults():
    names = [spec.name for spec in PARAMETERS]
    assert set(CONTRACT) <= set(names)
    assert len(names) == len(set(names))
    d = defaults()
    assert d['initial_state'] == [0.0, 0.0, 450000.0, 450000.0]
    assert d['initial_command'] == [5.5, 5.5]
    assert d['rate'] == 1000.0 and d['lockstep_timeout'] == 0.5
    assert d['quantisation_bits'] == -1 and d['seed'] == 0 and d['publish_clock'] is False
    assert d['timing'] == 'realtime' and d['frame_id'] == 'pam_joint' and d['scenario'] == ''
    assert d['max_catch_up'] == 10 and d['clock_rate'] == 1000.0


@pytest.mark.parametrize(('clock_rate', 'rate', 'every', 'words'), [
    (1000.0, 1000.0, 1, 'with every sample'),
    (1000.0, 500.0, 1, 'with every sample'),      # the default, of a slower rig
    (100.0, 1000.0, 10, 'with 1 sample in 10'),
    (300.0, 1000.0, 3, 'with 1 sample in 3'),
])
def test_clock_rate_decimates_the_samples(clock_rate, rate, every, words):
    config = build_config({'publish_clock': True, 'clock_rate': clock_rate, 'rate': rate})
    assert config.clock_every == every
    assert any(f'/clock published {words}' in line for line in config.summary), config.summary


def test_valve_range_agrees_with_pam_model():
    from pam_model import physics
    assert (sim_config.U_MIN, sim_config.U_MAX) == (physics.U_MIN, physics.U_MAX)


@pytest.mark.parametrize('parameter, choice', [('friction_law', FrictionLaw),
                                               ('force_model', ForceModel)])
def test_law_parameters_take_exactly_the_names_of_pam_model(parameter, choice):
    """The choices are pam_model's enumeration; each name reaches the plant's model."""
    configs = assert_takes_exactly(build_config, PARAMETERS, parameter, choice.names())
    assert [getattr(c.model, parameter) for c in configs] == list(choice)
    assert defaults()[parameter] == str(choice.PROPOSED)


def test_default_configuration():
    config = build_config({})
    assert config.h == pytest.approx(1e-3)
    assert config.scenario is None
    assert config.sensor.noise_std == 0.0 and config.sensor.bits == 0
    assert not config.model.locked
    rig = config.make_rig()
    assert rig.u == (5.5, 5.5)
    assert list(rig.x) == [0.0, 0.0, 450000.0, 450000.0]
    assert any(line.startswith('timing: realtime at 1000 Hz') for line in config.summary)
    assert any('scenario: none' in line for line in config.summary)


def test_mild_mismatch_brings_its_sensor_unless_overridden():
    config = build_config({'scenario': 'mild'})
    nominal = build_config({}).parameters
    assert config.scenario.name == 'mild'
    assert config.sensor.noise_std == 2000.0 and config.sensor.bits == 12
    assert config.parameters.mu_s == pytest.approx(1.2 * nominal.mu_s)
    assert "scenario: 'mild'" in ' '.join(config.summary)
    tuned = build_config({'scenario': 'mild', 'pressure_noise_std': 0.0, 'quantisation_bits': 0})
    assert tuned.sensor.noise_std == 0.0 and tuned.sensor.bits == 0
    explicit = build_config({'pressure_noise_std': 500.0, 'quantisation_bits': 10})
    assert explicit.sensor.noise_std == 500.0 and explicit.sensor.bits == 10


def test_realistic_mismatch_brings_its_effects_to_the_rig():
    config = build_config({'scenario': 'realistic'})
    assert config.scenario.effects.active
    assert config.make_rig().plant is not None
    assert build_config({'scenario': 'mild'}).make_rig().plant is None
    assert 'unmodelled effects: valve lag 5 ms' in ' '.join(config.summary)


def test_options_reach_the_model():
    config = build_config({'friction_law': 'tondu', 'force_model': 'no_offset',
                           'joint_mode': 'locked', 'rate': 2000.0,
                           'plant_parameters': 'printed'})
    assert config.model.friction == 'tondu' and config.model.force == 'no_offset'
    assert config.model.locked and config.h == pytest.approx(5e-4)
    assert config.parameters.p_w2_2 == pytest.approx(-15.75)


@pytest.mark.parametrize('overrides, words', [
    ({'joint_mode': 'sideways'}, ['joint_mode', 'sideways', 'free, locked']),
    ({'friction_law': 'sticky'}, ['friction_law', 'tondu']),
    ({'force_model': ''}, ['force_model']),
    ({'timing': 'fast'}, ['timing', 'lockstep']),
    ({'plant_parameters': '/nonexistent.yaml'}, ['plant_parameters', 'cannot read']),
    ({'plant_parameters': ' '}, ['plant_parameters', 'empty']),
    ({'scenario': 'wild'}, ['scenario', 'wild']),
    ({'valve_map': '/nonexistent.csv'}, ['valve_map']),
    ({'initial_state': [0.0, 0.0, 4e5]}, ['initial_state', '4 numbers']),
    ({'initial_state': [0.0, 0.0, math.nan, 4e5]}, ['initial_state', 'finite']),
    ({'initial_state': [0.0, 0.0, 0.0, 4e5]}, ['initial_state', '> 0 Pa']),
    ({'initial_command': [5.5]}, ['initial_command', '2 numbers']),
    ({'initial_command': [5.5, 11.0]}, ['initial_command', '[0.0, 10.0]']),
    ({'rate': 50.0}, ['rate', 'out of range']),
    ({'rate': math.nan}, ['rate', 'finite']),
    ({'lockstep_timeout': -1.0}, ['lockstep_timeout']),
    ({'quantisation_bits': 40}, ['quantisation_bits']),
    ({'quantisation_bits': 2.5}, ['quantisation_bits', 'integer']),
    ({'seed': -3}, ['seed']),
    ({'max_catch_up': -1}, ['max_catch_up']),
    ({'publish_clock': 'yes'}, ['publish_clock']),
    ({'clock_rate': 2000.0}, ['clock_rate', 'above the sample rate']),
    ({'clock_rate': 0.0}, ['clock_rate']),
    ({'frame_id': 3}, ['frame_id', 'string']),
    ({'no_such_parameter': 1}, ['no_such_parameter']),
])
def test_bad_values_name_the_parameter(overrides, words):
    with pytest.raises(ConfigError) as info:
        build_config(overrides)
    for word in words:
        assert word in str(info.value)


def test_malformed_files_carry_pam_model_messages(tmp_path):
    plant = tmp_path / 'plant.yaml'
    plant.write_text('r_p: [unclosed\n')
    with pytest.raises(ConfigError, match=r"plant_parameters.*not valid YAML"):
        build_config({'plant_parameters': str(plant)})
    scenario = tmp_path / 'scenario.yaml'
    scenario.write_text('factors:\n  mu_s: -1.0\n')
    with pytest.raises(ConfigError, match=r"scenario.*mu_s"):
        build_config({'scenario': str(scenario)})


def test_usage_text_lists_every_parameter():
    text = usage_text()
    for spec in PARAMETERS:
        assert f'  {spec.name} (' in text
        assert spec.default_text() in text
    assert 'Hz' in text and 'Pa' in text and 'rad/s' in text


def test_wants_help():
    assert wants_help(['sim_node', '--help'])
    assert wants_help(['sim_node', '-h'])
    assert not wants_help(['sim_node'])
    assert not wants_help(['sim_node', '--ros-args', '-p', 'frame_id:=-h'])


def test_the_configuration_is_frozen_and_typed():
    """Built once: the node reads typed fields, never the parameter strings, and cannot change
    them."""
    config = build_config({'timing': 'lockstep', 'initial_command': [4.0, 7.0], 'seed': 3,
                           'thread_priority': 0, 'cpu_affinity': [1, 0, 1]})
    assert config.lockstep and config.timing == 'lockstep' and config.rate == 1000.0
    assert config.initial_command == (4.0, 7.0) and config.seed == 3
    assert config.initial_state == (0.0, 0.0, 450000.0, 450000.0)
    assert config.realtime.cpus == (0, 1) and config.realtime.priority == 0
    assert isinstance(config.summary, tuple)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.rate = 500.0
    with pytest.raises(TypeError):
        config.values['rate'] = 500.0
    with pytest.raises(ConfigError, match='cpu_affinity'):
        build_config({'cpu_affinity': [-1]})


def test_the_old_parameter_name_mismatch_is_read_as_scenario():
    """'mismatch' (the name of earlier releases, in users' params files) is the same parameter;
    both names with different values is an error naming them."""
    assert build_config({'mismatch': 'mild'}).scenario_name == 'mild'
    assert build_config({'mismatch': 'mild', 'scenario': 'mild'}).scenario_name == 'mild'
    with pytest.raises(ConfigError, match=r"'scenario'.*old name 'mismatch'"):
        build_config({'mismatch': 'mild', 'scenario': 'strong'})

