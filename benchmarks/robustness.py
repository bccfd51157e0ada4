#!/usr/bin/env python3
"""Robustness benchmark: the installed pam-robustness with its defaults, as a
user runs it, with the machine's load beside its time.

Every unmodelled effect (and all at once) at 0, 0.5, 1, 2 x its realistic value on the 'mild'
plant, and 6 Monte Carlo parameter draws per magnitude: the UKF's whole-run Q_psi and Q_tau over
the 130 s validation profile (nominal and oracle estimators) and the sensor-less closed loop's
worst steady-state error and settling over the demo's 64 s of angle steps. Writes
OUT/robustness.json and OUT/robustness_<figure>.png; docs/robustness.md holds the figures.
About 7.5 minutes (447 s of CPU) on the 2-core development machine at low load.

    .venv/bin/python benchmarks/robustness.py [--out out/robustness] [pam-robustness options]
"""

import argparse
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', default='out/robustness', help='directory for JSON and plots')
    args, extra = parser.parse_known_args()
    tool = shutil.which('pam-robustness') or str(Path(sys.executable).parent / 'pam-robustness')
    out = Path(args.out)
    print(f'load average before: {" ".join(f"{v:.2f}" for v in os.getloadavg())} '
          f'({os.cpu_count()} CPUs)', flush=True)
    clock = time.perf_counter()
    code = subprocess.call([tool, '--json', str(out / 'robustness.json'), '--plots', str(out),
                            *extra])
    print(f'benchmark: {time.perf_counter() - clock:.0f} s wall, load average after: '
          f'{" ".join(f"{v:.2f}" for v in os.getloadavg())}')
    return code


if __name__ == '__main__':
    sys.exit(main())
