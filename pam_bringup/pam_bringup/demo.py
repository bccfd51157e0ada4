"""pam-demo: the main job (`make demo`): sensor-less angle control of the simulated rig in real
time.

pam-bringup starts, composed in one process (pam_container; its default), the simulated rig
(sim_node at 1 kHz, the 'mild' mismatched plant with its noisy 12-bit pressure sensors), the UKF
(ukf_node, nominal model), the PI controller (pi_node, feedback = the estimate) and reference_node
(paper-style angle steps within +-20 deg, 8 s each), from pam_bringup's config/bringup.yaml; its
output goes to OUT/logs/bringup.log, the stack's to OUT/logs/pam_container.log. tracking_report (a
process of its own, talking to the stack over DDS) records --duration seconds, then prints per step
the steady-state error against the true (measured) angle and the settling time, the estimation
error, and writes a figure like the paper's Fig. 14 to OUT/demo_tracking.png. Then pam-bringup is
stopped (SIGINT).

The ROS domain is --domain-id, else ROS_DOMAIN_ID, else a random one in 110..199 (the demo does
not talk to other graphs); discovery stays on this machine unless ROS_AUTOMATIC_DISCOVERY_RANGE
says otherwise.

Exit code: tracking_report's when it fails (1: nothing to report, 130: interrupted); 1 when
pam-bringup stopped before the end (the end of its log is printed); 2 on a usage or set-up error;
else 0. A Ctrl-C in the terminal reaches tracking_report, which reports what it recorded;
SIGTERM / SIGHUP to pam-demo are passed on to it as SIGINT.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
from pathlib import Path

from pam_common.executables import executable_candidates, find_executable

from .stack import PACKAGE
from .supervisor import Child, Output, Supervisor

PROG = 'pam-demo'
DEFAULT_DURATION = 64.0      # s: the reference profile's 8 steps of 8 s
DEMO_DOMAINS = (110, 199)    # the random ROS_DOMAIN_ID's range (inclusive)
LOG_TAIL_LINES = 30          # of pam-bringup's log, when it stopped early
BRINGUP_SIGTERM_AFTER = 20.0   # s after our SIGINT: more than pam-bringup's own stop (<= 16 s)
BRINGUP_STOP_TIMEOUT = 30.0    # s after our SIGINT: SIGKILL


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='The main job: pam-bringup runs the simulated rig, ukf_node, pi_node and '
                    'reference_node; tracking_report records the closed-loop angle tracking, '
                    'prints per step the error against the true angle and the settling time, '
                    'and writes OUT/demo_tracking.png.',
        epilog='Exit codes: 0 done, 1 pam-bringup stopped early or nothing to report, 2 usage '
               'or set-up error, 130 interrupted. `make demo` runs it (DURATION=30 make demo: '
               '--duration 30).')
    parser.add_argument('--duration', type=float, default=DEFAULT_DURATION, metavar='SECONDS',
                        help=f'how long tracking_report records (default {DEFAULT_DURATION:g})')
    parser.add_argument('--transient', type=float, default=1.0, metavar='SECONDS',
                        help='tracking_report also prints the estimation error over t >= '
                             'SECONDS of its record (default 1)')
    parser.add_argument('--out', type=Path, default=Path('out'), metavar='DIR',
                        help='where the figure (DIR/demo_tracking.png) and the logs (DIR/logs/) '
                             'go (default: out)')
    parser.add_argument('--domain-id', type=int, metavar='N',
                        help='ROS_DOMAIN_ID (default: ROS_DOMAIN_ID, else a random one in '
                             f'{DEMO_DOMAINS[0]}..{DEMO_DOMAINS[1]})')
    args = parser.parse_args(argv)
    if not 1.0 <= args.duration <= 86400.0:   # tracking_report's range for its duration
        parser.error(f'--duration must be in 1..86400 s, got {args.duration:g}')
    if not 0.0 <= args.transient <= 86400.0:   # tracking_report's range for its transient
        parser.error(f'--transient must be in 0..86400 s, got {args.transient:g}')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        parser.error(f'--domain-id must be in 0..232, got {args.domain_id}')
    return args


def error(text: str) -> int:
    print(f'{PROG}: error: {text}', file=sys.stderr, flush=True)
    return 2


def demo_domain(given: int | None) -> str:
    if given is not None:
        return str(given)
    return os.environ.get('ROS_DOMAIN_ID') or str(random.randint(*DEMO_DOMAINS))


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    executables = {}
    for name in ('pam-bringup', 'tracking_report'):
        executables[name] = find_executable(name, PACKAGE)
        if executables[name] is None:
            return error(f"executable '{name}' of {PACKAGE} not found (run `make setup`); "
                         f"looked in: {'; '.join(executable_candidates(name, PACKAGE))}")
    logs = args.out / 'logs'
    try:
        logs.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return error(f'cannot create {logs}: {exc.strerror}')
    env = dict(os.environ, ROS_DOMAIN_ID=demo_domain(args.domain_id))
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

    report = None

    def pass_on(signum, frame) -> None:
        if signum != signal.SIGINT and report is not None and report.poll() is None:
            report.send_signal(signal.SIGINT)   # a Ctrl-C reaches it from the terminal itself

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, pass_on)
    print(f"demo: ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}, {args.duration:g} s of closed-loop "
          f'angle tracking; node logs in {logs}/', flush=True)
    # pam-bringup in a process group of its own (pam_bringup.supervisor): a Ctrl-C in the
    # terminal does not stop the stack under the report; we stop it once the report is done.
    # Its output goes to LOGS/bringup.log only.
    bringup = Child('bringup', [executables['pam-bringup'], '--log-dir', str(logs)],
                    'the stack')
    stack = Supervisor([bringup], env, Output(PROG, [bringup.name], False, echo=False),
                       log_dir=logs, sigterm_after=BRINGUP_SIGTERM_AFTER,
                       stop_timeout=BRINGUP_STOP_TIMEOUT)
    stack.start()
    try:
        report = subprocess.Popen(
            [executables['tracking_report'], '--ros-args', '-p',
             f'duration:={args.duration:.1f}', '-p', f'transient:={args.transient:.3f}', '-p',
             'start:=step', '-p',
             f"plot:={args.out / 'demo_tracking.png'}"], env=env)
        code = report.wait()
        if code != 0:
            return code
        if stack.dead():
            print('demo: pam-bringup stopped early; its log:', file=sys.stderr)
            print('\n'.join(list(bringup.tail)[-LOG_TAIL_LINES:]), file=sys.stderr, flush=True)
            return 1
        return 0
    finally:
        if report is not None and report.poll() is None:
            report.send_signal(signal.SIGINT)
            report.wait()
        stack.stop()


if __name__ == '__main__':
    sys.exit(main())
