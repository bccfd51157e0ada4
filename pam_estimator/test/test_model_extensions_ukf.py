"""The estimator's model extensions (docs/model_extensions.md): the UKF and the
model alone carry the effects of pam_model.model_extensions; without them (NO_EXTENSIONS, no
supply) they compute what the paper's model computed, bit for bit."""

from dataclasses import replace

import numpy as np
import pytest

from pam_estimator.evaluation import (
    evaluate,
    measured_and_estimated,
    run_model_alone,
    run_ukf,
    start_state,
)
from pam_estimator.pam_ukf import PamUkf
from pam_model.effects import Effects
from pam_model.metrics import metrics
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.model_extensions import ESTIMATOR_FIELDS, NO_EXTENSIONS, extensions_from_dict
from pam_model.parameters import load_parameters
from pam_model.profiles import validation_profile
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate

X0 = (0.0, 0.0, 4.5e5, 4.5e5)
#: Estimator-side effects of the size of the 'realistic' scenario's.
RIG = Effects(valve_time_constant=0.005, dead_volume=6.0e-6, hysteresis_band=2.0,
              sensor_offset=(2000.0, -3000.0), sensor_gain_error=(0.005, -0.005))
#: With a Bouc-Wen loop of either driver and orientation beside the Maxwell slip.
LOOPS = (replace(RIG, bouc_wen_band=-1.5, bouc_wen_driver='length',
                 bouc_wen_length_travel=8e-4),
         replace(RIG, hysteresis_band=0.0, bouc_wen_band=2.0, bouc_wen_driver='pressure',
                 bouc_wen_pressure_travel=3e4))


def true_extensions(effects: Effects) -> Effects:
    """A plant's effects restricted to what an estimator's model may carry."""
    return extensions_from_dict({k: getattr(effects, k) for k in ESTIMATOR_FIELDS}, 'plant')


def short_run(locked, effects, seconds=3.0, model=None):
    model = replace(model or PamModel(), locked=locked)
    profile = validation_profile(1, seconds, model.h)
    return model, simulate(model, profile.u, X0, PressureSensor(2000.0, 12), 1, effects=effects)


@pytest.mark.parametrize('locked', [False, True])
def test_no_extensions_is_the_paper_filter_bit_for_bit(locked):
    """The extensions' path (taken when a supply pressure is given) with NO_EXTENSIONS and the
    nominal P_tank computes exactly the paper filter's numbers (ukf_step)."""
    model, run = short_run(locked, RIG, seconds=1.0)
    paper = PamUkf(model=model, x0=X0)
    extended = PamUkf(model=model, x0=X0, extensions=NO_EXTENSIONS)
    for k in range(1, len(run.t)):
        a = paper.step(run.p_measured[k], run.u[k - 1])
        b = extended.step(run.p_measured[k], run.u[k - 1], supply=model.params.P_tank)
        assert np.array_equal(a.x, b.x) and np.array_equal(a.P, b.P)
        assert (a.force1, a.force2, a.torque, a.torque_variance, a.subsystem, a.nis) == (
            b.force1, b.force2, b.torque, b.torque_variance, b.subsystem, b.nis)


def test_a_measured_supply_pressure_moves_the_prediction():
    model, run = short_run(False, None, seconds=0.5)
    nominal, low = PamUkf(model=model, x0=X0), PamUkf(model=model, x0=X0)
    for k in range(1, len(run.t)):
        a = nominal.step(run.p_measured[k], run.u[k - 1], supply=float('nan'))  # = nominal
        b = low.step(run.p_measured[k], run.u[k - 1], supply=model.params.P_tank - 1.0e5)
    assert a.x[2] > b.x[2] + 1.0e3 or a.x[3] > b.x[3] + 1.0e3


def test_an_estimator_refuses_the_rig_states():
    with pytest.raises(ValueError, match='supply_droop not allowed in an estimator'):
        PamUkf(extensions=Effects(supply_droop=1.0e4))


def test_the_sensor_extension_inverts_the_reading_but_checks_the_raw_one():
    """y = (1 + g) P + o read back as P: a filter that knows the offset and gain follows the
    true pressures; a raw reading out of range is still refused."""
    ext = Effects(sensor_offset=(3.0e4, -3.0e4), sensor_gain_error=(0.05, -0.05))
    model, run = short_run(True, ext, seconds=1.0)
    knows = PamUkf(model=model, x0=X0, extensions=ext)
    blind = PamUkf(model=model, x0=X0)
    for k in range(1, len(run.t)):
        a = knows.step(run.p_measured[k], run.u[k - 1])
        b = blind.step(run.p_measured[k], run.u[k - 1])
    truth = run.x[-1, 2:]
    assert np.max(np.abs(a.x[2:] - truth)) < 5.0e3 < np.max(np.abs(b.x[2:] - truth))
    before = knows.rejected_samples
    knows.step((500.0, 4.0e5), run.u[-1])     # raw reading below y_range
    assert knows.rejected_samples == before + 1


@pytest.mark.parametrize('locked', [False, True])
def test_the_model_alone_with_the_plant_effects_is_the_plant(locked):
    """Open loop from the true start, the model alone carrying the plant's valve lag, dead
    volume and hysteresis computes the plant's angle and torque (the sensor's offset and gain
    change nothing it computes); without them it does not."""
    model, run = short_run(locked, RIG)
    x0 = start_state(run, 'recorded')
    ext = run_model_alone(run, model, x0, RIG)
    paper = run_model_alone(run, model, x0)
    np.testing.assert_allclose(ext.torque, run.torque, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ext.x, run.x, rtol=0, atol=1e-6)
    assert np.max(np.abs(paper.torque - run.torque)) > 0.05


@pytest.fixture(scope='module')
def realistic():
    """20 s of the 'realistic' rig (validation profile, seed 1), the true mild parameters."""
    scenario = load_scenario('realistic')
    model = PamModel(params=scenario.apply(load_parameters('default')))
    profile = validation_profile(1, 20.0, model.h)
    runs = {locked: simulate(replace(model, locked=locked), profile.u, X0, scenario.sensor, 1,
                             effects=scenario.effects) for locked in (False, True)}
    return model, runs, true_extensions(scenario.effects)


@pytest.mark.parametrize('locked', [False, True])
def test_the_true_extensions_beat_the_paper_model_on_the_realistic_rig(realistic, locked):
    model, runs, extensions = realistic
    run = runs[locked]
    m = replace(model, locked=locked)
    q = {name: metrics(*measured_and_estimated(run, run_ukf(run, m, extensions=e))).Q
         for name, e in (('without', NO_EXTENSIONS), ('with', extensions))}
    print(f"{'locked' if locked else 'free'}: UKF Q without {100 * q['without']:.2f} %, "
          f"with the true extensions {100 * q['with']:.2f} %")
    assert q['with'] < 0.25 * q['without']


def test_the_measured_start_reads_through_the_sensor_extension():
    """The estimators start from the first reading as the UKF reads every sample: (y - o) /
    (1 + g); a raw start would put the sensor's offset into the start state."""
    model, run = short_run(True, RIG, seconds=0.1)
    x0 = start_state(run, extensions=RIG)
    expected = (run.p_measured[0] - np.array(RIG.sensor_offset)) / (
        1.0 + np.array(RIG.sensor_gain_error))
    assert x0[2:].tolist() == expected.tolist()
    assert start_state(run).tolist() == start_state(run, extensions=NO_EXTENSIONS).tolist()
    assert np.max(np.abs(x0[2:] - run.x[0, 2:])) < np.max(np.abs(start_state(run)[2:]
                                                                 - run.x[0, 2:]))
    assert run_ukf(run, model, extensions=RIG).x[0].tolist() == x0.tolist()


def test_evaluate_passes_the_extensions_to_both(realistic):
    model, runs, extensions = realistic
    run = runs[True]
    short = replace(run, t=run.t[:2000], u=run.u[:2000], x=run.x[:2000],
                    torque=run.torque[:2000], force=run.force[:2000],
                    friction=run.friction[:2000], subsystem=run.subsystem[:2000],
                    p_measured=run.p_measured[:2000])
    table, alone, ukf = evaluate(short, model, extensions=extensions)
    plain, alone0, ukf0 = evaluate(short, model)
    assert not np.array_equal(alone.torque, alone0.torque)
    assert not np.array_equal(ukf.torque, ukf0.torque)
    assert table['ukf'].Q < plain['ukf'].Q


def composed_reference(model, extensions):
    """The extended step as the composition of its public pieces (the valve lag, the sensor
    correction, predict_correct_with_effects, the Maxwell-slip and Bouc-Wen memories,
    estimate_outputs), for the one compiled kernel to be checked against."""
    from pam_estimator.pam_ukf import (
        INFO_FINITE,
        estimate_outputs,
        predict_correct_with_effects,
    )
    from pam_model.effects import BoucWen, MaxwellSlip, ValveLag, sanitised_voltages
    from pam_model.physics import muscle_lengths
    ukf = PamUkf(model=model, x0=X0, extensions=extensions)
    x, P, info, m, e = ukf.x.copy(), ukf.P.copy(), np.zeros(10), model, extensions
    state = {'valve': None, 'F_h': np.zeros(2), 'memory': None, 'loop': None,
             'F_bw': np.zeros(2)}
    if e.hysteresis_band > 0.0:
        state['memory'] = MaxwellSlip(e.hysteresis_band, e.hysteresis_elements,
                                      e.hysteresis_travel, m.params.P_out)
        state['memory'].update(m.outputs(x)[:2], x[2:4])

    def drive(x):
        if e.bouc_wen_driver == 'length':
            return np.array(muscle_lengths.py_func(float(x[0]), m.params))
        return x[2:4]
    if e.bouc_wen_band != 0.0:
        state['loop'] = BoucWen(e.bouc_wen_band, e.bouc_wen_length_travel
                                if e.bouc_wen_driver == 'length' else
                                e.bouc_wen_pressure_travel, m.params.P_out)
        state['loop'].update(drive(x), x[2:4])       # z = 0 at x0: no force
    record = m.params_array.copy()

    def step(y, u_prev):
        u = sanitised_voltages(u_prev)
        if state['valve'] is None:
            state['valve'] = ValveLag(m.valve_map, m.h, e.valve_time_constant, u)
        alpha1, alpha2 = state['valve'].openings(u)
        y = np.asarray(y, dtype=float)
        if np.all((y >= ukf.y_range[0]) & (y <= ukf.y_range[1])):
            y = (y - np.asarray(e.sensor_offset)) / (1.0 + np.asarray(e.sensor_gain_error))
        else:
            y = np.full(2, np.nan)
        F_h, loop = state['F_h'], state['loop']
        loop_state = np.zeros((3, 2)) if loop is None else np.array(
            [loop.z, loop.drive_before, state['F_bw']])
        x_post, P_post, F1, F2 = predict_correct_with_effects(
            x, P, alpha1, alpha2, y, ukf._Q, ukf._R, m.h, record, m.friction_code,
            m.force_code, m.locked, ukf.lock_angle, ukf.nis_gate, info, e.dead_volume, F_h[0],
            F_h[1], ukf._effects, loop_state)
        if state['memory'] is not None and np.all(np.isfinite(x_post)):
            F_h = state['memory'].update((F1, F2), x_post[2:4])
        if loop is not None and np.all(np.isfinite(x_post)):
            state['F_bw'] = loop.update(drive(x_post), x_post[2:4])
        F_out = F_h + state['F_bw'] if loop is not None else F_h
        estimate_outputs(x, P, x_post, P_post, m.h, record, m.friction_code, m.force_code,
                         m.locked, F_out[0], F_out[1], info)
        if info[INFO_FINITE]:
            state['F_h'] = F_h
        return x.copy(), P.copy(), info.copy()
    return step


@pytest.mark.parametrize('extensions', (RIG, *LOOPS), ids=['maxwell', 'length', 'pressure'])
@pytest.mark.parametrize('locked', [False, True])
def test_the_extended_kernel_is_the_composition_of_its_pieces(locked, extensions):
    """ukf_step_with_effects (one compiled call a sample) computes exactly what its pieces
    compute one after the other, through bad readings and bad commands too; with a Bouc-Wen
    loop of either driver too."""
    model, run = short_run(locked, RIG, seconds=1.0)
    reference = composed_reference(model, extensions)
    ukf = PamUkf(model=model, x0=X0, extensions=extensions)
    rng = np.random.default_rng(4)
    for k in range(1, len(run.t)):
        y, u = run.p_measured[k].copy(), run.u[k - 1].copy()
        if k % 37 == 0:
            y[k % 2] = np.nan if k % 74 else 3e6
        if k % 41 == 0:
            u[0] = np.inf if k % 82 else rng.uniform(10.5, 20.0)
        x, P, info = reference(y, u)
        out = ukf.step(y, u)
        assert np.array_equal(out.x, x) and np.array_equal(out.P, P)
        assert (out.force1, out.force2, out.torque, out.torque_variance, out.nis) == tuple(
            info[[4, 5, 6, 7, 0]])
    assert ukf.rejected_samples > 0
    assert np.any(ukf.F_h != 0.0) == (extensions.hysteresis_band > 0.0)
    moves = not (locked and extensions.bouc_wen_driver == 'length')   # a locked length stands
    assert np.any(ukf._bouc_wen[2] != 0.0) == (extensions.bouc_wen_band != 0.0 and moves)
