#!/usr/bin/env python3
"""Real-time factor of the batch simulator: the 130 s validation profile at 1 kHz.

Target (foundation issue): >= 100x real time. Prints the first call (includes loading numba's
on-disk cache or compiling) and the median of repeated runs, plus the per-step cost of the
scalar step called from Python (what sim_node pays per sample) and of the vectorised path.

    .venv/bin/python benchmarks/simulate_speed.py [--repeats 5]
"""

import argparse
import statistics
import time

import numpy as np

from pam_model.model import PamModel
from pam_model.profiles import validation_profile
from pam_model.rest import REST_STATE
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()

    model = PamModel()
    profile = validation_profile(0)
    x0 = list(REST_STATE)
    sensor = PressureSensor(2000.0, 12)
    duration = len(profile.t) * model.h

    start = time.perf_counter()
    simulate(model, profile.u, x0, sensor=sensor)
    first = time.perf_counter() - start
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        simulate(model, profile.u, x0, sensor=sensor)
        times.append(time.perf_counter() - start)
    median = statistics.median(times)

    x = np.array(x0)
    n = 5000
    start = time.perf_counter()
    for j in range(n):
        x, _, _ = model.step(x, profile.u[j])
    scalar_us = (time.perf_counter() - start) / n * 1e6

    X = np.tile(x0, (9, 1))
    start = time.perf_counter()
    for j in range(1000):
        X, _, _ = model.step_many(X, profile.u[j])
    vector_us = (time.perf_counter() - start) / 1000 * 1e6

    print(f'batch simulator, {duration:.0f} s validation profile at {1 / model.h:.0f} Hz '
          f'(free joint, proposed friction, 12-bit noisy sensor):')
    print(f'  first call  {first:.3f} s  ({duration / first:.0f}x real time, incl. cache load)')
    print(f'  median of {args.repeats}  {median:.3f} s  ({duration / median:.0f}x real time; '
          f'target >= 100x)')
    print(f'  scalar step from Python      {scalar_us:.1f} us/step')
    print(f'  vectorised step, 9 states    {vector_us:.1f} us/step')


if __name__ == '__main__':
    main()
