"""The unmodelled effects of the simulated plant (pam_model/effects.py): each
effect alone against its equation, every effect off = the paper's plant bit for bit, the two named
scenarios with exactly the issue's numbers, and bad YAML refused naming the key.
"""

import math

import numpy as np
import pytest
import yaml

from pam_model.effects import Effects, EffectsPlant, MaxwellSlip
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.parameters import ParameterError, load_parameters
from pam_model.physics import muscle_lengths, muscle_volume
from pam_model.rig import SimulatedRig
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate

H = 1.0e-3
X0 = np.array([0.05, 0.0, 3.0e5, 4.0e5])


def inputs(n=600):
    k = np.arange(n)
    return np.column_stack([5.0 + 3.0 * np.sin(k / 97.0), 5.0 - 3.0 * np.sin(k / 53.0)])


# --- every effect off: the paper's plant, bit for bit ---------------------------------------------

@pytest.mark.parametrize('effects', [None, Effects(), Effects(hysteresis_elements=7,
                                                              hysteresis_travel=5.0),
                                     load_scenario('mild').effects])
def test_every_effect_off_is_the_papers_plant_bit_for_bit(effects):
    model = PamModel(params=load_scenario('mild').apply(load_parameters()))
    sensor = PressureSensor(noise_std=2000.0, bits=12)
    today = SimulatedRig(model, X0, sensor=sensor, seed=4)
    rig = SimulatedRig(model, X0, sensor=sensor, seed=4, effects=effects)
    assert rig.plant is None
    for u in inputs(300):
        for r in (today, rig):
            r.set_command(*u)
        a, b = today.sample(), rig.sample()
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.p_measured, b.p_measured)
        assert (a.torque, a.force) == (b.torque, b.force)
        today.step()
        rig.step()
    U = inputs()
    batch = simulate(model, U, X0, sensor, seed=2)
    same = simulate(model, U, X0, sensor, seed=2, effects=effects)
    np.testing.assert_array_equal(batch.table(), same.table())


@pytest.mark.parametrize('locked', [False, True])
def test_effects_kernel_with_every_effect_zero_steps_as_the_papers_kernel(locked):
    """EffectsPlant forced on with zero effects: the same numbers as physics.step_array."""
    model = PamModel(locked=locked)
    plant = EffectsPlant(model, Effects(), X0, (0.0, 0.0))
    x = X0.copy()
    for u in inputs(400):
        expected = model.step(x, u)
        got = plant.step(x, u, 0.0)
        np.testing.assert_array_equal(expected[0], got[0])
        assert expected[1:] == got[1:]
        x = expected[0]


# --- each effect alone against its equation -------------------------------------------------------

def test_valve_lag_is_first_order_with_its_time_constant():
    tau = 5.0e-3
    plant = EffectsPlant(PamModel(), Effects(valve_time_constant=tau), X0, (0.0, 0.0))
    filtered = []
    for _ in range(20):
        plant.openings((8.0, 4.0))
        filtered.append(plant.u_filtered.copy())
    t = H * np.arange(1, 21)
    np.testing.assert_allclose(np.array(filtered), np.column_stack(
        [8.0 * (1 - np.exp(-t / tau)), 4.0 * (1 - np.exp(-t / tau))]), rtol=1e-12)
    assert filtered[4][0] == pytest.approx(8.0 * (1 - math.exp(-1)), rel=1e-12)  # 63 % at tau
    # the opening held over a step is kappa of the filter's mean over that step
    plant = EffectsPlant(PamModel(), Effects(valve_time_constant=tau), X0, (0.0, 0.0))
    mean = 8.0 * (1 - tau / H * (1 - math.exp(-H / tau)))
    assert plant.openings((8.0, 8.0))[0] == pytest.approx(float(PamModel().openings(mean)))


def test_dead_volume_slows_the_pressure_response_by_the_volume_ratio():
    model = PamModel(locked=True)
    V_d = 6.0e-6
    x = np.array([0.0, 0.0, 3.0e5, 3.0e5])
    rates = []
    for effects in (Effects(valve_time_constant=0.0), Effects(dead_volume=V_d)):
        plant = EffectsPlant(model, effects, x, (9.0, 9.0))
        x_next = plant.step(x, (9.0, 9.0), 0.0)[0] if effects.active else model.step(
            x, (9.0, 9.0))[0]
        rates.append((x_next[2:] - x[2:]) / H)
    V = muscle_volume(muscle_lengths(0.0, model.params)[0], model.params)
    np.testing.assert_allclose(rates[1] / rates[0], V / (V + V_d), rtol=2e-3)


def test_supply_droops_with_the_inflow_and_ripples():
    e = Effects(supply_droop=2.0e4, supply_ripple=5.0e3, supply_ripple_frequency=0.2)
    model = PamModel()
    plant = EffectsPlant(model, e, X0, (0.0, 0.0))
    P0, T = model.params.P_tank, model.params.T
    choked = (2.0e5, 2.0e5)                   # below c* P_tank: both inflows choked
    assert plant.tank_pressure(0.0, choked, (1.0, 1.0), T) == pytest.approx(P0 - 2.0e4,
                                                                            rel=1e-12)
    assert plant.tank_pressure(0.0, choked, (0.5, 0.0), T) == pytest.approx(P0 - 0.5e4, rel=1e-9)
    assert plant.tank_pressure(0.0, choked, (0.0, 0.0), T) == P0        # venting draws nothing
    assert plant.tank_pressure(0.0, (P0, P0), (1.0, 1.0), T) == P0      # full muscles: no flow
    assert plant.tank_pressure(1.25, (P0, P0), (1.0, 1.0), T) == pytest.approx(P0 + 5.0e3)
    assert plant.tank_pressure(3.75, (P0, P0), (1.0, 1.0), T) == pytest.approx(P0 - 5.0e3)
    plant.step(np.array([0.0, 0.0, 2.0e5, 2.0e5]), (10.0, 10.0), 1.25)
    assert plant.record['P_tank'][0] == pytest.approx(P0 - 2.0e4 + 5.0e3, rel=1e-6)


def sweep(slip, s_path, P=5.0e5):
    return np.array([slip.update((s, s), (P, P))[0] for s in s_path])


def branch_at(s_path, force, s0, rising):
    """The force where the path crosses s0 going up (rising) or down."""
    for j in range(1, len(s_path)):
        if (s_path[j - 1] < s0 <= s_path[j]) if rising else (s_path[j - 1] > s0 >= s_path[j]):
            return force[j]
    raise AssertionError('path does not cross')


@pytest.mark.parametrize('points', [400, 4000])
def test_hysteresis_loop_is_twice_the_band_at_500kpa_and_rate_independent(points):
    band, P_out = 2.0, load_parameters().P_out
    quarter = np.linspace(0.0, 100.0, points)
    s_path = np.concatenate([quarter, quarter[::-1], -quarter, -quarter[::-1], quarter])
    force = sweep(MaxwellSlip(band, 4, 20.0, P_out), s_path)
    width = branch_at(s_path, force, 50.0, False) - branch_at(s_path, force, 50.0, True)
    assert width == pytest.approx(-2 * band, rel=1e-12)      # down branch above, up below
    assert np.max(np.abs(force)) == pytest.approx(band, rel=1e-12)
    # rate independence: the loop at 10x the speed has the same forces at the same inputs
    coarse = np.concatenate([quarter[::10], quarter[::-10], -quarter[::10], -quarter[::-10]])
    slow = sweep(MaxwellSlip(band, 4, 20.0, P_out), s_path)
    fast = sweep(MaxwellSlip(band, 4, 20.0, P_out), coarse)
    for s0 in (-60.0, -10.0, 30.0, 80.0):
        for rising in (False, True):
            assert branch_at(coarse, fast, s0, rising) == pytest.approx(
                branch_at(s_path, slow, s0, rising), abs=0.02 * band)


def test_hysteresis_band_scales_with_the_gauge_pressure():
    P_out = load_parameters().P_out
    slip = MaxwellSlip(2.0, 4, 20.0, P_out)
    half = P_out + 0.5 * (5.0e5 - P_out)
    force = sweep(slip, np.linspace(0.0, 200.0, 500), P=half)
    assert force[-1] == pytest.approx(1.0, rel=1e-12)
    assert sweep(MaxwellSlip(2.0, 4, 20.0, P_out), [0.0, 100.0], P=P_out)[-1] == 0.0


def test_hysteresis_forces_enter_the_rigs_torque():
    model = PamModel(locked=True)
    rig = SimulatedRig(model, [0.0, 0.0, 2.0e5, 2.0e5], effects=Effects(hysteresis_band=2.0),
                       u0=(10.0, 0.0))
    for _ in range(1500):
        rig.step()
    sample = rig.sample()
    F1, F2, tau = model.outputs(rig.x)
    F_h = rig.plant.F_h
    c = rig.plant.hysteresis.pressure_scale(rig.x[2:])
    assert F_h[0] == pytest.approx(2.0 * c[0], rel=1e-9)   # muscle 1 loaded: the full band at P1
    assert abs(F_h[1]) <= 2.0 * c[1] < 0.1                 # muscle 2 vented: (almost) no band
    assert sample.force == pytest.approx((F1 + F_h[0], F2 + F_h[1]), rel=1e-12)
    assert sample.torque - tau == pytest.approx(model.params.r * (F_h[0] - F_h[1]), rel=1e-9)


def locked_loop(charge_volts, vent_volts, band=2.0):
    """A locked rig with hysteresis only: P1 charged from 200 to 620 kPa, then vented to
    350 kPa (P2 vented). Returns the hysteresis force F1 - F1(model) where P1 crosses 500 kPa
    going up and going down."""
    model = PamModel(locked=True)
    rig = SimulatedRig(model, [0.0, 0.0, 2.0e5, 2.0e5], effects=Effects(hysteresis_band=band),
                       u0=(charge_volts, 0.0))
    crossings = {}
    for volts, target, rising in ((charge_volts, 6.2e5, True), (vent_volts, 3.5e5, False)):
        rig.set_command(volts, 0.0)
        before = rig.sample()
        while (before.x[2] < target) if rising else (before.x[2] > target):
            rig.step()
            now = rig.sample()
            if rising and before.x[2] < 5.0e5 <= now.x[2]:
                crossings['up'] = now
            if not rising and before.x[2] > 5.0e5 >= now.x[2]:
                crossings['down'] = now
            before = now
            assert rig.k < 20000, 'the pressure does not get there'
    return {key: sample.force[0] - float(model.outputs(sample.x)[0])
            for key, sample in crossings.items()}, rig.k


def test_plant_force_loop_at_500kpa_is_twice_the_band_at_two_speeds():
    """The torque meter's view in a locked run: at P1 = 500 kPa the rising and the falling branch
    of F1 differ by 2 B (fully open loop), the same at two charging/venting speeds."""
    fast, fast_steps = locked_loop(10.0, 0.0)
    slow, slow_steps = locked_loop(8.5, 2.5)
    assert slow_steps > 1.3 * fast_steps
    for loop in (fast, slow):
        assert loop['up'] == pytest.approx(2.0, rel=5e-3)
        assert loop['down'] == pytest.approx(-2.0, rel=5e-3)
        assert loop['up'] - loop['down'] == pytest.approx(4.0, rel=5e-3)


def test_temperature_drifts_linearly_then_holds():
    T0 = load_parameters().T
    plant = EffectsPlant(PamModel(), Effects(temperature_drift=3.0, temperature_drift_time=130.0),
                         X0, (0.0, 0.0))
    assert [plant.temperature(t) - T0 for t in (0.0, 65.0, 130.0, 500.0)] == pytest.approx(
        [0.0, 1.5, 3.0, 3.0], abs=1e-12)
    plant.step(X0, (5.0, 5.0), 65.0)
    assert plant.record['T'][0] == pytest.approx(T0 + 1.5)


def test_sensor_offset_gain_and_filter():
    e = Effects(sensor_offset=(2.0e3, -3.0e3), sensor_gain_error=(0.005, -0.005),
                sensor_time_constant=1.0e-3)
    rig = SimulatedRig(PamModel(), X0, sensor=PressureSensor(range_max=2e6), effects=e)
    np.testing.assert_allclose(rig.sample().p_measured,
                               [1.005 * 3.0e5 + 2.0e3, 0.995 * 4.0e5 - 3.0e3], rtol=1e-12)
    plant = rig.plant
    for k in range(1, 6):
        plant.filter_pressures(np.array([4.0e5, 2.0e5]))
        np.testing.assert_allclose(plant.P_filtered, [4.0e5 - 1.0e5 * math.exp(-k),
                                                      2.0e5 + 2.0e5 * math.exp(-k)], rtol=1e-12)


# --- the named scenarios ------------------------------------------------------------------------

def test_realistic_and_harsh_carry_exactly_the_issues_numbers():
    realistic, harsh = load_scenario('realistic'), load_scenario('harsh')
    mild, strong = load_scenario('mild'), load_scenario('strong')
    assert (realistic.factors, realistic.offsets, realistic.sensor) == (
        mild.factors, mild.offsets, mild.sensor)
    assert (harsh.factors, harsh.offsets, harsh.sensor) == (
        strong.factors, strong.offsets, strong.sensor)
    assert realistic.effects == Effects(
        valve_time_constant=5e-3, dead_volume=6e-6, supply_droop=20e3, supply_ripple=5e3,
        supply_ripple_frequency=0.2, hysteresis_band=2.0, temperature_drift=3.0,
        temperature_drift_time=130.0, sensor_offset=(2e3, -3e3), sensor_gain_error=(0.005, -0.005),
        sensor_time_constant=1e-3)
    assert harsh.effects == Effects(
        valve_time_constant=10e-3, dead_volume=12e-6, supply_droop=40e3, supply_ripple=10e3,
        supply_ripple_frequency=0.2, hysteresis_band=4.0, temperature_drift=6.0,
        temperature_drift_time=130.0, sensor_offset=(4e3, -6e3), sensor_gain_error=(0.01, -0.01),
        sensor_time_constant=2e-3)
    assert realistic.effects.active and not mild.effects.active


@pytest.mark.parametrize('name', ['realistic', 'other_forms'])
def test_realistic_plant_runs_finite_in_the_batch_simulator(name):
    scenario = load_scenario(name)
    model = PamModel(params=scenario.apply(load_parameters()))
    run = simulate(model, inputs(2000), X0, scenario.sensor, seed=1, effects=scenario.effects)
    assert np.all(np.isfinite(run.table()))
    plain = simulate(model, inputs(2000), X0, scenario.sensor, seed=1)
    assert np.max(np.abs(run.x[:, 2:] - plain.x[:, 2:])) > 1.0e3     # the effects act


@pytest.mark.parametrize('effects, words', [
    ({'valve_time_constant': -0.005}, ['effects', 'valve_time_constant', '>= 0']),
    ({'dead_volume': float('nan')}, ['effects', 'dead_volume']),
    ({'sensor_time_constant': '.inf'}, ['effects', 'sensor_time_constant']),
    ({'valve_lag': 0.005}, ['effects', "'valve_lag'"]),
    ({'sensor_offset': [2000.0]}, ['effects', 'sensor_offset', 'pair']),
    ({'sensor_gain_error': [-1.5, 0.0]}, ['effects', 'sensor_gain_error']),
    ({'hysteresis_elements': 2.5}, ['effects', 'hysteresis_elements']),
    ({'hysteresis_travel': 0.0}, ['effects', 'hysteresis_travel']),
    ({'temperature_drift_time': -1.0}, ['effects', 'temperature_drift_time']),
    ({'supply_droop': 'lots'}, ['effects', 'supply_droop', 'number']),
    # the second family's keys (test_effects_other_forms.py)
    ({'valve_delay': -0.001}, ['valve_delay', '>= 0']),
    ({'valve_natural_frequency': float('nan')}, ['valve_natural_frequency']),
    ({'valve_damping': 0.0}, ['valve_damping', '> 0']),
    ({'valve_time_constant': 0.005, 'valve_natural_frequency': 30.0},
     ['valve_time_constant', 'valve_natural_frequency', 'not both']),
    ({'bouc_wen_band': 'lots'}, ['bouc_wen_band', 'number']),
    ({'bouc_wen_band': float('inf')}, ['bouc_wen_band', 'finite']),
    ({'bouc_wen_driver': 'force'}, ['bouc_wen_driver', 'length, pressure']),
    ({'bouc_wen_length_travel': 0.0}, ['bouc_wen_length_travel', '> 0']),
    ({'bouc_wen_pressure_travel': -1.0}, ['bouc_wen_pressure_travel', '> 0']),
    ({'tank_volume': -1e-3}, ['tank_volume', '>= 0']),
    ({'compressor_flow': 2.5e-4}, ['compressor_flow', 'tank_volume > 0']),
    ({'compressor_band': 0.0}, ['compressor_band', '> 0']),
    ({'sensor_filter_order': 5}, ['sensor_filter_order', '1..4']),
    ({'sensor_filter_order': 1.5}, ['sensor_filter_order', 'integer']),
])
def test_bad_effects_are_refused_in_one_line_naming_the_key(tmp_path, effects, words):
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump({'name': 'bad', 'effects': effects}))
    with pytest.raises(ParameterError) as info:
        load_scenario(path)
    text = str(info.value)
    assert '\n' not in text and str(path) in text
    for word in words:
        assert word in text, text
