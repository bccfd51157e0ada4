"""Scalar and vectorised paths, guards against NaN/inf, RK4 order, friction laws and force
models."""

import math

import numpy as np
import pytest

from pam_model import physics, physics_vectorised
from pam_model.model import PamModel
from pam_model.model_choices import ForceModel, FrictionLaw
from pam_model.simulate import simulate


def random_states(rng, n, extreme=False):
    if extreme:
        scale = np.array([10.0, 1e4, 1e7, 1e7])
        return rng.uniform(-1, 1, (n, 4)) * scale * 10.0 ** rng.integers(-3, 4, (n, 1))
    return np.column_stack([rng.uniform(-0.45, 0.45, n), rng.uniform(-3, 3, n),
                            rng.uniform(1.2e5, 7.2e5, n), rng.uniform(1.2e5, 7.2e5, n)])


@pytest.mark.parametrize('friction', FrictionLaw.names())
@pytest.mark.parametrize('force', ForceModel.names())
@pytest.mark.parametrize('locked', [False, True])
def test_scalar_and_vectorised_steps_agree(friction, force, locked):
    rng = np.random.default_rng(7)
    model = PamModel(friction=friction, force=force, locked=locked)
    X = random_states(rng, 300)
    U = rng.uniform(-1, 11, (300, 2))
    X_vec, T_f_vec, sigma_vec = model.step_many(X, U)
    for j in range(len(X)):
        x, T_f, sigma = model.step(X[j], U[j])
        np.testing.assert_allclose(x, X_vec[j], rtol=1e-12, atol=1e-12 * np.abs(x).max())
        assert T_f == pytest.approx(T_f_vec[j], rel=1e-12, abs=1e-15)
        assert sigma == sigma_vec[j]


def test_scalar_path_runs_as_plain_python_too():
    """The py_func path (no compilation) gives the same step: the filter oracle relies on it."""
    model = PamModel()
    p, vm = model.params, model.valve_map
    x = (0.1, 0.5, 4e5, 3e5)
    a = (physics.valve_opening.py_func(6.0, vm.u, vm.alpha),
         physics.valve_opening.py_func(4.0, vm.u, vm.alpha))
    codes = (int(FrictionLaw.PROPOSED), int(ForceModel.PROPOSED))
    compiled = physics.rk4_step(*x, *a, 1e-3, p, *codes, False)
    # py_func of the outer function still calls compiled inner functions; results must match
    plain = physics.rk4_step.py_func(*x, *a, 1e-3, p, *codes, False)
    np.testing.assert_allclose(compiled[:5], plain[:5], rtol=1e-14)


@pytest.mark.parametrize('friction', FrictionLaw.names())
@pytest.mark.parametrize('locked', [False, True])
def test_no_nan_or_inf_from_extreme_finite_states_and_inputs(friction, locked):
    rng = np.random.default_rng(3)
    model = PamModel(friction=friction, locked=locked)
    X = random_states(rng, 2000, extreme=True)
    U = rng.uniform(-1e6, 1e6, (2000, 2))
    U[::7] = np.nan
    U[::11, 1] = np.inf
    X_next, T_f, sigma = model.step_many(X, U)
    assert np.all(np.isfinite(X_next)) and np.all(np.isfinite(T_f))
    assert np.all((sigma >= 1) & (sigma <= 18))
    for j in range(0, 2000, 50):
        x, T, s = model.step(X[j], U[j])
        assert np.all(np.isfinite(x)) and math.isfinite(T) and 1 <= s <= 18


def test_full_range_inputs_keep_the_plant_finite():
    """Bang-bang full-range voltages drive psi toward V = 0 (about 34 deg): the V floor holds."""
    t = np.arange(20000) * 1e-3
    square = np.where(np.sin(2 * np.pi * 0.2 * t) > 0, 10.0, 0.0)
    run = simulate(PamModel(), np.column_stack([square, 10.0 - square]), [0.0, 0.0, 4.5e5, 4.5e5])
    assert np.all(np.isfinite(run.x))
    assert np.abs(run.x[:, 0]).max() < physics.PSI_MAX


def rk4_error(h, T=0.05):
    """Error of the smooth model (no friction) at time T with step h against a fine reference."""
    x0 = np.array([0.05, 0.0, 2.5e5, 3.0e5])
    u = np.array([8.0, 3.0])   # charging PAM1 from the choked region, discharging PAM2

    def run(step):
        model = PamModel(friction='none', h=step)
        x = x0.copy()
        for _ in range(round(T / step)):
            x, _, _ = model.step(x, u)
        return x
    scale = np.array([1.0, 10.0, 1e5, 1e5])
    return np.max(np.abs(run(h) - run(h / 32.0)) / scale)


def test_rk4_converges_with_fourth_order():
    e1, e2 = rk4_error(1e-3), rk4_error(0.5e-3)
    order = math.log2(e1 / e2)
    assert 3.5 < order < 4.5, order


def test_locked_joint_holds_angle_and_measures_torque():
    model = PamModel(locked=True)
    run = simulate(model, np.tile([8.0, 3.0], (2000, 1)), [0.0, 0.0, 4.5e5, 4.5e5])
    assert np.all(run.x[:, 0] == 0.0) and np.all(run.x[:, 1] == 0.0)
    assert run.torque[-1] > 1.0                      # raising u1 gives a positive torque


def test_free_joint_moves_positive_when_u1_rises():
    run = simulate(PamModel(), np.tile([7.0, 4.0], (3000, 1)), [0.0, 0.0, 4.5e5, 4.5e5])
    assert run.x[-1, 2] > 5e5 > run.x[-1, 3]
    assert math.degrees(run.x[-1, 0]) > 5.0


@pytest.mark.parametrize('friction', FrictionLaw.names()[1:])
def test_alternative_friction_laws_change_the_motion(friction):
    U = np.tile([6.5, 4.5], (800, 1))
    x0 = [0.0, 0.0, 4.5e5, 4.5e5]
    base = simulate(PamModel(), U, x0)
    alt = simulate(PamModel(friction=friction), U, x0)
    assert np.max(np.abs(alt.x[:, 0] - base.x[:, 0])) > 1e-4


@pytest.mark.parametrize('force', ForceModel.names()[1:])
def test_alternative_force_models_change_the_torque(force):
    X = np.array([[0.2, 0.0, 4e5, 3e5]])
    assert abs(PamModel(force=force).outputs(X)[2] - PamModel().outputs(X)[2]) > 1e-3


def test_subsystem_index_covers_18_subsystems():
    p = PamModel().params
    pressures = [1.5e5, 3e5, 5e5]
    seen = {physics.subsystem_index(s, P1, P2, p) for s in (False, True)
            for P1 in pressures for P2 in pressures}
    assert seen == set(range(1, 19))
    sliding = np.array([False, True])
    vec = physics_vectorised.subsystem_indices(sliding, np.array([1.5e5, 5e5]),
                                               np.array([3e5, 1.5e5]), p)
    assert list(vec) == [1 + 0 + 0 + 1, 1 + 9 + 6 + 0]


def test_unknown_law_names_are_rejected():
    with pytest.raises(ValueError, match='friction law'):
        PamModel(friction='stribeck')
    with pytest.raises(ValueError, match='force model'):
        PamModel(force='chou')


def test_outputs_of_one_state_equal_the_array_form():
    """PamModel.outputs_at (one compiled call, the per-sample path) gives outputs()'s numbers."""
    model = PamModel()
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.uniform(-0.6, 0.6, 200), rng.normal(0.0, 1.0, 200),
                         rng.uniform(1e5, 8e5, 200), rng.uniform(1e5, 8e5, 200)])
    F1, F2, tau = model.outputs(X)
    for i in range(len(X)):
        assert model.outputs_at(X[i]) == (F1[i], F2[i], tau[i])
