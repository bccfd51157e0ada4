#!/usr/bin/env python3
"""When does a subscriber that exists before the stack starts get each topic?

Each round: a probe node (this process, one rclpy context for all rounds, a fresh node per round,
as the tests' probe fixture does) subscribes /pam/pressures and /pam/estimate; then sim_node and
ukf_node start as separate processes on an isolated ROS domain (localhost discovery). It records
when the first message of each topic arrives (waiting up to --wait s for each), then stops both.
Prints every round and a summary: rounds where a topic never arrived ("missed for good"), and
the lag between the two topics' first arrivals. DDS discovery completes pair by pair: a pair of
participants that misses the initial announcements matches only at the next periodic one (Fast
DDS: every 3 s by default), so one topic can start flowing up to ~3 s after another.
--profile FILE runs every process with FASTRTPS_DEFAULT_PROFILES_FILE=FILE (e.g. a shorter
leaseAnnouncement period) to compare.

    .venv/bin/python benchmarks/discovery_latency.py [--rounds 30] [--wait 30] [--profile XML]
"""

import argparse
import os
import time

import rclpy
from rclpy.context import Context

from pam_common.testing import NodeProcess, Probe, child_env, wait_until
from pam_interfaces.msg import JointEstimate, Pressures


def first_arrival(collector, t0: float):
    items = collector.items()
    return items[0][0] - t0 if items else None


def one_round(context, env: dict, index: int, wait: float) -> tuple:
    """(first pressures s, first estimate s) after the processes started; None: never."""
    probe = Probe(context, f'discovery_probe_{index}')
    pressures = probe.subscribe(Pressures, '/pam/pressures', depth=1000)
    estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=1000)
    t0 = time.monotonic()
    nodes = [NodeProcess('sim_node', 'pam_driver', [], env, cwd='/tmp'),
             NodeProcess('ukf_node', 'pam_estimator', [], env, cwd='/tmp')]
    try:
        wait_until(lambda: len(pressures) > 0 and len(estimates) > 0, wait)
        return first_arrival(pressures, t0), first_arrival(estimates, t0)
    finally:
        for node in nodes:
            node.close()
        probe.close()


def text(value) -> str:
    return 'never' if value is None else f'{value:.2f} s'


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--rounds', type=int, default=30)
    parser.add_argument('--wait', type=float, default=30.0,
                        help='s to wait for each topic before counting it missed')
    parser.add_argument('--profile', help='a Fast DDS XML profile for every process')
    args = parser.parse_args()
    domain = os.getpid() % 90 + 110
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    if args.profile:
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = os.path.abspath(args.profile)
    env = child_env(domain)
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    results = []
    try:
        for index in range(args.rounds):
            p, e = one_round(context, env, index, args.wait)
            lag = None if p is None or e is None else p - e
            results.append((p, e, lag))
            print(f'round {index + 1:3d}: first /pam/pressures {text(p)}, first /pam/estimate '
                  f'{text(e)}, pressures - estimate {text(lag)}', flush=True)
    finally:
        context.try_shutdown()
    missed = sum(1 for p, e, _ in results if p is None or e is None)
    lags = sorted(abs(lag) for _, _, lag in results if lag is not None)
    print(f'\n{len(results)} rounds (profile: {args.profile or "Fast DDS defaults"}): '
          f'missed for good (> {args.wait:g} s): {missed}')
    if lags:
        print(f'|lag| between the two topics\' first messages: median '
              f'{lags[len(lags) // 2]:.2f} s, max {lags[-1]:.2f} s, '
              f'rounds >= 1 s: {sum(v >= 1.0 for v in lags)}, '
              f'>= 2 s: {sum(v >= 2.0 for v in lags)}')


if __name__ == '__main__':
    main()
