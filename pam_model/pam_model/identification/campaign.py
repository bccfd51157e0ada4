"""A calibration campaign on the simulated rig: the runs pam-identify needs, simulated offline.

The same profiles a lab plays on its rig (profile_player profile:=calibration_locked at each lock
angle, profile:=calibration_free), run on a plant (parameters, valve map, sensor) with the batch
simulator: locked runs at each of `lock_angles`, then one free run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..calibration_profiles import (
    FREE_LEVELS,
    HOLD_VOLTAGES,
    free_calibration_profile,
    locked_calibration_profile,
)
from ..model import PamModel
from ..parallel import map_in_processes
from ..rest import REST_PRESSURE
from ..simulate import simulate

DEFAULT_LOCK_ANGLES = (-15.0, 0.0, 15.0)   # deg
INITIAL_PRESSURE = REST_PRESSURE           # Pa abs, both muscles at the start of each run


@dataclass(frozen=True)
class CampaignPlan:
    """What to run: lock angles (deg), the locked profile's hold lengths and voltages (s, V), the
    free profile's length and levels (s; (beta V, d_max V) pairs), and the seed."""

    lock_angles: tuple = DEFAULT_LOCK_ANGLES
    hold: float = 10.0
    pair_hold: float = 3.0
    voltages: tuple = HOLD_VOLTAGES
    free_duration: float = 60.0
    free_levels: tuple = FREE_LEVELS
    seed: int = 0


def run_name(angle_deg: float | None) -> str:
    """'locked_m15deg', 'locked_0deg', 'locked_p15deg' or 'free' (angle None)."""
    if angle_deg is None:
        return 'free'
    sign = 'm' if angle_deg < 0 else ('p' if angle_deg > 0 else '')
    return f'locked_{sign}{abs(angle_deg):g}deg'


def simulate_campaign(model: PamModel, sensor=None, plan: CampaignPlan = CampaignPlan(),
                      effects=None, workers: int | None = None, finish=None):
    """[(name, SimulationResult)]: one locked run per lock angle, then the free run; effects:
    the plant's unmodelled effects (pam_model.effects.Effects, default none). finish(name, run),
    if given, is called on each run where it was simulated and [(name, what it returned)] is
    returned instead (e.g. writing each run's bag in its worker: a picklable callable).

    The runs are independent (each has its own seed), so with effects (simulated sample by sample
    in Python, about 0.15 ms a sample) they run in `workers` processes at once (default: one per
    CPU); the results do not depend on it. Without effects and finish the compiled kernel is fast
    enough to run them one after the other."""
    locked, free = replace(model, locked=True), replace(model, locked=False)
    jobs = []
    for j, angle in enumerate(plan.lock_angles):
        profile = locked_calibration_profile(plan.seed + j, plan.hold, plan.pair_hold,
                                             plan.voltages, model.h)
        x0 = np.array([math.radians(angle), 0.0, INITIAL_PRESSURE, INITIAL_PRESSURE])
        jobs.append((run_name(angle), locked, profile.u, x0, sensor, plan.seed + j, effects,
                     finish))
    if plan.free_duration > 0.0:
        profile = free_calibration_profile(plan.seed + 100, plan.free_duration, plan.free_levels,
                                           model.h)
        x0 = np.array([0.0, 0.0, INITIAL_PRESSURE, INITIAL_PRESSURE])
        jobs.append((run_name(None), free, profile.u, x0, sensor, plan.seed + 100, effects,
                     finish))
    if finish is None and (effects is None or not effects.active):
        workers = 1
    return map_in_processes(_simulate_job, jobs, workers, cost=lambda job: len(job[2]))


def _simulate_job(job) -> tuple:
    """(name, SimulationResult or what finish returned) of one campaign run: (name, model, U,
    x0, sensor, seed, effects, finish)."""
    name, model, U, x0, sensor, seed, effects, finish = job
    run = simulate(model, U, x0, sensor, seed, effects=effects)
    return name, (run if finish is None else finish(name, run))


def records_of(runs) -> list:
    """CalibrationRecords of [(name, SimulationResult)]."""
    from .records import CalibrationRecord
    return [CalibrationRecord.from_run(run, name) for name, run in runs]

