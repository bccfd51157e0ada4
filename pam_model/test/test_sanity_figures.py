"""The sanity figures of MODEL.md section 3 and the kappa check figures of section 4."""

import math

import numpy as np
import pytest

from pam_model import physics
from pam_model.model import PamModel
from pam_model.model_choices import ForceModel
from pam_model.parameters import load_parameters
from pam_model.simulate import simulate
from pam_model.valve_map import (
    DEFAULT_STATIC_CURVE,
    calibrate_valve_map,
    data_path,
    load_valve_map,
    opening_for_steady_pressure,
    read_two_column_csv,
    steady_pressure,
)

P = load_parameters('default')
PROPOSED_FORCE = int(ForceModel.PROPOSED)   # the scalar kernels take the integer value


def crossing_time(t, signal, level, rising):
    hit = signal >= level if rising else signal <= level
    assert hit.any(), f'never reached {level}'
    return t[np.argmax(hit)]


def test_volume_at_rest_length_and_zero_volume_length():
    assert physics.muscle_volume(P.L0, P) == pytest.approx(3.627e-5, rel=1e-4)
    roots = np.roots([P.D1, P.D2, P.D3])
    l_zero = max(roots.real)
    assert l_zero == pytest.approx(0.18588, abs=1e-5)
    assert math.degrees(math.asin((l_zero - P.L0) / P.r)) == pytest.approx(34.9, abs=0.05)


def test_forces_at_rest_length_and_500_kPa():
    F1, F2 = physics.muscle_forces(0.0, 5e5, 5e5, P, PROPOSED_FORCE)
    assert F1 == pytest.approx(53.70, abs=0.005)
    assert F2 == pytest.approx(53.81, abs=0.005)


def test_printed_set_differs_by_31_N():
    printed = load_parameters('printed')
    F1, F2 = physics.muscle_forces(0.0, 5e5, 5e5, printed, PROPOSED_FORCE)
    assert F1 == pytest.approx(53.70, abs=0.005)
    assert F2 == pytest.approx(22.3, abs=0.05)


def test_rest_angle_at_equal_pressures_is_about_zero():
    held = P.replace(k1=0.0, k2=0.0)   # pressures held
    model = PamModel(params=held, friction='linear')
    run = simulate(model, np.zeros((3000, 2)), [0.0, 0.0, 5e5, 5e5])
    assert abs(math.degrees(run.x[-1, 0])) < 0.1


def test_steady_pressure_alpha_half_and_closed_form_inverse():
    assert steady_pressure(0.5, P) == pytest.approx(573e3, abs=500)
    for alpha in (0.1, 0.3, 0.5, 0.8):
        assert opening_for_steady_pressure(steady_pressure(alpha, P), P)[0] == pytest.approx(
            alpha, abs=1e-9)


def test_steady_pressure_matches_a_long_simulation():
    """Step (a) by root finding agrees with the model run to rest at constant alpha."""
    model = PamModel(locked=True)
    u = 6.0
    alpha = float(model.openings(u))
    run = simulate(model, np.full((30000, 2), u), [0.0, 0.0, 4e5, 6.5e5])
    assert run.x[-1, 2] == pytest.approx(steady_pressure(alpha, P), abs=200)
    assert run.x[-1, 3] == pytest.approx(steady_pressure(alpha, P), abs=200)


def test_charging_from_200_kPa_with_alpha_1():
    model = PamModel(locked=True)
    run = simulate(model, np.full((3500, 2), 10.0), [0.0, 0.0, 2e5, 2e5])
    assert crossing_time(run.t, run.x[:, 2], 375e3, True) == pytest.approx(0.79, abs=0.02)
    assert crossing_time(run.t, run.x[:, 2], 700e3, True) == pytest.approx(2.8, abs=0.05)


def test_discharging_from_700_kPa_with_alpha_0():
    model = PamModel(locked=True)
    run = simulate(model, np.zeros((3500, 2)), [0.0, 0.0, 7e5, 7e5])
    assert crossing_time(run.t, run.x[:, 2], 400e3, False) == pytest.approx(1.2, abs=0.03)
    assert crossing_time(run.t, run.x[:, 2], 200e3, False) == pytest.approx(2.7, abs=0.05)


def test_stiffness_natural_frequency_and_damping_with_pressures_held():
    held = P.replace(k1=0.0, k2=0.0)
    eps = 1e-6
    tau = [physics.joint_torque(s, *physics.muscle_forces(s, 5e5, 5e5, held, PROPOSED_FORCE), held)
           for s in (-eps, eps)]
    stiffness = -(tau[1] - tau[0]) / (2 * eps) + held.k_s
    assert stiffness == pytest.approx(8.0, abs=0.1)
    run = simulate(PamModel(params=held, friction='linear'), np.zeros((1000, 2)),
                   [math.radians(1.0), 0.0, 5e5, 5e5])
    psi = run.x[:, 0]
    peaks = [j for j in range(1, len(psi) - 1) if psi[j - 1] < psi[j] >= psi[j + 1]]
    period = (peaks[1] - peaks[0]) * 1e-3
    assert 1.0 / period == pytest.approx(21.0, abs=1.0)
    zeta = math.log(psi[peaks[0]] / psi[peaks[1]]) / (2 * math.pi)
    assert zeta == pytest.approx(0.02, abs=0.005)


def test_release_from_3_degrees_sticks_within_the_friction_dead_band():
    """With the proposed friction the swing dies in a few crossings and the joint sticks with
    |psi| below T_c / K (about 0.94 deg at 500 kPa) and psi_dot (almost) zero.

    MODEL.md quotes 'crosses zero twice within ~25 ms, then sticks near +1 deg'; with the pressures
    held this model crosses once and sticks at about -0.9 deg (same dead band, see the issue note).
    """
    held = P.replace(k1=0.0, k2=0.0)
    run = simulate(PamModel(params=held), np.zeros((400, 2)), [math.radians(3.0), 0.0, 5e5, 5e5])
    psi = np.degrees(run.x[:, 0])
    crossings = np.flatnonzero(np.diff(np.sign(psi)) != 0)
    assert 1 <= len(crossings) <= 2 and crossings[-1] < 40
    assert 0.3 < abs(psi[-1]) < 0.95
    assert abs(run.x[-1, 1]) < 1e-3
    assert run.subsystem[-1] <= 9                       # sticking subsystems are 1..9


KAPPA_CHECK = {0: 0.0, 2: .0532, 3: .1344, 4: .2240, 5: .3238, 5.5: .3939, 6: .4708, 7: .6382,
               8: .7801, 9: .8655, 10: 1.0}


def test_kappa_procedure_reproduces_the_check_figures():
    u, P_bar = read_two_column_csv(data_path(DEFAULT_STATIC_CURVE))
    valve_map = calibrate_valve_map(u, P_bar, P)
    for voltage, alpha in KAPPA_CHECK.items():
        assert valve_map(voltage) == pytest.approx(alpha, abs=6e-5)


def test_shipped_kappa_table_is_the_procedure_output():
    u, P_bar = read_two_column_csv(data_path(DEFAULT_STATIC_CURVE))
    fresh = calibrate_valve_map(u, P_bar, P)
    shipped = load_valve_map('default')
    np.testing.assert_allclose(shipped.u, fresh.u)
    np.testing.assert_allclose(shipped.alpha, fresh.alpha, atol=1e-6)


def test_kappa_is_monotone_and_pinned():
    valve_map = load_valve_map()
    u = np.linspace(-5, 15, 401)
    alpha = valve_map(u)
    assert np.all(np.diff(alpha) >= 0)
    assert valve_map(0.0) == 0.0 and valve_map(10.0) == 1.0
    assert valve_map(float('nan')) == 0.0
    assert physics.valve_opening(float('nan'), valve_map.u, valve_map.alpha) == 0.0
    assert physics.valve_opening(7.0, valve_map.u, valve_map.alpha) == pytest.approx(
        float(valve_map(7.0)), abs=1e-15)
