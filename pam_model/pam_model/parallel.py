"""Independent jobs in worker processes: the offline tools' long, separate pieces (a campaign's
runs, a set of bags to read) on every CPU at once, with results that do not depend on it."""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor


def cpus() -> int:
    """CPUs this process may run on."""
    return len(os.sched_getaffinity(0))


def map_in_processes(function, items, workers: int | None = None, cost=None) -> list:
    """[function(item) for item in items], in that order, computed in up to `workers` processes
    (default: one per CPU; one worker or one item: in this process). `function` and the items
    must be picklable (a module-level function, a functools.partial of one); an exception in a
    job is raised here. cost(item) orders the jobs, the costliest first, so that the last job to
    start is a short one. The workers come from a fork server (a clean single-threaded process
    started for the pool): forking the caller itself is unsafe once it has threads (a ROS
    node's, a test session's), and the workers load the compiled kernels from numba's cache
    (written at set-up) instead of compiling them."""
    items = list(items)
    workers = min(len(items), workers or cpus())
    if workers < 2:
        return [function(item) for item in items]
    order = sorted(range(len(items)), key=lambda i: -cost(items[i])) if cost else \
        list(range(len(items)))
    context = multiprocessing.get_context('forkserver')
    with ProcessPoolExecutor(workers, mp_context=context) as pool:
        results = dict(zip(order, pool.map(function, [items[i] for i in order]), strict=True))
    return [results[i] for i in range(len(items))]
