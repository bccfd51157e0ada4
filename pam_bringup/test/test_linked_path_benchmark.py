"""benchmarks/linked_path.py: the linked path's CPU per sample beside the models' own compute,
back to back and paced at 1 kHz."""

import re
import subprocess
import sys
from pathlib import Path

BENCHMARK = Path(__file__).resolve().parents[2] / 'benchmarks' / 'linked_path.py'


def test_the_linked_path_benchmark_times_the_path_beside_the_models():
    """benchmarks/linked_path.py, 200 samples: both timings printed, and the loop closed (the
    estimate follows the plant through the reference steps)."""
    out = subprocess.run([sys.executable, str(BENCHMARK), '--samples', '200'], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    figures = re.findall(r'(back to back|paced 1 kHz): +([\d.]+) us; the models alone +([\d.]+) '
                         r'us \(([\d.]+) x\)', out.stdout)
    assert [name for name, *_ in figures] == ['back to back', 'paced 1 kHz'], out.stdout
    assert all(float(path) > 0.0 and float(models) > 0.0 for _, path, models, _ in figures)
    estimate, truth = map(float, re.search(r'last estimate ([-+\d.]+) rad, the plant '
                                           r'([-+\d.]+) rad', out.stdout).groups())
    assert abs(estimate - truth) < 0.05, out.stdout
