#!/usr/bin/env python3
"""How the default UKF tuning was chosen: a grid over the diagonal of Q on the accuracy scenario
(benchmarks/accuracy_scenario.py), with R = (2 kPa)^2, the variance of the simulated sensor.

Prints angle and torque metrics of the UKF for each Q. Takes a few minutes.

    .venv/bin/python benchmarks/ukf_tuning_sweep.py
"""

import itertools

from accuracy_scenario import scenario_runs
from pam_estimator.evaluation import measured_and_estimated, run_ukf
from pam_estimator.pam_ukf import DEFAULT_TUNING, UkfTuning
from pam_model.metrics import metrics
from pam_model.model import PamModel

GRID_PSI = (1e-10, 1e-9, 1e-8)          # rad^2
GRID_PSI_DOT = (1e-7, 1e-6, 1e-5, 1e-4)  # (rad/s)^2
GRID_P = (1e2, 1e3, 1e4)                # Pa^2
R = (4e6, 4e6)                          # Pa^2


def main():
    runs = scenario_runs()
    for q_psi, q_psi_dot, q_p in itertools.product(GRID_PSI, GRID_PSI_DOT, GRID_P):
        tuning = UkfTuning(Q=(q_psi, q_psi_dot, q_p, q_p), R=R, P0=DEFAULT_TUNING.P0)
        rows = []
        for kind, run in runs.items():
            model = PamModel(locked=run.locked)
            rows.append(f'{kind} ' + metrics(*measured_and_estimated(
                run, run_ukf(run, model, tuning))).row())
        print(f'Q diag ({q_psi:g}, {q_psi_dot:g}, {q_p:g}, {q_p:g}):  ' + ' | '.join(rows),
              flush=True)


if __name__ == '__main__':
    main()
