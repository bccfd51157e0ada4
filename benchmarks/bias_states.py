#!/usr/bin/env python3
"""The UKF's bias states (docs/model_extensions.md, "Bias states") on the 'realistic' rig:
validation profile (seed 1) on the realistic plant (mild parameter mismatch, every unmodelled
effect), free and locked; the UKF with (a) the nominal model, (b) the TRUE mild parameters without
extensions, (c) the true parameters with the true extensions (the scenario's estimator-side
effects, or --extensions FILE), each without bias states, with the default ones (sensor offsets
b1, b2) and with a moving torque bias too (TORQUE_BIAS_STATES); Q (%) of the
angle (free) / torque (locked) over the whole run and after the initial transient, the biases at
the end, and the UKF's time per sample.

    .venv/bin/python benchmarks/bias_states.py [--duration 130] [--extensions FILE]
"""

import argparse
import time
from dataclasses import replace

from pam_estimator.bias_ukf import DEFAULT_BIAS_STATES, TORQUE_BIAS_STATES
from pam_estimator.evaluation import measured_and_estimated, run_ukf, start_state
from pam_model.metrics import DEFAULT_TRANSIENT, metrics, metrics_after
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.model_extensions import (
    ESTIMATOR_FIELDS,
    NO_EXTENSIONS,
    extensions_from_dict,
    load_extensions,
)
from pam_model.parameters import load_parameters
from pam_model.profiles import validation_profile
from pam_model.rest import REST_STATE
from pam_model.simulate import simulate

X0 = REST_STATE
SEED = 1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--duration', type=float, default=130.0, help='s (default %(default)g)')
    parser.add_argument('--extensions', default='', metavar='FILE',
                        help="the 'true' extensions (default: the scenario's own)")
    args = parser.parse_args()
    scenario = load_scenario('realistic')
    nominal = load_parameters('default')
    true_params = scenario.apply(nominal)
    true_ext = (load_extensions(args.extensions) if args.extensions else extensions_from_dict(
        {k: getattr(scenario.effects, k) for k in ESTIMATOR_FIELDS}, 'realistic'))
    cases = {'(a) nominal model': (nominal, NO_EXTENSIONS),
             '(b) true params, no ext.': (true_params, NO_EXTENSIONS),
             '(c) true params + true ext.': (true_params, true_ext)}
    print(f'realistic rig, validation profile seed {SEED}, {args.duration:g} s; Q % whole run '
          f'(after {DEFAULT_TRANSIENT:g} s), UKF time per sample, biases at the end')
    for locked in (False, True):
        plant = PamModel(params=true_params, locked=locked)
        profile = validation_profile(SEED, args.duration, plant.h)
        run = simulate(plant, profile.u, X0, scenario.sensor, SEED, effects=scenario.effects)
        print(f'\n{"locked (Q_tau)" if locked else "free (Q_psi)"}')
        for label, (params, ext) in cases.items():
            model = replace(plant, params=params)
            row = f'  {label:<28}'
            for bias in (None, DEFAULT_BIAS_STATES, TORQUE_BIAS_STATES):
                t0 = time.perf_counter()
                est = run_ukf(run, model, x0=start_state(run, extensions=ext), extensions=ext,
                              bias_states=bias)
                us = 1e6 * (time.perf_counter() - t0) / len(run.t)
                whole = metrics(*measured_and_estimated(run, est))
                after = metrics_after(run.t, *measured_and_estimated(run, est))
                name = 'off' if bias is None else 'b1,b2' if bias.torque_rate == 0 else '+b_tau'
                row += (f' | {name:<6} {100 * whole.Q:6.2f} '
                        f'({100 * after.Q:6.2f}) {us:5.1f} us')
                if est.biases is not None:
                    b1, b2, bt = est.biases[-1]
                    row += f' b=({b1:.0f}, {b2:.0f}) Pa {bt:+.3f} N m'
            print(row, flush=True)


if __name__ == '__main__':
    main()
