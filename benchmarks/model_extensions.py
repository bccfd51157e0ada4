#!/usr/bin/env python3
"""The estimator's model extensions on the 'realistic' rig (
docs/model_extensions.md): validation profile (seed 1) on the realistic plant (its mild parameter
mismatch and every unmodelled effect), free and locked; the model alone and the UKF, both with
the TRUE mild parameters, without extensions and with each of the scenario's estimator-side
effects (pam_model.model_extensions.ESTIMATOR_FIELDS) alone and all together, Q (%) of the angle
(free) and torque (locked) over the whole run (the paper's definition) and the UKF's after the
initial transient (metrics_after: with the true extensions the whole-run M, hence Q, is set by
the first samples, where both estimators start from the same measured state); then the UKF's
median step time with and without.

    .venv/bin/python benchmarks/model_extensions.py [--duration 130]

About 2 minutes for 130 s on one core (the plant and the model alone with effects step per
sample in Python around numba kernels).
"""

import argparse
import time
from dataclasses import replace

import numpy as np

from pam_estimator.evaluation import evaluate, table_after
from pam_estimator.pam_ukf import PamUkf
from pam_model.effects import Effects
from pam_model.metrics import DEFAULT_TRANSIENT
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.model_extensions import ESTIMATOR_FIELDS, NO_EXTENSIONS, extensions_from_dict
from pam_model.parameters import load_parameters
from pam_model.profiles import validation_profile
from pam_model.rest import REST_STATE
from pam_model.simulate import simulate

X0 = REST_STATE
SEED = 1


def variants(true: Effects) -> dict:
    """{label: extensions}: none, each estimator-side effect of the scenario alone, all."""
    e = true
    return {
        'none (paper model)': NO_EXTENSIONS,
        'valve lag': Effects(valve_time_constant=e.valve_time_constant),
        'dead volume': Effects(dead_volume=e.dead_volume),
        'hysteresis': Effects(hysteresis_band=e.hysteresis_band,
                              hysteresis_travel=e.hysteresis_travel,
                              hysteresis_elements=e.hysteresis_elements),
        'sensor offset+gain': Effects(sensor_offset=e.sensor_offset,
                                      sensor_gain_error=e.sensor_gain_error),
        'all (true)': true,
    }


def median_step_us(model, run, extensions, steps=3000) -> float:
    ukf = PamUkf(model=model, x0=X0, extensions=extensions)
    ukf.step(run.p_measured[1], run.u[0])          # loads the compiled kernels
    ukf.reset()
    times = np.empty(steps)
    for k in range(steps):
        start = time.perf_counter()
        ukf.step(run.p_measured[k + 1], run.u[k])
        times[k] = time.perf_counter() - start
    return float(np.median(times)) * 1e6


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--duration', type=float, default=130.0, help='s (default: %(default)g)')
    args = parser.parse_args()
    scenario = load_scenario('realistic')
    true = extensions_from_dict({k: getattr(scenario.effects, k) for k in ESTIMATOR_FIELDS},
                                'realistic')
    model = PamModel(params=scenario.apply(load_parameters('default')))
    profile = validation_profile(SEED, args.duration, model.h)
    print(f"'realistic' plant ({scenario.effects.describe()}), validation profile seed {SEED}, "
          f'{args.duration:g} s; estimators with the true mild parameters and these extensions '
          f'(true: {true.describe()}). Q % over the whole run:')
    print(f'{"extensions":<22} {"free: alone":>12} {"UKF":>7}   {"locked: alone":>14} {"UKF":>7}'
          f'   | after {DEFAULT_TRANSIENT:g} s: {"free UKF":>8} {"locked UKF":>10}')
    runs = {locked: simulate(replace(model, locked=locked), profile.u, X0, scenario.sensor,
                             SEED, effects=scenario.effects) for locked in (False, True)}
    for label, extensions in variants(true).items():
        row = []
        for locked in (False, True):
            table, alone, ukf = evaluate(runs[locked], model, extensions=extensions)
            after = table_after(runs[locked], alone, ukf)
            row += [100 * table['model'].Q, 100 * table['ukf'].Q, 100 * after['ukf'].Q]
        print(f'{label:<22} {row[0]:11.2f}% {row[1]:6.2f}%   {row[3]:13.2f}% {row[4]:6.2f}%'
              f'   | {" " * 11}{row[2]:7.2f}% {row[5]:9.2f}%', flush=True)
    free = replace(model, locked=False)
    print(f'UKF median step: {median_step_us(free, runs[False], NO_EXTENSIONS):.1f} us without '
          f'extensions, {median_step_us(free, runs[False], true):.1f} us with all')


if __name__ == '__main__':
    main()
