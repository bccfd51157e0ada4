#!/usr/bin/env python3
"""Per-step cost of the UKF: ours (one numba-compiled kernel per step) against the same filter on
filterpy (the test oracle), timed in one run over the same samples. Targets: >= 10x faster than
filterpy, median under 30 us (the paper's C implementation: 346 us per step at 3.2 GHz).

    .venv/bin/python benchmarks/ukf_speed.py [--steps 3000]
"""

import argparse
import time

import numpy as np

from pam_estimator.pam_ukf import DEFAULT_TUNING, PamUkf
from pam_estimator.reference import filterpy_ukf
from pam_model.model import PamModel
from pam_model.profiles import validation_profile
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate


def per_step_times(step, n):
    times = np.empty(n)
    for k in range(n):
        start = time.perf_counter()
        step(k)
        times[k] = time.perf_counter() - start
    return times


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--steps', type=int, default=3000)
    args = parser.parse_args()
    n = args.steps
    profile = validation_profile(0, duration=max(10.0, (n + 1) * 1e-3))
    x0 = (0.0, 0.0, 4.5e5, 4.5e5)
    run = simulate(PamModel(), profile.u[:n + 1], x0, sensor=PressureSensor(2000.0, 12))
    model = PamModel()

    start = time.perf_counter()
    ours = PamUkf(model=model, x0=x0)
    ours.step(run.p_measured[1], run.u[0])
    first = time.perf_counter() - start
    ours.reset()
    ref = filterpy_ukf(model, DEFAULT_TUNING, x0)

    def step_ours(k):
        ours.step(run.p_measured[k + 1], run.u[k])

    def step_ref(k):
        ref.predict(u=run.u[k])
        ref.update(run.p_measured[k + 1])

    t_ours = per_step_times(step_ours, n)
    t_ref = per_step_times(step_ref, n)
    med_o, p99_o = np.median(t_ours) * 1e6, np.percentile(t_ours, 99) * 1e6
    med_r, p99_r = np.median(t_ref) * 1e6, np.percentile(t_ref, 99) * 1e6
    print(f'UKF step over {n} samples (4 states, 9 sigma points, RK4):')
    print(f'  ours (numba kernel)   median {med_o:7.1f} us   p99 {p99_o:7.1f} us')
    print(f'  filterpy reference    median {med_r:7.1f} us   p99 {p99_r:7.1f} us')
    print(f'  speed-up (median)     {med_r / med_o:.1f}x   (target >= 10x; ours median target '
          f'< 30 us)')
    print(f'  first call incl. loading the compiled kernel: {first * 1e3:.0f} ms')


if __name__ == '__main__':
    main()
