"""pam-robustness's computation, no ROS: which imperfection of a rig matters.

For every plant of robustness_plants.sweep_plants (an effect at a magnitude, or a Monte Carlo
parameter draw) it runs
* the validation profile (pam_model.profiles.validation_profile, free and locked joint, the
  plant's sensor) through each estimator: the UKF's whole-run Q of the angle (Q_psi) and of the
  torque (Q_tau), MODEL.md section 6, the estimator starting from the first measured state as
  pam-evaluate does (pam_estimator.evaluation.start_state);
* the sensor-less closed loop (pam_controller.closed_loop) over the demo's angle steps
  (reference_node's defaults: steps of 8 s within +-20 deg, seed 0)
  with pi_node's default gains:
  the worst steady-state error (% of the 40 deg range) and the worst settling time (s) of
  step_metrics.

The estimators (columns):
* 'nominal': the UKF with the shipped Table II set (what a user has before identification);
* 'oracle': the UKF with the plant's TRUE parameters and no model of the effects: what remains
  when identification is perfect;
* 'oracle+ext': the same with the plant's true estimator-side effects as model extensions
  (pam_model.model_extensions: valve lag, dead volume, hysteresis, sensor offset and gain; not the
  supply, temperature or sensor filter): what remains when those are modelled and known;
* 'identified' and 'identified+ext' (optional, costly): the UKF with what
  pam_model.identification.identify (partial) makes of a simulated calibration campaign on that
  plant, effects included: the paper's model only, and with the extensions it identifies
  (pam-identify's extensions.yaml).

The UKF runs of all plants x estimators sharing a valve map go through one compiled kernel
(ukf_runs_kernel: the estimation of many plants at once); the plants with effects step sample
by sample (pam_model.effects.EffectsPlant), those without through the compiled simulator.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from math import nan
from typing import NamedTuple

import numpy as np
from numba import njit

from pam_estimator.evaluation import run_ukf
from pam_estimator.pam_ukf import (
    DEFAULT_TUNING,
    INFO_FIELDS,
    INFO_TORQUE,
    FilterSettings,
    ukf_step,
)
from pam_estimator.valid_readings import NIS_GATE_OFF, PRESSURE_MAX, PRESSURE_MIN
from pam_model.effects import Effects
from pam_model.metrics import metrics
from pam_model.mismatch import MismatchScenario
from pam_model.model import KernelModel, PamModel
from pam_model.model_extensions import ESTIMATOR_FIELDS, NO_EXTENSIONS
from pam_model.physics import joint_torque, muscle_forces
from pam_model.profiles import step_reference_profile, validation_profile
from pam_model.rest import REST_STATE
from pam_model.simulate import simulate

from .closed_loop import simulate_closed_loop, simulate_closed_loop_with_effects
from .pi import PiGains
from .robustness_plants import Plant, sweep_plants
from .step_metrics import ANGLE_SPAN

X0 = REST_STATE                     # rad, rad/s, Pa, Pa: every run's initial state
REFERENCE_SEED = 0                   # the demo's reference steps (reference_node's seed)
CHUNK = 8                            # distinct plants whose runs are held (and batched) at once


@dataclass(frozen=True)
class Settings:
    """What to run: rows and magnitudes (robustness_plants), Monte Carlo plants, the seed (the
    validation profile's, the sensor noise's and the draws'), the validation profile's and the
    closed loop's durations (s), the estimators, the identification campaign plan."""

    base: MismatchScenario
    rows: tuple
    magnitudes: tuple
    monte_carlo: int = 6
    seed: int = 1
    validation_duration: float = 130.0
    closed_loop_duration: float = 64.0
    reference_hold: float = 8.0      # s, the demo's (reference_node's hold)
    estimators: tuple = ('nominal', 'oracle')
    campaign: object = None          # pam_model.identification.campaign.CampaignPlan
    gains: tuple = (40.0, 50.0)      # kp V/rad, ki V/(rad s)
    limits: PiGains = PiGains(0.0, 0.0)   # its beta, u_min, u_max (V)
    anti_windup: str = 'conditional'
    tracking_time: float = 0.1       # s


@dataclass
class PlantResult:
    """One plant's figures per estimator: q_psi, q_tau (%), ss_error (% of range), settling (s)."""

    plant: Plant
    figures: dict = field(default_factory=dict)      # estimator -> {figure: value}


@njit(cache=True)
def ukf_runs_kernel(p_measured, U, x0s, est_arrays, h, kappa_u, kappa_alpha, friction_law,
                    force_model, locked, Q, R, P0):
    """The UKF over B recorded runs of one input profile at once: run b (p_measured[b] (N, 2)
    Pa, commands U (N, 2) V) with the parameters est_arrays[b] from x0s[b]; as
    pam_estimator.evaluation.run_ukf: sample 0 is x0, sample k predicts with U[k-1] and updates
    with p_measured[b, k]. Returns the estimated angle (B, N) (rad) and torque (B, N) (N m)."""
    B, n = p_measured.shape[0], p_measured.shape[1]
    psi = np.empty((B, n))
    tau = np.empty((B, n))
    info = np.zeros(len(INFO_FIELDS))
    for b in range(B):
        p_array = est_arrays[b:b + 1]
        x = x0s[b].copy()
        P = P0.copy()
        F1, F2 = muscle_forces(x[0], x[2], x[3], p_array[0], force_model)
        psi[b, 0] = x[0]
        tau[b, 0] = joint_torque(x[0], F1, F2, p_array[0])
        model = KernelModel(h, p_array, kappa_u, kappa_alpha, friction_law, force_model, locked)
        settings = FilterSettings(Q, R, x0s[b, 0], NIS_GATE_OFF, PRESSURE_MIN, PRESSURE_MAX)
        for k in range(1, n):
            ukf_step(x, P, U[k - 1], p_measured[b, k], model, settings, info)
            psi[b, k] = x[0]
            tau[b, k] = info[INFO_TORQUE]
    return psi, tau


class Estimator(NamedTuple):
    """A UKF's model and its model extensions (pam_model.model_extensions)."""

    model: PamModel
    extensions: Effects = NO_EXTENSIONS


def estimator_extensions(effects: Effects) -> Effects:
    """The part of a plant's effects an estimator's model may carry (ESTIMATOR_FIELDS)."""
    return Effects(**{name: getattr(effects, name) for name in ESTIMATOR_FIELDS})


def q_percent(run, psi, tau) -> float:
    """Whole-run Q (%) of an estimate: the angle's (deg) on a free run, the torque's locked."""
    measured, estimated = ((run.torque, tau) if run.locked else
                           (np.degrees(run.x[:, 0]), np.degrees(psi)))
    return 100.0 * metrics(measured, estimated).Q


def estimation_q(runs, estimators, tuning=DEFAULT_TUNING) -> np.ndarray:
    """Whole-run Q (%) of the UKF estimators[i] over runs[i]: SimulationResults of one input
    profile and one joint mode (angle Q when free, torque Q when locked). The estimators without
    extensions that share a valve map go through ukf_runs_kernel in one call; those with
    extensions run pam_estimator.evaluation.run_ukf (PamUkf, sample by sample)."""
    q = np.empty(len(runs))
    groups: dict = {}
    for i, (model, extensions) in enumerate(estimators):
        if extensions.active:
            est = run_ukf(runs[i], model, tuning, extensions=extensions)
            q[i] = q_percent(runs[i], est.x[:, 0], est.torque)
        else:
            groups.setdefault(id(model.valve_map), []).append(i)
    for index in groups.values():
        est = estimators[index[0]].model
        p_meas = np.ascontiguousarray([runs[i].p_measured for i in index])
        x0s = np.array([[runs[i].x[0, 0], runs[i].x[0, 1], *runs[i].p_measured[0]]
                        for i in index])
        arrays = np.concatenate([estimators[i].model.params_array for i in index])
        psi, tau = ukf_runs_kernel(p_meas, np.ascontiguousarray(runs[index[0]].u), x0s, arrays,
                                   est.h, est.valve_map.u, est.valve_map.alpha,
                                   est.friction_code, est.force_code, runs[index[0]].locked,
                                   np.diag(tuning.Q), np.diag(tuning.R), np.diag(tuning.P0))
        for row, i in enumerate(index):
            q[i] = q_percent(runs[i], psi[row], tau[row])
    return q


IDENTIFIED = ('identified', 'identified+ext')


def identified_estimators(plant_model: PamModel, plant: Plant, sensor, nominal: PamModel, plan,
                          names) -> dict:
    """{name: Estimator or None} for the names of IDENTIFIED asked for: what
    pam_model.identification.identify (partial) makes of one simulated calibration campaign on
    the plant (effects included): 'identified' the paper's model only (extensions=False),
    'identified+ext' with the extensions it identifies. None where the fits give an impossible
    set (IdentificationError: the figures are then NaN)."""
    from pam_model.identification.campaign import records_of, simulate_campaign
    from pam_model.identification.identify import IdentificationError, identify
    records = records_of(simulate_campaign(plant_model, sensor, plan, effects=plant.effects))
    out = {}
    for name in names:
        try:
            ident = identify(records, nominal.params, nominal.valve_map, partial=True,
                             extensions=name == 'identified+ext')
        except IdentificationError:
            out[name] = None
            continue
        out[name] = Estimator(replace(nominal, params=ident.params, valve_map=ident.valve_map),
                              ident.extensions)
    return out


def closed_loop_figures(plant_model: PamModel, plant: Plant, estimator: Estimator, reference,
                        settings: Settings, sensor) -> dict:
    """Worst steady-state error (% of the 40 deg range) and settling (s) of the angle steps."""
    args = dict(sensor=sensor, mode='angle', anti_windup=settings.anti_windup,
                limits=settings.limits,
                tracking_time=settings.tracking_time, x0=X0, seed=settings.seed)
    model, extensions = estimator
    if plant.effects.active or extensions.active or model.valve_map is not plant_model.valve_map:
        run = simulate_closed_loop_with_effects(plant_model, plant.effects, model, reference,
                                                settings.gains, extensions=extensions, **args)
    else:
        run, = simulate_closed_loop(plant_model, model, reference, [settings.gains], **args)
    report = run.report(ANGLE_SPAN, 2.0)
    return {'ss_error': report.worst_error, 'settling': report.worst_settling}


def same_estimators(estimators: dict) -> dict:
    """{name: an earlier name} for the estimators equal to an earlier one (the same model object
    and extensions: 'oracle+ext' on a plant without estimator-side effects is 'oracle'); their
    figures are copied, not computed again."""
    first: dict = {}
    copies = {}
    for name, (model, extensions) in estimators.items():
        original = first.setdefault((id(model), extensions), name)
        if original != name:
            copies[name] = original
    return copies


def run_sweep(settings: Settings, nominal: PamModel, log: Callable[[str], None] = print,
              chunk: int = CHUNK) -> tuple[list[PlantResult], dict]:
    """Every plant's figures and the time spent per stage (s). Distinct plants are computed
    once, `chunk` at a time: their validation runs, then the UKF runs of the whole chunk (plants
    x estimators) in one kernel call per joint mode, then their closed loops."""
    timing = {'simulate': 0.0, 'identify': 0.0, 'estimate': 0.0, 'closed_loop': 0.0}
    sensor = settings.base.sensor
    profile = validation_profile(settings.seed, settings.validation_duration, nominal.h)
    reference = step_reference_profile('angle', REFERENCE_SEED, settings.closed_loop_duration,
                                       settings.reference_hold, nominal.h).value
    plants = sweep_plants(settings.rows, settings.magnitudes, settings.base, nominal.params,
                          settings.monte_carlo, settings.seed)
    unique: dict = {}
    for plant in plants:
        unique.setdefault((plant.params, plant.effects), plant)
    log(f'{len(plants)} plants ({len(unique)} distinct), validation profile '
        f'{settings.validation_duration:g} s, closed loop {settings.closed_loop_duration:g} s, '
        f'estimators {", ".join(settings.estimators)}')
    keys = list(unique)
    done: dict = {}

    def stage(name, work, *args):
        """work(*args), its time added to timing[name]."""
        clock = time.perf_counter()
        result = work(*args)
        timing[name] += time.perf_counter() - clock
        return result

    def validation_run(plant, model, locked):
        return simulate(replace(model, locked=locked), profile.u, X0, sensor, settings.seed,
                        effects=plant.effects)

    for start in range(0, len(keys), chunk):
        batch = [(key, unique[key], replace(nominal, params=unique[key].params))
                 for key in keys[start:start + chunk]]
        runs = {(key, locked): stage('simulate', validation_run, plant, model, locked)
                for key, plant, model in batch for locked in (False, True)}
        models, copies = {}, {}
        for key, plant, model in batch:
            models[key] = {'nominal': Estimator(nominal), 'oracle': Estimator(model),
                           'oracle+ext': Estimator(model, estimator_extensions(plant.effects))}
            asked = [name for name in IDENTIFIED if name in settings.estimators]
            if asked:
                models[key].update(stage('identify', identified_estimators, model, plant, sensor,
                                         nominal, settings.campaign, asked))
            done[key] = {name: dict.fromkeys(('q_psi', 'q_tau', 'ss_error', 'settling'), nan)
                         for name in settings.estimators}
            models[key] = {name: models[key][name] for name in settings.estimators
                           if models[key][name] is not None}
            copies[key] = same_estimators(models[key])
        pairs = [(key, name) for key, _, _ in batch for name in models[key]
                 if name not in copies[key]]
        for locked, figure in ((False, 'q_psi'), (True, 'q_tau')):
            q = stage('estimate', estimation_q, [runs[key, locked] for key, _ in pairs],
                      [Estimator(replace(models[key][name].model, locked=locked),
                                 models[key][name].extensions) for key, name in pairs])
            for (key, name), value in zip(pairs, q, strict=True):
                done[key][name][figure] = float(value)
        del runs
        for key, plant, model in batch:
            for name, estimator in models[key].items():
                if name not in copies[key]:
                    done[key][name].update(stage('closed_loop', closed_loop_figures, model,
                                                 plant, estimator, reference, settings, sensor))
            for name, original in copies[key].items():
                done[key][name] = dict(done[key][original])
            log(f'  [{keys.index(key) + 1}/{len(keys)}] {plant.row} x{plant.magnitude:g}'
                + (f' draw {plant.draw}' if plant.row == 'parameters' else '') + ': '
                + '; '.join(f'{name} Q_psi {f["q_psi"]:.2f} % Q_tau {f["q_tau"]:.2f} % ss '
                            f'{f["ss_error"]:.2f} %' for name, f in done[key].items()))
    return [PlantResult(p, done[(p.params, p.effects)]) for p in plants], timing
