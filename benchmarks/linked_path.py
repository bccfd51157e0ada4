#!/usr/bin/env python3
"""The linked 1 kHz path alone: CPU per sample of rig -> UKF -> PI -> command, in one thread.

sim_node, ukf_node and pi_node are built in this process with the in-process links on
(pam_common.links, as `pam_container --links` builds them, with the parameters stack_load.py
gives them: bringup.yaml, the rig on --scenario, ukf_node on --identified), no executor, no
sampling thread: this script takes each sample itself (SimCore.realtime_samples, then the node's
own messages and publish, which the links hand to ukf_node, whose estimate they hand to pi_node,
whose command they hand back to sim_node). The reference is a step of --step rad every 2 s.
Two timings of --samples samples each, this thread's CPU:
  back to back  one sample after the other: the path's own cost, warm caches, no wake-ups;
  paced         one sample per 1 ms deadline, sleeping between (as sim_node's sampler): the
                cost inside a 1 kHz loop, wake-ups and cold caches included;
beside the models' own compute measured the same two ways (stack_load.py's baseline,
pam_bringup.model_cost). The difference is the nodes' Python and rclpy around the kernels; the
whole container's CPU (executor, DDS, diagnostics) is stack_load.py's figure.

    .venv/bin/python benchmarks/linked_path.py [--scenario realistic]
        [--identified out/demo/identified] [--samples 5000]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from stack_load import params_file

STEP_PERIOD = 2000      # samples between two reference steps


def linked_nodes(params: Path):
    """(sim_node, ukf_node, pi_node) of one process with the links on, not started."""
    from pam_common.links import enable_links
    from pam_controller.pi_node import PiNode
    from pam_driver.sim_node import configured_sim_node
    from pam_estimator.ukf_node import UkfNode
    links = enable_links()
    kwargs = {'namespace': '/pam', 'cli_args': ['--ros-args', '--params-file', str(params)]}
    nodes = configured_sim_node(**kwargs), UkfNode(**kwargs), PiNode(**kwargs)
    links.open()
    return nodes


def time_path(sim, pi, samples: int, paced: bool, step: float) -> float:
    """This thread's CPU per sample (s) over `samples` samples of the linked path."""
    from pam_interfaces.msg import Reference
    core = sim.core
    t0_ns = time.time_ns()
    start = time.monotonic() + 0.01
    first = core.rig.k
    cpu = time.thread_time()
    for n in range(samples):
        if n % STEP_PERIOD == 0:
            pi._on_reference(Reference(mode=Reference.ANGLE,
                                       value=step if (n // STEP_PERIOD) % 2 == 0 else -step))
        if paced:
            delay = start + n * 1e-3 - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
        sample = core.realtime_samples(0, [t0_ns + (first + n) * 1_000_000])[0]
        sim._publish(sim._messages(sample))
    return (time.thread_time() - cpu) / samples


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--scenario', default='realistic', metavar='NAME',
                        help="the simulated rig's scenario (default realistic)")
    parser.add_argument('--identified', type=Path, metavar='DIR',
                        help="ukf_node's model: a pam-identify output directory (default: the "
                             'nominal model)')
    parser.add_argument('--samples', type=int, default=5000, help='samples per timing')
    parser.add_argument('--step', type=float, default=0.3,
                        help='rad, the reference steps between +step and -step')
    args = parser.parse_args(argv)
    if args.samples < 100:
        parser.error('--samples >= 100')
    import rclpy
    rclpy.init()
    try:
        with tempfile.TemporaryDirectory() as folder:
            params = params_file(Path(folder), {}, args.scenario, args.identified)
            sim, ukf, pi = linked_nodes(params)
            time_path(sim, pi, 1000, False, args.step)          # warm-up
            back_to_back = time_path(sim, pi, args.samples, False, args.step)
            paced = time_path(sim, pi, args.samples, True, args.step)
            estimate = ukf.core.last_output.x[0]
            truth = sim.core.rig.x[0]
            for node in (sim, ukf, pi):
                node.destroy_node()
    finally:
        rclpy.try_shutdown()
    from pam_bringup.model_cost import measure_model_cost
    cost = measure_model_cost(args.scenario, args.identified, paced=args.samples)
    print(f'the linked path (sim_node -> ukf_node -> pi_node -> sim_node), {args.samples} '
          f'samples each, CPU of this thread per sample:')
    print(f'  back to back: {back_to_back * 1e6:7.1f} us; the models alone '
          f'{cost.back_to_back * 1e6:6.1f} us ({back_to_back / cost.back_to_back:.1f} x)')
    print(f'  paced 1 kHz:  {paced * 1e6:7.1f} us; the models alone {cost.paced * 1e6:6.1f} us '
          f'({paced / cost.paced:.1f} x)')
    print(f'  (the last estimate {estimate:+.4f} rad, the plant {truth:+.4f} rad)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
