"""The estimator's extensions identified from simulated calibration runs.

Each fit on a short campaign of a plant with that effect ALONE (the 'mild' parameters underneath,
its sensor noise), and on the same campaign without it (the fit must then keep 0: the paper's
model). The plants with an effect step sample by sample (EffectsPlant), so the campaigns are kept
short (a few voltages, 2 lock angles or 1). Tolerances, from what was seen (seed 3): hysteresis
band B within 5 % (seen +0.8 %), travel within 10 % (seen -0.8 %); sensor offsets within 0.3 kPa
of o (the holds read o + g P_out, g = 0 here; seen 40 Pa); dead volume within 15 % (seen +2.7 %,
the areas then within 0.8 %);
mu_s with the hysteresis in the model joint within 3 % (seen 0.5 %) and mu_p within 15 % (seen
5 %); without it mu_s is off by > 5 % (seen -10 %: the loop is taken for friction) and mu_p is not
identifiable (56 %).
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from pam_model.effects import NO_EFFECTS, Effects, MaxwellSlip
from pam_model.identification.campaign import CampaignPlan, records_of, simulate_campaign
from pam_model.identification.flow_fit import AREA_FIELDS, AREA_NAMES, PressureModel, fit_flow
from pam_model.identification.force_fit import fit_forces
from pam_model.identification.friction_fit import fit_friction
from pam_model.identification.hysteresis_fit import fit_hysteresis, slip_response
from pam_model.identification.identify import identify
from pam_model.identification.sensor_fit import corrected, fit_sensors
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.parameters import load_parameters
from pam_model.valve_map import load_valve_map

ELEMENTS = NO_EFFECTS.hysteresis_elements
HYSTERESIS = Effects(hysteresis_band=2.0, hysteresis_travel=5.0)
LOCKED_PLAN = CampaignPlan(lock_angles=(-15.0, 15.0), voltages=(0.0, 2.0, 4.0, 5.0, 6.0, 7.0, 10.0),
                           hold=10.0, pair_hold=3.0, free_duration=0.0, seed=3)


@pytest.fixture(scope='module')
def plant():
    scenario = load_scenario('mild')
    return load_parameters(), scenario.apply(load_parameters()), scenario.sensor


def campaign(plant, plan, effects):
    _, truth, sensor = plant
    return records_of(simulate_campaign(PamModel(params=truth), sensor, plan, effects=effects))


def test_the_slip_kernel_is_the_plants_maxwell_slip():
    """slip_response (the fits' numba kernel, band 1 N) times B = MaxwellSlip (the plant's)."""
    rng = np.random.default_rng(0)
    s = np.cumsum(rng.normal(0.0, 1.5, 2000)) + 50.0
    P = 3e5 + 2e5 * np.sin(np.linspace(0.0, 20.0, 2000))
    slip = MaxwellSlip(2.5, ELEMENTS, 4.0, 1.013e5, count=1)
    expected = np.array([slip.update([s[k]], [P[k]])[0] for k in range(len(s))])
    out = np.empty(len(s))
    slip_response(s, P, ELEMENTS, 4.0, 1.013e5, out)
    assert np.max(np.abs(2.5 * out - expected)) < 1e-12
    assert np.ptp(expected) > 1.0        # the loop is exercised


@pytest.fixture(scope='module')
def hysteresis_runs(plant):
    return campaign(plant, LOCKED_PLAN, HYSTERESIS)


def test_the_hysteresis_band_and_travel_are_recovered_from_the_locked_runs(plant,
                                                                          hysteresis_runs):
    prior, truth, _ = plant
    group, changes, hyst, (band, travel) = fit_hysteresis(hysteresis_runs, prior, ELEMENTS)
    assert abs(band / HYSTERESIS.hysteresis_band - 1.0) < 0.05, band
    assert abs(travel / HYSTERESIS.hysteresis_travel - 1.0) < 0.10, travel
    std = {e.name: e.std for e in hyst.estimates}
    assert 0.0 < std['hysteresis_band'] < 0.1 and 0.0 < std['hysteresis_travel'] < 1.0
    # the loop modelled, the force coefficients are those of the plant
    for key in ('p_v1_1', 'p_v2_1', 'p_v1_2', 'p_v2_2'):
        assert abs(changes[key] / getattr(truth, key) - 1.0) < 0.005, key
    plain, _ = fit_forces(hysteresis_runs, prior)
    assert group.residual_rms < 0.5 * plain.residual_rms


def test_no_loop_is_found_on_a_plant_without_hysteresis(plant):
    prior, _, _ = plant
    runs = campaign(plant, LOCKED_PLAN, None)
    group, changes, hyst, (band, travel) = fit_hysteresis(runs, prior, ELEMENTS)
    assert band == 0.0 and travel is None
    assert 'loop not seen' in ' '.join(hyst.notes)
    plain_group, plain_changes = fit_forces(runs, prior)
    assert changes == plain_changes and group.residual_rms == plain_group.residual_rms


def test_the_friction_refit_with_the_loop_in_the_model_does_not_absorb_it(plant):
    """Free run on a plant with hysteresis alone, true forces: mu_s right with the identified
    loop in the model joint, inflated without it."""
    _, truth, _ = plant
    plan = CampaignPlan(lock_angles=(), free_duration=30.0, seed=3)
    runs = campaign(plant, plan, HYSTERESIS)
    loop = (HYSTERESIS.hysteresis_band, ELEMENTS, HYSTERESIS.hysteresis_travel)
    _, with_loop, skipped, _ = fit_friction(runs, truth, loop)
    _, without, skipped_without, _ = fit_friction(runs, truth)
    assert abs(with_loop['mu_s'] / truth.mu_s - 1.0) < 0.03, with_loop
    assert abs(with_loop['mu_p'] / truth.mu_p - 1.0) < 0.15 and not skipped, with_loop
    assert abs(without['mu_s'] / truth.mu_s - 1.0) > 0.05, without
    assert [gap.parameters for gap in skipped_without] == [('mu_p',)]


SENSOR_PLAN = CampaignPlan(lock_angles=(0.0,), voltages=(0.0, 5.0, 10.0), hold=10.0, pair_hold=0.0,
                           free_duration=0.0, seed=3)
OFFSETS = (2.0e3, -3.0e3)


def test_sensor_offsets_are_recovered_from_the_vented_holds(plant):
    prior, _, _ = plant
    runs = campaign(plant, SENSOR_PLAN, Effects(sensor_offset=OFFSETS))
    _, offsets, gains = fit_sensors(runs, prior)
    assert np.allclose(offsets, OFFSETS, atol=300.0), offsets
    assert gains == (0.0, 0.0)
    again = fit_sensors(corrected(runs, offsets, gains), prior)[0]
    residual = [e.value for e in again.estimates if e.name.startswith('sensor_offset')]
    assert np.allclose(residual, 0.0, atol=1.0), residual   # the corrected vented holds: P_out


def test_no_offset_is_kept_on_exact_sensors(plant):
    prior, _, _ = plant
    runs = campaign(plant, SENSOR_PLAN, None)
    group, offsets, _ = fit_sensors(runs, prior)
    assert offsets == (0.0, 0.0)
    assert all(e.note for e in group.estimates)      # each says why it is 0
    assert corrected(runs, offsets, (0.0, 0.0)) == list(runs)


FLOW_PLAN = CampaignPlan(lock_angles=(-15.0, 15.0), voltages=(0.0, 2.0, 4.0, 5.0, 6.0, 7.0, 10.0),
                         hold=0.0, pair_hold=3.0, free_duration=0.0, seed=3)
DEAD_VOLUME = 6.0e-6


def test_the_dead_volume_is_recovered_with_the_valve_areas(plant):
    prior, truth, _ = plant
    runs = campaign(plant, FLOW_PLAN, Effects(dead_volume=DEAD_VOLUME))
    model = PamModel(params=truth)
    group, changes, _, V_d = fit_flow(runs, prior, model.valve_map, dead_volume=True)
    assert abs(V_d / DEAD_VOLUME - 1.0) < 0.15, V_d
    for key in ('A1_1', 'A2_1', 'A1_2', 'A2_2'):
        true = getattr(truth, key) * truth.k1 / prior.k1
        assert abs(changes[key] / true - 1.0) < 0.05, (key, changes[key] / true)
    estimate = next(e for e in group.estimates if e.name == 'dead_volume')
    assert 0.0 < estimate.std < 0.3 * DEAD_VOLUME and not estimate.note


def test_no_dead_volume_is_kept_without_one(plant):
    prior, truth, _ = plant
    runs = campaign(plant, FLOW_PLAN, None)
    model = PamModel(params=truth)
    group, changes, _, V_d = fit_flow(runs, prior, model.valve_map, dead_volume=True)
    assert V_d == 0.0
    plain, plain_changes, _ = fit_flow(runs, prior, model.valve_map)
    assert changes == plain_changes
    assert any(e.name == 'dead_volume' and e.note for e in group.estimates)
    assert math.isfinite(plain.residual_rms)


FREE_FLOW_PLAN = replace(FLOW_PLAN, free_duration=30.0)


def test_a_weak_k2_is_held_at_its_prior_and_the_areas_are_still_fitted(plant):
    """On 'mild' (the paper's flow) k2 is fitted with the areas (seen -0.6 %, 1.8 % sigma). On
    'other_forms' (a finite tank, a second-order valve with a delay) the same campaign leaves k2
    too uncertain (seen 60 %): k2 keeps its prior, reported, and the areas are fitted with it
    (seen 3-4 % sigma, pressure residual 15 % below the prior areas') instead of being dropped
    with k2."""
    prior, truth, _ = plant
    _, changes, skipped = fit_flow(campaign(plant, FREE_FLOW_PLAN, None), prior,
                                       PamModel(params=truth).valve_map)
    assert skipped == [] and abs(changes['k2'] / truth.k2 - 1.0) < 0.05, changes['k2']
    scenario = load_scenario('other_forms')
    other = scenario.apply(prior)
    runs = records_of(simulate_campaign(PamModel(params=other), scenario.sensor, FREE_FLOW_PLAN,
                                        effects=scenario.effects))
    group, changes, skipped = fit_flow(runs, prior, PamModel(params=other).valve_map)
    assert [gap.parameters for gap in skipped] == [('k2',)]
    assert 'k2 (' in skipped[0].what and 'held at its prior' in skipped[0].what
    assert 'k2' not in changes and [e.name for e in group.estimates] == list(AREA_NAMES)
    for e in group.estimates:
        assert 0.0 < e.std < 0.1 * e.value and e.value != e.prior, e
    at_prior = PressureModel(runs, PamModel(params=other).valve_map, prior)
    prior_areas = [getattr(prior, f) for f in AREA_FIELDS]
    prior_rms = np.sqrt(np.mean((at_prior.simulate(prior_areas, prior.k2)
                                 - at_prior.measured) ** 2))
    assert group.residual_rms < 0.9 * prior_rms, (group.residual_rms, prior_rms)



def test_the_realistic_campaign_identifies_everything_without_refusing():
    """All of 'realistic' at once (short campaign, 2 lock angles, 8 voltages, 30 s free run):
    identify() without partial completes (without the extensions the loop is taken for friction
    and mu_p is refused, test above), the extensions it reveals come out near the plant's
    (offsets: the vented holds read o + g P_out, +0.5 kPa here), gains and valve lag stay 0.
    Seen: B +0.9 %, offsets +0.52 / -0.52 kPa, V_d -5 %, mu_s +0.5 %, mu_p +0.7 %."""
    scenario = load_scenario('realistic')
    prior = load_parameters()
    truth, effects = scenario.apply(prior), scenario.effects
    plan = CampaignPlan(lock_angles=(-15.0, 15.0),
                        voltages=(0.0, 2.0, 4.0, 5.0, 5.5, 6.0, 7.0, 10.0), hold=10.0,
                        pair_hold=3.0, free_duration=30.0, seed=3)
    runs = records_of(simulate_campaign(PamModel(params=truth), scenario.sensor, plan,
                                        effects=effects))
    ident = identify(runs, prior, load_valve_map())
    ext = ident.extensions
    assert ident.complete
    assert abs(ext.hysteresis_band / effects.hysteresis_band - 1.0) < 0.05
    assert abs(ext.hysteresis_travel / effects.hysteresis_travel - 1.0) < 0.10
    readable = np.add(effects.sensor_offset, np.multiply(effects.sensor_gain_error, prior.P_out))
    assert np.allclose(ext.sensor_offset, readable, atol=300.0), ext.sensor_offset
    assert ext.sensor_gain_error == (0.0, 0.0) and ext.valve_time_constant == 0.0
    assert abs(ext.dead_volume / effects.dead_volume - 1.0) < 0.25
    assert abs(ident.params.mu_s / truth.mu_s - 1.0) < 0.03
    assert abs(ident.params.mu_p / truth.mu_p - 1.0) < 0.15
