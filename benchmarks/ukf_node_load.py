#!/usr/bin/env python3
"""ukf_node at 1 kHz: dropped samples, CPU share and pressure-to-estimate latency.

Starts sim_node (real time, 1 kHz) and ukf_node as separate processes on an isolated ROS domain;
a probe node in this process records, by stamp, when each pressure sample and each estimate
arrives (one clock), while the rig is driven by antagonistic steps. Prints the estimate count
against the pressure count, the samples lost by the sample counter (gaps in Pressures.sample
that ukf_node reports on /diagnostics, since it started; gaps in the counters the probe got),
ukf_node's CPU share (from /proc over the window) and the latency p50 / p99 (estimate arrival
minus pressure arrival, both seen by the probe).

    .venv/bin/python benchmarks/ukf_node_load.py [--seconds 10]
"""

import argparse
import os
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context

from pam_common.diagnostics import status_values
from pam_common.sample_gaps import SampleGaps, loss_summary
from pam_common.stamps import stamp_ns
from pam_common.testing import NodeProcess, Probe, child_env, diagnostic_statuses, wait_until
from pam_interfaces.msg import JointEstimate, Pressures, ValveCommand


def cpu_seconds(pid: int) -> float:
    with open(f'/proc/{pid}/stat') as stat:
        fields = stat.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=10.0)
    args = parser.parse_args()
    domain = os.getpid() % 90 + 110
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    env = child_env(domain)
    sim = NodeProcess('sim_node', 'pam_driver', [], env, cwd='/tmp')
    ukf = NodeProcess('ukf_node', 'pam_estimator', [], env, cwd='/tmp')
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    probe = Probe(context, 'ukf_load_probe')
    arrivals_p, arrivals_e = {}, {}
    gaps_p, gaps_e = SampleGaps(), SampleGaps()      # of what the probe got

    def on_pressures(m):
        arrivals_p.setdefault(stamp_ns(m.header.stamp), time.time_ns())
        gaps_p.update(m.sample)

    def on_estimate(m):
        arrivals_e.setdefault(stamp_ns(m.header.stamp), time.time_ns())
        gaps_e.update(m.sample)

    probe.subscribe(Pressures, '/pam/pressures', on_pressures)
    probe.subscribe(JointEstimate, '/pam/estimate', on_estimate)
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=100)
    commands = probe.publisher(ValveCommand, '/pam/valve_command')
    try:
        if not wait_until(lambda: len(arrivals_e) > 500, 90.0):
            raise SystemExit(f'no estimates; ukf_node stderr:\n{ukf.stderr}')
        arrivals_p.clear()
        arrivals_e.clear()
        cpu0, wall0 = cpu_seconds(ukf.proc.pid), time.monotonic()
        k = 0
        while time.monotonic() - wall0 < args.seconds:
            d = 1.5 if (k // 20) % 2 else -1.5                  # 2 s steps
            commands.publish(ValveCommand(u1=5.5 + d, u2=5.5 - d))
            k += 1
            time.sleep(0.1)
        cpu_share = (cpu_seconds(ukf.proc.pid) - cpu0) / (time.monotonic() - wall0)
        time.sleep(1.5)                                       # one more /diagnostics
        statuses = diagnostic_statuses(diagnostics, 'ukf_node')
        ukf_values = status_values(statuses[-1]) if statuses else {}
    finally:
        probe.close()
        context.try_shutdown()
        for process in (ukf, sim):
            process.close()
    window = sorted(arrivals_p)[:-200]                        # leave the tail in flight
    missing = [s for s in window if s not in arrivals_e]
    latency = np.array([arrivals_e[s] - arrivals_p[s] for s in window if s in arrivals_e]) / 1e3
    print(f'ukf_node at 1 kHz over {args.seconds:g} s (sim_node real time, separate processes):')
    print(f'  pressure samples {len(window)}, estimates missing {len(missing)}')
    print(f'  ukf_node /diagnostics (since it started): {loss_summary(ukf_values)}')
    print(f'  probe, pressures: {loss_summary(gaps_p.values())}; estimates: '
          f'{loss_summary(gaps_e.values())}')
    print(f'  CPU share of ukf_node {100 * cpu_share:.1f} % of one core')
    print(f'  latency pressure -> estimate (seen by one probe): p50 {np.median(latency):.0f} us, '
          f'p99 {np.percentile(latency, 99):.0f} us, max {latency.max():.0f} us')


if __name__ == '__main__':
    main()
