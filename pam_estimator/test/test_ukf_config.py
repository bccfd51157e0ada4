"""ukf_node's law parameters against pam_model's enumerations (no ROS)."""

import pytest

from pam_common.node_params import defaults
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
