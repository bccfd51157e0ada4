#!/usr/bin/env python3
"""How the default PI gains were found: a grid search on the batch simulator, the sensor-less
loop (plant 'mild' with its sensor -> UKF with nominal parameters -> PI) closed in one compiled
loop over all candidates, on paper-style reference steps (8 s holds within +-20 deg, +-2 N m).

Prints, per candidate, the step-response metrics (pam_controller.step_metrics): worst
steady-state error (% of the 40 deg / 4 N m range), worst settling time, overshoot and ripple.
The ranking key is the worst steady-state error plus a penalty for settling over 3 s,
overshoot over 15 % and ripple over 1 %.

    .venv/bin/python benchmarks/pi_gain_search.py [--mode angle|torque] [--seed 1]
"""

import argparse
import itertools
import time

import numpy as np

from pam_controller.closed_loop import simulate_closed_loop
from pam_controller.step_metrics import ANGLE_SPAN, TORQUE_SPAN
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.parameters import load_parameters
from pam_model.profiles import step_reference_profile

GRIDS = {'angle': (np.array([20.0, 30.0, 40.0, 60.0, 80.0]), np.array([10.0, 20.0, 30.0, 50.0])),
         'torque': (np.array([2.0, 3.0, 4.0, 6.0, 8.0]), np.array([2.0, 3.0, 5.0, 8.0]))}
SPANS = {'angle': ANGLE_SPAN, 'torque': TORQUE_SPAN}


def score(report) -> float:
    return (report.worst_error + max(0.0, report.worst_settling - 3.0)
            + max(0.0, report.worst_overshoot - 15.0) / 10.0 + max(0.0, report.worst_ripple - 1.0))


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--mode', choices=['angle', 'torque'], default='angle')
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--duration', type=float, default=48.0)
    args = parser.parse_args()
    scenario = load_scenario('mild')
    locked = args.mode == 'torque'
    plant = PamModel(params=scenario.apply(load_parameters()), locked=locked)
    reference = step_reference_profile(args.mode, args.seed, args.duration, hold=8.0).value
    kp, ki = GRIDS[args.mode]
    candidates = list(itertools.product(kp, ki))
    start = time.perf_counter()
    runs = simulate_closed_loop(plant, PamModel(locked=locked), reference, candidates,
                                sensor=scenario.sensor, mode=args.mode, seed=args.seed)
    elapsed = time.perf_counter() - start
    unit = 'V/rad' if args.mode == 'angle' else 'V/(N m)'
    print(f'{args.mode} mode, {len(candidates)} candidates x {args.duration:g} s in '
          f'{elapsed:.1f} s; kp in {unit}, ki in {unit}/s')
    rows = []
    for run in runs:
        report = run.report(SPANS[args.mode], 2.0)
        rows.append((score(report), run.gains, report))
    for s, (p, i), r in sorted(rows, key=lambda row: row[0]):
        print(f'kp {p:6.1f}  ki {i:6.1f}  worst error {r.worst_error:5.2f} %  settling '
              f'{r.worst_settling:5.2f} s  overshoot {r.worst_overshoot:5.1f} %  ripple '
              f'{r.worst_ripple:5.2f} %  score {s:.2f}')


if __name__ == '__main__':
    main()
