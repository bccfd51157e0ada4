"""benchmarks/stack_load.py's baseline: the models' own compute per sample, back to back and
paced at 1 kHz as sim_node's sampler paces them (the scenario's plant, the nominal UKF, PI)."""

import importlib.util
import math
import time
from pathlib import Path

BENCHMARK = Path(__file__).resolve().parents[2] / 'benchmarks' / 'stack_load.py'


def stack_load(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARK.parent))
    spec = importlib.util.spec_from_file_location('stack_load', BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_baseline_times_each_kernel_and_the_three_paced_at_1_khz(monkeypatch):
    module = stack_load(monkeypatch)
    start = time.monotonic()
    kernels = module.kernels_per_sample('realistic', None, samples=50, paced=200)
    took = time.monotonic() - start
    assert set(kernels) == {'sim', 'ukf', 'pi', 'paced'}
    assert all(math.isfinite(v) and v > 0.0 for v in kernels.values())
    assert took >= 0.199            # 200 deadlines 1 ms apart: the pacing is real
    assert kernels['paced'] < 1e-3  # CPU per sample, not the period
