"""The compiled kernels of the plant's effects on the 1 kHz path (pam_model.effects_physics:
maxwell_slip_update, supply_inflow) and ValveLag's scalar form give, bit for bit, what the array
formulas of their docstrings give (the forms they replaced), over random sequences of inputs."""

import numpy as np
import pytest

from pam_model.effects import HYSTERESIS_PRESSURE, MaxwellSlip, ValveLag
from pam_model.effects_physics import supply_inflow
from pam_model.model import PamModel
from pam_model.parameters import load_parameters
from pam_model.physics import gas_constants, inflow_per_area, valve_opening
from pam_model.valve_map import load_valve_map


def _array_maxwell_slip(slip, stiffness, p_out, anchor, s, P):
    """The array form: clip(k (s - a), -f c(P), f c(P)), a = s - F / k, summed per muscle."""
    s = np.asarray(s, dtype=float).reshape(-1, 1)
    c = np.maximum(np.asarray(P, dtype=float) - p_out, 0.0) / (HYSTERESIS_PRESSURE - p_out)
    limit = slip * c.reshape(-1, 1)
    force = np.clip(stiffness * (s - anchor), -limit, limit)
    return force.sum(axis=1), s - force / stiffness


@pytest.mark.parametrize('elements', [1, 2, 4, 7, 8, 12, 21])
def test_maxwell_slip_kernel_equals_the_array_form(elements):
    rng = np.random.default_rng(elements)
    hysteresis = MaxwellSlip(2.0, elements, 5.0, 1.013e5)
    s0, P0 = rng.normal(300.0, 50.0, 2), rng.uniform(1e5, 8e5, 2)
    hysteresis.update(s0, P0)
    anchor = hysteresis.anchor.copy()
    for _ in range(2000):
        s = s0 + np.cumsum(rng.normal(0.0, 3.0, 2))
        P = rng.uniform(0.9e5, 8e5, 2)
        expected, anchor = _array_maxwell_slip(hysteresis.slip, hysteresis.stiffness,
                                               hysteresis.p_out, anchor, s, P)
        got = hysteresis.update(s, P)
        assert np.array_equal(got, expected), (got, expected)
        assert np.array_equal(hysteresis.anchor, anchor)


def test_valve_lag_scalar_form_equals_the_array_form():
    model = PamModel(params=load_parameters('default'), valve_map=load_valve_map('default'))
    lag = ValveLag(model.valve_map, model.h, 0.005, (5.5, 5.5))
    u_f = np.array([5.5, 5.5])
    rng = np.random.default_rng(3)
    for _ in range(2000):
        u = rng.uniform(0.0, 10.0, 2)
        mean = u + (u_f - u) * lag.mean_weight
        u_f = u + (u_f - u) * lag.decay
        expected = tuple(valve_opening(float(m), model.valve_map.u, model.valve_map.alpha)
                         for m in mean)
        assert lag.openings(u) == expected
        assert np.array_equal(lag.u_filtered, u_f)


def test_supply_inflow_kernel_equals_the_sum_of_the_two_valves():
    model = PamModel(params=load_parameters('default'), valve_map=load_valve_map('default'))
    record = model.params_array.copy()
    rng = np.random.default_rng(4)
    for _ in range(500):
        record['T'] = rng.uniform(290.0, 310.0)
        p = record[0]
        P, alpha = rng.uniform(1e5, 7e5, 2), rng.uniform(0.0, 1.0, 2)
        g = gas_constants(p)
        expected = sum(alpha[i] * (p['A1_1'] if i == 0 else p['A1_2'])
                       * inflow_per_area(P[i], p, g) for i in range(2))
        assert supply_inflow(P[0], P[1], alpha[0], alpha[1], record) == expected
