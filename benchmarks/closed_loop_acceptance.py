#!/usr/bin/env python3
"""Acceptance of sensor-less PI control (controller issue, section 5), over DDS in lockstep.

sim_node (lockstep, the 'mild' plant with its sensor), ukf_node (nominal model) and pi_node
(default gains, feedback = the estimate) run as separate processes; paper-style reference steps
(pam_model.profiles.step_reference_profile) are held 8 s each, within +-20 deg (free joint) and
+-2 N m (locked joint). The steady-state error of a step is |reference - true value| averaged
over the last second of its hold, in % of the 40 deg / 4 N m range.
Targets: worst step <= 3.0 % (angle) and <= 3.5 % (torque), settling <= 3 s, no sustained
oscillation (ripple), no windup overshoot after saturation. Also printed: the samples ukf_node
and pi_node counted lost (gaps in Pressures.sample / JointEstimate.sample, their last
/diagnostics): none is expected in lockstep.

    .venv/bin/python benchmarks/closed_loop_acceptance.py [--steps 6] [--seed 2]
"""

import argparse
import math
import os
import time

from pam_bringup.lockstep_run import run_lockstep_steps
from pam_common.sample_gaps import loss_summary
from pam_model.profiles import step_reference_profile

TARGETS = {'angle': 3.0, 'torque': 3.5}


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--steps', type=int, default=6, help='holds per mode (first is 0)')
    parser.add_argument('--seed', type=int, default=2)
    args = parser.parse_args()
    all_ok = True
    for k, mode in enumerate(('angle', 'torque')):
        hold = 8.0
        levels = step_reference_profile(mode, args.seed, args.steps * hold, hold, Ts=hold).value
        start = time.monotonic()
        diagnostics = {}
        report, t, _, _ = run_lockstep_steps(mode, levels, hold,
                                             domain_id=os.getpid() % 80 + 120 + k, seed=args.seed,
                                             timeout=1200.0, diagnostics=diagnostics)
        scale, unit = (math.degrees(1.0), 'deg') if mode == 'angle' else (1.0, 'Nm')
        print(f'{mode}: {len(levels)} holds of {hold:g} s, {t[-1]:.1f} s simulated in '
              f'{time.monotonic() - start:.0f} s wall')
        for line in report.lines(scale, unit):
            print('  ' + line)
        for node in ('ukf_node', 'pi_node'):
            print(f'  {node}: {loss_summary(diagnostics.get(node, {}))}')
        ok = (report.worst_error <= TARGETS[mode] and report.worst_settling <= 3.0
              and report.worst_ripple < 1.0)
        print(f'  target: worst steady-state error <= {TARGETS[mode]} %, settling <= 3 s, no '
              f'sustained oscillation: {"met" if ok else "MISSED"}\n')
        all_ok = all_ok and ok
    print('all targets met' if all_ok else 'SOME TARGETS MISSED')


if __name__ == '__main__':
    main()
