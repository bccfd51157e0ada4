"""ukf_node's configuration (no ROS): its law parameters against pam_model's enumerations, and
the frozen, typed UkfConfig build_config makes once."""

import dataclasses

import pytest

from pam_common.node_params import ConfigError, defaults
from pam_common.testing import assert_takes_exactly
from pam_estimator.ukf_config import PARAMETERS, build_config
from pam_model.model_choices import ForceModel, FrictionLaw


@pytest.mark.parametrize('choice', [FrictionLaw, ForceModel])
def test_law_parameters_take_exactly_the_names_of_pam_model(choice):
    """friction_law and force_model offer pam_model's enumeration; each name reaches the filter."""
    parameter = 'force_model' if choice is ForceModel else 'friction_law'
    assert defaults(PARAMETERS)[parameter] == str(choice.PROPOSED)
    configs = assert_takes_exactly(build_config, PARAMETERS, parameter, choice.names())
    assert [getattr(c.ukf.model, parameter) for c in configs] == list(choice)


def test_the_configuration_is_frozen_and_typed():
    config = build_config({'initial_command': [4.0, 7.0], 'pressure_min': 2.0e3,
                           'cpu_affinity': [1, 0], 'frame_id': 'joint_a'})
    assert config.initial_command == (4.0, 7.0) and config.frame_id == 'joint_a'
    assert config.realtime.cpus == (0, 1) and not config.use_supply_pressure
    assert config.ukf.y_range == (2.0e3, defaults(PARAMETERS)['pressure_max'])
    assert isinstance(config.summary, tuple)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.frame_id = 'joint_b'
    with pytest.raises(TypeError):
        config.values['frame_id'] = 'joint_b'
    with pytest.raises(ConfigError, match='cpu_affinity'):
        build_config({'cpu_affinity': [-1]})
