"""The second family of unmodelled effects (pam_model/effects.py: Bouc-Wen hysteresis, second-order
valve spool, transport delay, finite supply tank with a compressor, sensor filter order): each
kernel against a plain python/numpy form of its equation, every new key at 0 leaving the plant
what it was, and the `other_forms` scenario. The new keys' validation: test_effects.py's
test_bad_effects_are_refused_in_one_line_naming_the_key."""

import math

import numpy as np
import pytest

from pam_model.effects import (
    BoucWen,
    CommandDelay,
    Effects,
    EffectsPlant,
    SecondOrderValve,
    SupplyTank,
    pressure_scale,
)
from pam_model.effects_physics import bouc_wen_update, spool_second_order, tank_update
from pam_model.mismatch import BUILTIN_SCENARIOS, load_scenario
from pam_model.model import PamModel
from pam_model.parameters import load_parameters
from pam_model.physics import valve_opening
from pam_model.rig import SimulatedRig
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate

H = 1.0e-3
X0 = np.array([0.05, 0.0, 3.0e5, 4.0e5])
P_OUT = 1.013e5
#: The new keys' magnitudes at 0 and their shapes away from the defaults: nothing is on.
NEW_KEYS_OFF = dict(valve_delay=0.0, valve_natural_frequency=0.0, valve_damping=0.3,
                    bouc_wen_band=0.0, bouc_wen_driver='pressure', bouc_wen_length_travel=2e-3,
                    bouc_wen_pressure_travel=5e4, tank_volume=0.0, compressor_flow=0.0,
                    compressor_band=1e4, sensor_filter_order=1)


def inputs(n=400):
    k = np.arange(n)
    return np.column_stack([5.0 + 3.0 * np.sin(k / 97.0), 5.0 - 3.0 * np.sin(k / 53.0)])


# --- every new key at 0: the plant is what it was ------------------------------------------------

def test_new_keys_at_zero_switch_nothing_on_and_step_the_papers_plant_bit_for_bit():
    effects = Effects(**NEW_KEYS_OFF)
    assert not effects.active and effects.describe() == 'none'
    model = PamModel(params=load_scenario('mild').apply(load_parameters()))
    sensor = PressureSensor(noise_std=2000.0, bits=12)
    assert SimulatedRig(model, X0, sensor=sensor, effects=effects).plant is None
    np.testing.assert_array_equal(simulate(model, inputs(), X0, sensor, seed=2).table(),
                                  simulate(model, inputs(), X0, sensor, seed=2,
                                           effects=effects).table())


def test_realistic_with_the_new_keys_at_zero_is_the_realistic_plant_bit_for_bit():
    """The `realistic` plant stepped with the new keys written at 0 (shapes changed) gives the
    same numbers as without them, and the numbers the plant gave before the new forms existed
    (recorded from the previous code, to 1e-12 for another machine's libm)."""
    scenario = load_scenario('realistic')
    model = PamModel(params=scenario.apply(load_parameters()))
    base = simulate(model, inputs(), X0, scenario.sensor, seed=1, effects=scenario.effects)
    zeros = Effects(**{**{f: getattr(scenario.effects, f) for f in (
        'valve_time_constant', 'dead_volume', 'supply_droop', 'supply_ripple',
        'supply_ripple_frequency', 'hysteresis_band', 'temperature_drift',
        'sensor_offset', 'sensor_gain_error', 'sensor_time_constant')}, **NEW_KEYS_OFF})
    same = simulate(model, inputs(), X0, scenario.sensor, seed=1, effects=zeros)
    np.testing.assert_array_equal(base.table(), same.table())
    before = {99: ([-0.04221557061448922, 0.0015494394333443514, 320003.3676202619,
                    375311.76321921364], 0.024934736641684427, [324542.12454212457,
                                                                368253.9682539683]),
              399: ([-0.03328602415171978, 3.107264723498025e-05, 338420.0009462206,
                     382034.6763839056], 0.04501905223287442, [344810.7448107448,
                                                               376800.97680097684])}
    for j, (x, torque, measured) in before.items():
        np.testing.assert_allclose(base.x[j], x, rtol=1e-12, atol=1e-15)
        assert base.torque[j] == pytest.approx(torque, rel=1e-10)
        np.testing.assert_allclose(base.p_measured[j], measured, rtol=1e-12)


# --- Bouc-Wen -------------------------------------------------------------------------------------

def _bouc_wen_ode(z, dx, substeps=20000):
    """dz = dx - (|dx| z + dx |z|) / 2 integrated by plain forward Euler in tiny steps."""
    d = dx / substeps
    for _ in range(substeps):
        z += d - (abs(d) * z + d * abs(z)) / 2.0
    return z


def test_bouc_wen_kernel_solves_its_differential_law():
    rng = np.random.default_rng(5)
    z, before = np.zeros(2), np.zeros(2)
    reference = np.zeros(2)
    drive = np.zeros(2)
    force = np.empty(2)
    for _ in range(60):
        drive = drive + rng.normal(0.0, 0.6, 2)
        P = rng.uniform(0.9e5, 7e5, 2)
        for i in range(2):
            reference[i] = _bouc_wen_ode(reference[i], drive[i] - before[i])
        bouc_wen_update(drive.copy(), before, z, -2.5, P, P_OUT, 5.0e5, force)
        np.testing.assert_allclose(z, reference, atol=1e-4)
        np.testing.assert_allclose(before, drive)
        np.testing.assert_allclose(force, -2.5 * np.maximum(P - P_OUT, 0.0) / (5.0e5 - P_OUT) * z,
                                   rtol=1e-15)
        assert np.all(np.abs(z) < 1.0)


def test_bouc_wen_loop_opens_to_twice_the_band_with_its_orientation():
    """Driven up and down by many travels at 500 kPa: the force saturates at +-B (c = 1), larger
    while the driver rises for B > 0, smaller for B < 0."""
    for band in (2.5, -2.5):
        bw = BoucWen(band, 1.0e-3, P_OUT)
        lengths = np.concatenate([np.linspace(0.160, 0.170, 200), np.linspace(0.170, 0.160, 200)])
        force = np.array([bw.update((length, length), (5.0e5, 5.0e5))[0] for length in lengths])
        assert force[199] == pytest.approx(band, rel=1e-3)       # rising: z -> +1
        assert force[-1] == pytest.approx(-band, rel=1e-3)       # falling: z -> -1
        rising, falling = force[100], force[300]                 # both at l = 0.165 m
        assert (rising - falling) * band > 0.0
    assert pressure_scale(5.0e5, P_OUT) == 1.0 and pressure_scale(0.9e5, P_OUT) == 0.0


@pytest.mark.parametrize('driver', ['length', 'pressure'])
def test_bouc_wen_force_enters_the_plant_from_its_driver(driver):
    """The plant's hysteresis force is BoucWen fed with the muscle lengths (l = L0 -+ r sin psi)
    or the pressures of each sample; driven by the length it stays 0 in a locked run."""
    e = Effects(bouc_wen_band=2.5, bouc_wen_driver=driver)
    for locked in (False, True):
        model = PamModel(locked=locked)
        plant = EffectsPlant(model, e, X0, (5.0, 5.0))
        travel = e.bouc_wen_length_travel if driver == 'length' else e.bouc_wen_pressure_travel
        reference = BoucWen(2.5, travel, model.params.P_out)
        p = model.params
        x = X0.copy()
        for u in inputs(300):
            drive = ((p.L0 - p.r * math.sin(x[0]), p.L0 + p.r * math.sin(x[0]))
                     if driver == 'length' else x[2:])
            np.testing.assert_array_equal(plant.F_h, reference.update(drive, x[2:]))
            x = plant.step(x, u, 0.0)[0]
        moved = np.max(np.abs(plant.F_h)) > 0.1
        assert moved == (not (locked and driver == 'length'))


# --- second-order valve spool, transport delay ----------------------------------------------------

def _spool_rk4(position, rate, u, w, zeta, h, substeps=2000):
    """u_f'' = w^2 (u - u_f) - 2 zeta w u_f' by plain RK4; (u_f, u_f', mean of u_f)."""
    d = h / substeps

    def f(s):
        return np.array([s[1], w * w * (u - s[0]) - 2.0 * zeta * w * s[1], s[0]])
    s = np.array([position, rate, 0.0])
    for _ in range(substeps):
        k1 = f(s)
        k2 = f(s + d / 2 * k1)
        k3 = f(s + d / 2 * k2)
        k4 = f(s + d * k3)
        s = s + d / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return s[0], s[1], s[2] / h


def test_second_order_spool_kernel_is_the_exact_step_of_its_equation():
    rng = np.random.default_rng(7)
    frequency, zeta = 30.0, 0.7
    valve = SecondOrderValve(PamModel().valve_map, H, frequency, zeta, (5.0, 2.0))
    state, mean = valve.state.copy(), np.empty(2)
    w = 2 * math.pi * frequency
    for _ in range(30):
        u = rng.uniform(0.0, 10.0, 2)
        expected = [_spool_rk4(state[i, 0], state[i, 1], u[i], w, zeta, H) for i in range(2)]
        spool_second_order(u[0], u[1], state, valve.transition, mean)
        for i in range(2):
            np.testing.assert_allclose([state[i, 0], state[i, 1], mean[i]], expected[i],
                                       rtol=1e-9, atol=1e-9)


def test_second_order_valve_settles_and_opens_by_the_mean_of_its_spool():
    vm = PamModel().valve_map
    valve = SecondOrderValve(vm, H, 30.0, 0.7, (0.0, 0.0))
    state, mean = valve.state.copy(), np.empty(2)
    spool_second_order(8.0, 3.0, state, valve.transition, mean)
    assert valve.openings((8.0, 3.0)) == (valve_opening(mean[0], vm.u, vm.alpha),
                                          valve_opening(mean[1], vm.u, vm.alpha))
    for _ in range(300):
        valve.openings((8.0, 3.0))
    np.testing.assert_allclose(valve.u_filtered, [8.0, 3.0], rtol=1e-9)
    # underdamped (zeta 0.2): the spool overshoots; zeta 0.7 hardly (4.6 %)
    overshoot = {}
    for zeta in (0.2, 0.7):
        valve = SecondOrderValve(vm, H, 30.0, zeta, (0.0, 0.0))
        positions = []
        for _ in range(200):
            valve.openings((8.0, 8.0))
            positions.append(valve.u_filtered[0])
        overshoot[zeta] = max(positions) / 8.0 - 1.0
    assert overshoot[0.2] == pytest.approx(math.exp(-math.pi * 0.2 / math.sqrt(1 - 0.04)),
                                           abs=0.01)
    assert overshoot[0.7] == pytest.approx(math.exp(-math.pi * 0.7 / math.sqrt(1 - 0.49)),
                                           abs=0.01)


def test_transport_delay_acts_on_the_command_of_n_samples_before():
    delay = CommandDelay(3, (1.0, 2.0))
    commands = [(float(k), 10.0 - k) for k in range(8)]
    assert [delay.delayed(u) for u in commands] == [(1.0, 2.0)] * 3 + commands[:5]
    model = PamModel()
    plant = EffectsPlant(model, Effects(valve_delay=0.003), X0, (0.0, 0.0))
    vm = model.valve_map
    got = [plant.openings(u) for u in inputs(10)]
    expected = [(valve_opening(u[0], vm.u, vm.alpha), valve_opening(u[1], vm.u, vm.alpha))
                for u in [(0.0, 0.0)] * 3 + [tuple(map(float, u)) for u in inputs(7)]]
    assert got == expected


# --- finite supply tank with a compressor ---------------------------------------------------------

def test_tank_kernel_is_its_mass_balance_with_a_hysteretic_switch():
    R, T, V, h = 287.0, 293.0, 2e-3, 1e-3
    P, running = 7.1e5, False
    rng = np.random.default_rng(2)
    for _ in range(5000):
        inflow = rng.uniform(0.0, 3e-4)
        expected = P + h * R * T / V * ((2.5e-4 if running else 0.0) - inflow)
        expected_running = True if expected <= 6.6e5 else False if expected >= 7.1e5 else running
        P, running = tank_update(P, running, inflow, 2.5e-4, h, R, T, V, 6.6e5, 7.1e5)
        assert P == pytest.approx(expected, rel=1e-15) and running == expected_running


def test_tank_empties_into_the_valves_and_the_compressor_refills_it_between_its_limits():
    e = Effects(tank_volume=2e-3, compressor_flow=2.5e-4, compressor_band=5e4)
    model = PamModel(locked=True)
    plant = EffectsPlant(model, e, X0, (10.0, 10.0))
    assert plant.tank.pressure == model.params.P_tank and not plant.tank.running
    x = np.array([0.0, 0.0, 2.0e5, 2.0e5])
    pressures, running = [], []
    for k in range(40000):
        u = (10.0, 10.0) if (k // 500) % 2 == 0 else (0.0, 0.0)   # fill, vent, fill, ...
        x = plant.step(x, u, k * H)[0]
        pressures.append(plant.record['P_tank'][0])
        running.append(plant.tank.running)
    pressures = np.array(pressures)
    assert pressures.min() == pytest.approx(model.params.P_tank - 5e4, abs=2e3)
    assert pressures.max() <= model.params.P_tank + 1e3
    assert 0 < np.mean(running) < 1                         # it cycles
    # the first step draws what the valves take in: supply_inflow at the tank's pressure
    fresh = EffectsPlant(model, e, X0, (10.0, 10.0))
    fresh.step(np.array([0.0, 0.0, 2.0e5, 2.0e5]), (10.0, 10.0), 0.0)
    drawn = (model.params.P_tank - fresh.tank.pressure) * e.tank_volume / (
        H * model.params.R * model.params.T)
    choked = 2 * 1.0 * model.params.A1_1 * model.params.P_tank * math.sqrt(
        1.4 / 287.0 * (2 / 2.4) ** 6.0) / math.sqrt(model.params.T)
    assert drawn == pytest.approx(choked, rel=1e-9)


def test_tank_without_compressor_empties_and_stays_finite():
    tank = SupplyTank(7.1e5, 287.0, 2e-3, 0.0, 5e4)
    for _ in range(1000):
        tank.draw(1e-4, 293.0, 1e-3)
    assert tank.pressure == pytest.approx(7.1e5 - 1000 * 1e-3 * 287.0 * 293.0 / 2e-3 * 1e-4)
    for _ in range(100000):
        tank.draw(1e-4, 293.0, 1e-3)
    assert tank.running and np.isfinite(tank.pressure)     # switched on, but nothing to supply


# --- sensor filter order --------------------------------------------------------------------------

@pytest.mark.parametrize('order', [1, 2, 3])
def test_sensor_filter_is_n_first_order_stages_in_cascade(order):
    tau = 0.7e-3
    plant = EffectsPlant(PamModel(), Effects(sensor_time_constant=tau, sensor_filter_order=order),
                         X0, (0.0, 0.0))
    decay = math.exp(-H / tau)
    stages = [X0[2:].copy() for _ in range(order)]
    rng = np.random.default_rng(order)
    for _ in range(50):
        P = rng.uniform(2e5, 7e5, 2)
        signal = P
        for j in range(order):
            stages[j] = signal + (stages[j] - signal) * decay
            signal = stages[j]
        plant.filter_pressures(P)
        np.testing.assert_array_equal(plant.P_filtered, stages[-1])


# --- the `other_forms` scenario -------------------------------------------------------------------

def test_other_forms_is_mild_plus_effects_of_other_forms():
    scenario, mild = load_scenario('other_forms'), load_scenario('mild')
    assert 'other_forms' in BUILTIN_SCENARIOS and scenario.name == 'other_forms'
    assert (scenario.factors, scenario.offsets, scenario.sensor) == (
        mild.factors, mild.offsets, mild.sensor)
    e = scenario.effects
    assert e == Effects(valve_natural_frequency=30.0, valve_damping=0.7, valve_delay=0.003,
                        tank_volume=2e-3, compressor_flow=2.5e-4, compressor_band=5e4,
                        bouc_wen_band=2.5, bouc_wen_driver='length',
                        bouc_wen_length_travel=1e-3, temperature_drift=-2.0,
                        temperature_drift_time=130.0, sensor_offset=(-2.5e3, 1.5e3),
                        sensor_gain_error=(-0.008, 0.004), sensor_time_constant=0.7e-3,
                        sensor_filter_order=2)
    # none of the realistic scenario's forms
    assert (e.valve_time_constant, e.hysteresis_band, e.supply_droop, e.supply_ripple,
            e.dead_volume) == (0.0, 0.0, 0.0, 0.0, 0.0)
    assert e.active and e.supply_varies
    text = e.describe()
    for word in ('2nd-order valve 30 Hz', 'valve delay 3 ms', 'tank 2 L', 'Bouc-Wen +2.5 N',
                 'length (1 mm)', 'x2'):
        assert word in text, text

