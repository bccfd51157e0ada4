"""Metrics, sensor model, input profiles and the batch simulator's files."""

import math

import numpy as np
import pytest

from pam_model.metrics import metrics, relative_max
from pam_model.model import PamModel
from pam_model.profiles import step_reference_profile, validation_profile
from pam_model.sensor import PressureSensor, adc_reading
from pam_model.simulate import SimulationResult, simulate


def test_metrics_definitions():
    measured = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    estimated = measured - np.array([0.0, 0.5, -1.0, 0.0, 0.5])
    m = metrics(measured, estimated)
    assert m.I == pytest.approx(math.sqrt((0.25 + 1 + 0.25) / 5))
    assert m.M == 1.0
    assert m.Q == pytest.approx(1.0 / 4.0)


def test_metrics_reject_bad_input():
    with pytest.raises(ValueError):
        relative_max([1.0, 2.0], [3.0, 3.0])
    with pytest.raises(ValueError):
        metrics([1.0, np.nan], [1.0, 1.0])


def test_sensor_quantises_to_12_bits_and_adds_noise():
    sensor = PressureSensor(noise_std=2000.0, bits=12, range_min=0.0, range_max=1e6)
    rng = np.random.default_rng(0)
    P = np.full(20000, 432_100.0)
    reading = sensor.measure(P, rng)
    counts = reading / sensor.resolution
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    expected = math.sqrt(2000.0 ** 2 + sensor.resolution ** 2 / 12)
    assert np.std(reading - P) == pytest.approx(expected, rel=0.05)
    assert np.all(sensor.measure(np.array([-5e5, 5e6]), rng) == [0.0, 1e6])


@pytest.mark.parametrize('bits', [0, 12])
def test_one_dimensional_readings_equal_the_ufunc_of_any_shape(bits):
    """A sample's readings (a 1-D array: one compiled loop) are the ufunc's, bit for bit, and a
    2-D array of the same pressures reads the same."""
    sensor = PressureSensor(noise_std=0.0, bits=bits, range_min=1e4, range_max=9e5)
    P = np.random.default_rng(5).uniform(-1e5, 1.1e6, 400)
    rng = np.random.default_rng(0)
    flat = sensor.measure(P, rng)
    assert np.array_equal(flat, adc_reading(P, sensor.resolution, 1e4, 9e5))
    assert np.array_equal(sensor.measure(P.reshape(20, 20), rng).ravel(), flat)


def test_sensor_rejects_impossible_settings():
    with pytest.raises(ValueError):
        PressureSensor(noise_std=-1.0)
    with pytest.raises(ValueError):
        PressureSensor(bits=40)
    with pytest.raises(ValueError):
        PressureSensor(range_min=1.0, range_max=0.0)


def test_validation_profile_is_deterministic_and_in_range():
    a, b, c = validation_profile(3), validation_profile(3), validation_profile(4)
    assert len(a.t) == 130_000 and a.u.shape == (130_000, 2)
    np.testing.assert_array_equal(a.u, b.u)
    assert np.any(a.u != c.u)
    assert np.all((a.u >= 0.0) & (a.u <= 10.0))
    np.testing.assert_allclose(a.u[:, 0] + a.u[:, 1], 11.0)         # antagonistic about 5.5 V


def test_validation_profile_spans_the_envelope():
    profile = validation_profile(0)
    run = simulate(PamModel(), profile.u, [0.0, 0.0, 4.5e5, 4.5e5])
    psi = np.degrees(run.x[:, 0])
    assert psi.min() < -15.0 and psi.max() > 15.0
    assert abs(psi).max() < 25.0
    assert run.x[:, 2:].min() > 180e3 and run.x[:, 2:].max() < 710e3
    locked = simulate(PamModel(locked=True), profile.u, [0.0, 0.0, 4.5e5, 4.5e5])
    assert locked.torque.min() < -1.8 and locked.torque.max() > 1.8


@pytest.mark.parametrize('mode, limit', [('angle', math.radians(20.0)), ('torque', 2.0)])
def test_step_reference_profiles(mode, limit):
    ref = step_reference_profile(mode, seed=5, duration=60.0, hold=6.0)
    assert ref.value[0] == 0.0 and np.all(np.abs(ref.value) <= limit)
    levels = ref.value[::6000]
    assert len(levels) == 10 and np.all(np.abs(np.diff(levels)) >= 0.5 * limit)
    np.testing.assert_array_equal(ref.value, step_reference_profile(mode, 5, 60.0, 6.0).value)
    with pytest.raises(ValueError):
        step_reference_profile('speed')


@pytest.mark.parametrize('suffix', ['.npz', '.csv'])
def test_simulation_files_round_trip(tmp_path, suffix):
    U = validation_profile(1, duration=2.0).u
    run = simulate(PamModel(locked=True), U, [0.0, 0.0, 4.5e5, 4.5e5],
                   sensor=PressureSensor(2000.0, 12), seed=2)
    path = run.save(tmp_path / f'run{suffix}')
    back = SimulationResult.load(path)
    np.testing.assert_allclose(back.x, run.x, rtol=1e-9)
    np.testing.assert_allclose(back.p_measured, run.p_measured, rtol=1e-9)
    np.testing.assert_allclose(back.torque, run.torque, rtol=1e-8, atol=1e-9)
    assert np.any(run.p_measured != run.x[:, 2:])


def test_simulate_rejects_bad_shapes():
    with pytest.raises(ValueError):
        simulate(PamModel(), np.zeros((10, 3)), [0, 0, 4e5, 4e5])
    with pytest.raises(ValueError):
        simulate(PamModel(), np.zeros((10, 2)), [0, 0, np.nan, 4e5])
