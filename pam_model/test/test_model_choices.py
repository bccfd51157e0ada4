"""The named friction laws and force models: the names users type, the integer values the kernels
take, and the same acceptance and the same refusal at every entry of pam_model (the scalar path
behind PamModel.step, the vectorised path, PamModel, the pam-* tools). The node configs hold the
same contract in pam_driver/test/test_sim_config.py and pam_estimator/test/test_ukf_config.py.
"""

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pam_model import physics, physics_vectorised
from pam_model.cli.common import add_model_arguments
from pam_model.model import PamModel
from pam_model.model_choices import ForceModel, FrictionLaw
from pam_model.parameters import load_parameters

P = load_parameters('default')
X = np.array([[0.1, 0.5, 4.0e5, 3.0e5]])
ALPHA = np.array([0.6, 0.4])

#: Values that are no member: near misses of a name, numbers beside the values, other types.
NOT_MEMBERS = ['sticky', '', 'PROPOSED', 'Proposed', ' proposed', 'no-offset', -1, 5, 99, True,
               None, 1.0, '0']


def refusal(choice, value) -> str:
    """The one message every entry gives for a value that is no member of `choice`."""
    return (f'unknown {choice.kind()} {value!r}; choose one of: '
            + ', '.join(choice.names()))


def test_the_names_users_type_and_the_kernel_values_are_fixed():
    """Parameter files, launch arguments and bags name these; the cached kernels hold the values."""
    assert [(str(m), int(m)) for m in FrictionLaw] == [
        ('proposed', 0), ('linear', 1), ('coulomb', 2), ('tondu', 3), ('none', 4)]
    assert [(str(m), int(m)) for m in ForceModel] == [
        ('proposed', 0), ('length_independent', 1), ('no_offset', 2)]
    assert FrictionLaw.kind() == 'friction law' and ForceModel.kind() == 'force model'
    assert f'friction {FrictionLaw.TONDU}' == 'friction tondu'   # the log lines and labels


@pytest.mark.parametrize('choice', [FrictionLaw, ForceModel])
def test_every_member_is_found_by_its_name_its_value_and_itself(choice):
    for member in choice:
        assert choice.from_name(str(member)) is member
        for given in (member, str(member), int(member), np.int64(int(member))):
            assert choice.coerce(given) is member


@pytest.mark.parametrize('choice', [FrictionLaw, ForceModel])
@pytest.mark.parametrize('value', NOT_MEMBERS)
def test_anything_else_is_refused_with_the_names_listed(choice, value):
    with pytest.raises(ValueError) as caught:
        choice.coerce(value)
    assert str(caught.value) == refusal(choice, value)


def test_a_member_of_the_other_enumeration_is_refused():
    with pytest.raises(ValueError, match='unknown friction law'):
        FrictionLaw.coerce(ForceModel.NO_OFFSET)
    with pytest.raises(ValueError, match='unknown force model'):
        ForceModel.coerce(FrictionLaw.TONDU)


def scalar_step(friction=FrictionLaw.PROPOSED, force=ForceModel.PROPOSED):
    """The scalar (numba) path as the nodes reach it: through PamModel.step."""
    return PamModel(friction=friction, force=force).step(X[0], (6.0, 4.0))


def vectorised_step(friction=FrictionLaw.PROPOSED, force=ForceModel.PROPOSED):
    """The vectorised path called directly (it takes members, names or values)."""
    return physics_vectorised.rk4_steps(X, ALPHA, 1e-3, P, friction, force)


def vectorised_forces(friction=FrictionLaw.PROPOSED, force=ForceModel.PROPOSED):
    return physics_vectorised.muscle_forces(X[:, 0], X[:, 2], X[:, 3], P, force)


#: (entry, the enumeration it is checked for): each path with each of its two choices.
ENTRIES = [(scalar_step, FrictionLaw), (scalar_step, ForceModel), (vectorised_step, FrictionLaw),
           (vectorised_step, ForceModel), (vectorised_forces, ForceModel)]


def accepted(entry, choice, candidates):
    """The candidates the entry takes; every refusal must be the common message."""
    keyword = 'friction' if choice is FrictionLaw else 'force'
    taken = []
    for value in candidates:
        try:
            entry(**{keyword: value})
        except ValueError as exc:
            assert str(exc) == refusal(choice, value), (entry.__name__, value)
        else:
            taken.append(value)
    return taken


@pytest.mark.parametrize('entry, choice', ENTRIES,
                         ids=[f'{e.__name__}-{c.__name__}' for e, c in ENTRIES])
def test_both_physics_paths_take_exactly_the_members(entry, choice):
    names = list(choice.names())
    assert accepted(entry, choice, names + NOT_MEMBERS) == names
    values = [int(m) for m in choice]
    assert accepted(entry, choice, list(range(-2, len(values) + 3))) == values
    assert accepted(entry, choice, list(choice)) == list(choice)


@pytest.mark.parametrize('friction', list(FrictionLaw))
def test_the_scalar_kernels_are_compiled_for_plain_integers_only(friction):
    """PamModel hands int(law) to numba: a member would compile (and cache) a second
    specialisation typed IntEnumMember."""
    model = PamModel(friction=friction, force=ForceModel.NO_OFFSET)
    assert (model.friction, model.force) == (str(friction), 'no_offset')
    assert model.friction_law is friction and model.force_model is ForceModel.NO_OFFSET
    assert type(model.friction_code) is int and type(model.force_code) is int
    model.step(X[0], (6.0, 4.0))
    assert physics.step_array.signatures
    assert not any('Enum' in str(signature) for signature in physics.step_array.signatures)


def test_a_model_is_the_same_whether_named_or_given_the_member():
    by_name = PamModel(friction='tondu', force='length_independent')
    by_member = PamModel(friction=FrictionLaw.TONDU, force=ForceModel.LENGTH_INDEPENDENT)
    assert (by_name.friction, by_name.force) == (by_member.friction, by_member.force)
    np.testing.assert_array_equal(by_name.step(X[0], (6.0, 4.0))[0],
                                  by_member.step(X[0], (6.0, 4.0))[0])


def test_the_tools_offer_exactly_the_names():
    parser = argparse.ArgumentParser()
    add_model_arguments(parser)
    for option, choice in (('--friction', FrictionLaw), ('--force', ForceModel)):
        action = next(a for a in parser._actions if option in a.option_strings)
        assert tuple(action.choices) == choice.names()
        assert action.default == str(choice.PROPOSED)
        for member in choice:
            assert getattr(parser.parse_args([option, str(member)]),
                           option.lstrip('-')) == str(member)


def test_a_tool_refuses_an_unknown_law_in_one_line():
    tool = Path(sys.executable).parent / 'pam-simulate'
    tool = str(tool) if tool.exists() else shutil.which('pam-simulate')
    assert tool, 'pam-simulate is not installed: run the set-up (make setup)'
    result = subprocess.run([tool, '--friction', 'sticky', '-o', os.devnull], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2
    assert "--friction: invalid choice: 'sticky'" in result.stderr
    assert all(repr(name) in result.stderr for name in FrictionLaw.names())
