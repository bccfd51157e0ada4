"""pam-demo: the main job (`make demo`): the workflow a lab follows, on the simulated rig.

1. The calibration campaign on the simulated rig of --scenario (default 'realistic': the 'mild'
   parameter mismatch plus the unmodelled effects of a real rig: valve lag, dead volume, supply
   droop and ripple, force hysteresis, temperature drift, sensor offsets): pam-calibration-bags
   writes the locked and free runs as bags (batch simulator; --campaign full|quick) into
   OUT/demo/calibration.
2. pam-identify fits the model to them (partial: what the runs cannot identify keeps its prior
   value and the report says so) into OUT/demo/identified (params.yaml, kappa.csv,
   extensions.yaml, report.txt).
3. Real-time sensor-less angle tracking, twice at once on one ROS domain in two namespaces:
   pam-bringup (composed) runs the simulated rig (sim_node at 1 kHz on the scenario), ukf_node,
   pi_node and reference_node (paper-style steps within +-20 deg, 8 s each), /nominal with the
   nominal model, /identified with the identified one; a tracking_report in each namespace
   records --duration seconds from the first step and reports per step the steady-state error
   against the TRUE angle and the settling time, and the estimation error I / M / Q.
4. The two reports, the nominal-vs-identified comparison, the figure OUT/demo_tracking.png (the
   identified run; OUT/demo_tracking_nominal.png the nominal one) and OUT/demo_summary.json.

OUT/demo is replaced by the next pam-demo (it carries a marker; a directory without it is never
removed). Node logs go to OUT/logs/. The ROS domain is --domain-id, else ROS_DOMAIN_ID, else a
random one in 110..199; discovery stays on this machine unless ROS_AUTOMATIC_DISCOVERY_RANGE says
otherwise.

Exit code: 0 done; 1 a step failed (its output is printed) or a stack stopped early; 2 a usage
or set-up error; 130 interrupted (Ctrl-C: the tracking reports print what they recorded). SIGTERM
/ SIGHUP are passed on to the running step as SIGINT.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

from pam_common.executables import executable_candidates, find_executable

from .demo_workflow import (
    CAMPAIGNS,
    RUNS,
    DemoPaths,
    comparison_lines,
    demo_summary,
    write_run_params,
)
from .json_file import write_json
from .stack import PACKAGE, default_params_file
from .supervisor import Child, Output, Supervisor

PROG = 'pam-demo'
DEFAULT_DURATION = 64.0      # s: the reference profile's 8 steps of 8 s
DEFAULT_SCENARIO = 'realistic'
DEMO_DOMAINS = (110, 199)    # the random ROS_DOMAIN_ID's range (inclusive)
LOG_TAIL_LINES = 30          # of a stack's log, when it stopped early
BRINGUP_SIGTERM_AFTER = 20.0   # s after our SIGINT: more than pam-bringup's own stop (<= 16 s)
BRINGUP_STOP_TIMEOUT = 30.0    # s after our SIGINT: SIGKILL
#: the executables of each step, by package
EXECUTABLES = {'pam-calibration-bags': 'pam_estimator', 'pam-identify': 'pam_estimator',
               'pam-bringup': PACKAGE, 'tracking_report': PACKAGE}


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='The main job, the workflow a lab follows on the simulated rig: the '
                    'calibration campaign (pam-calibration-bags), pam-identify, then real-time '
                    'sensor-less angle tracking with the nominal and the identified model side '
                    'by side (pam-bringup + tracking_report in /nominal and /identified); prints '
                    'per step and the comparison, writes OUT/demo_tracking.png and '
                    'OUT/demo_summary.json.',
        epilog='Exit codes: 0 done, 1 a step failed or a stack stopped early, 2 usage or set-up '
               'error, 130 interrupted. `make demo` runs it (DURATION=30 make demo: '
               '--duration 30).')
    parser.add_argument('--scenario', default=DEFAULT_SCENARIO, metavar='NAME|FILE',
                        help="the simulated rig's mismatch scenario: 'mild', 'strong', "
                             "'realistic', 'harsh' or a scenario YAML (default "
                             f'{DEFAULT_SCENARIO})')
    parser.add_argument('--campaign', choices=sorted(CAMPAIGNS), default='full',
                        help="the calibration campaign: 'full' (3 lock angles, 10 s holds, 60 s "
                             "free run) or 'quick' (2 angles, 5 voltages, 30 s free run) "
                             '(default full)')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the campaign (profiles, sensor noise) (default 0)')
    parser.add_argument('--duration', type=float, default=DEFAULT_DURATION, metavar='SECONDS',
                        help=f'how long each tracking run records (default {DEFAULT_DURATION:g})')
    parser.add_argument('--transient', type=float, default=1.0, metavar='SECONDS',
                        help='the estimation error is also given over t >= SECONDS of each '
                             'record (default 1)')
    parser.add_argument('--out', type=Path, default=Path('out'), metavar='DIR',
                        help='where the summary, the figures, OUT/demo (bags, identified model) '
                             'and OUT/logs go (default: out)')
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


def check_scenario(name: str) -> str | None:
    """None if the scenario loads, else the one-line reason."""
    from pam_model.mismatch import load_scenario
    from pam_model.parameters import ParameterError
    try:
        load_scenario(name)
    except (ParameterError, OSError, ValueError) as exc:
        return f'--scenario {name}: {exc}'
    return None


class Steps:
    """Runs the demo's steps one after the other; a signal is passed on to the running one."""

    def __init__(self, env: dict):
        self.env = env
        self.running: list[subprocess.Popen] = []
        self.interrupted = False
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, self._pass_on)

    def _pass_on(self, signum, frame) -> None:
        self.interrupted = True
        for proc in self.running:
            if proc.poll() is None and signum != signal.SIGINT:
                proc.send_signal(signal.SIGINT)   # a Ctrl-C reaches them from the terminal

    def run(self, title: str, argv: list[str], log: Path) -> int:
        """One batch step, its output to log (and the log's end printed if it fails)."""
        print(f'demo: {title} ...', flush=True)
        t0 = time.monotonic()
        with open(log, 'w') as out:
            proc = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, env=self.env)
            self.running = [proc]
            code = proc.wait()
            self.running = []
        text = log.read_text(errors='replace')
        if code != 0:
            print(f'demo: {title} failed (exit {code}); the end of {log}:', file=sys.stderr)
            print('\n'.join(text.splitlines()[-LOG_TAIL_LINES:]), file=sys.stderr, flush=True)
            return 130 if self.interrupted else 1
        print(f'demo: {title}: done in {time.monotonic() - t0:.0f} s (log {log})', flush=True)
        return 0


def identification_summary(identified: Path) -> dict:
    """What the report of pam-identify says it left at the prior, and the files."""
    report = (identified / 'report.txt').read_text()
    missing = report.split('NOT identified (prior values kept):', 1)
    left = [line.strip()[2:] for line in missing[1].splitlines()
            if line.strip().startswith('- ')] if len(missing) == 2 else []
    return {'directory': str(identified), 'complete': not left, 'not_identified': left}


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    exe = {}
    for name, package in EXECUTABLES.items():
        exe[name] = find_executable(name, package)
        if exe[name] is None:
            return error(f"executable '{name}' of {package} not found (run `make setup`); "
                         f"looked in: {'; '.join(executable_candidates(name, package))}")
    reason = check_scenario(args.scenario)
    if reason:
        return error(reason)
    paths = DemoPaths(args.out)
    try:
        paths.prepare()
    except (OSError, ValueError) as exc:
        return error(str(exc))
    env = dict(os.environ, ROS_DOMAIN_ID=demo_domain(args.domain_id), PYTHONUNBUFFERED='1')
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    steps = Steps(env)
    t0 = time.monotonic()
    print(f"demo: scenario '{args.scenario}', campaign '{args.campaign}'; "
          f"ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}; logs in {paths.logs}/", flush=True)
    code = steps.run(
        f"1/3 calibration campaign on the simulated '{args.scenario}' rig (pam-calibration-bags)",
        [exe['pam-calibration-bags'], str(paths.calibration), '--mismatch', args.scenario,
         '--seed', str(args.seed), *CAMPAIGNS[args.campaign]], paths.logs / 'calibration.log')
    if code:
        return code
    bags = sorted(str(p) for p in paths.calibration.iterdir() if p.is_dir())
    code = steps.run('2/3 identification (pam-identify --partial)',
                     [exe['pam-identify'], *bags, '-o', str(paths.identified), '--partial',
                      '--truth-mismatch', args.scenario], paths.logs / 'identify.log')
    if code:
        return code
    identification = identification_summary(paths.identified)
    try:
        params = write_run_params(paths, default_params_file(), args.scenario)
    except (OSError, ValueError) as exc:
        return error(str(exc))
    print(f"demo: identified model in {paths.identified}/ (report.txt)"
          + ('' if identification['complete'] else '; kept at the prior: '
             + '; '.join(identification['not_identified'])), flush=True)
    reports, code = track(args, exe, paths, params, env, steps)
    for run in RUNS:
        log = paths.logs / f'tracking_{run}.log'
        if log.is_file():
            print(f'\n=== {run} model ===', flush=True)
            print(log.read_text(errors='replace').rstrip('\n'), flush=True)
    print('\ndemo: nominal vs identified model on the simulated '
          f"'{args.scenario}' rig (errors against the true angle):", flush=True)
    for line in comparison_lines(reports):
        print('  ' + line, flush=True)
    write_json(paths.summary, demo_summary(args.scenario, args.campaign, reports, identification))
    print(f'demo: summary {paths.summary}, figure {paths.figure("identified")}; '
          f'{time.monotonic() - t0:.0f} s in all', flush=True)
    return code


def track(args, exe, paths: DemoPaths, params: dict, env: dict, steps: Steps):
    """Step 3: both stacks and both reports; ({run: summary dict}, exit code)."""
    print(f'demo: 3/3 real-time sensor-less tracking, nominal and identified model side by '
          f'side, {args.duration:g} s each ...', flush=True)
    stacks = [Child(f'bringup_{run}', [exe['pam-bringup'], '--namespace', f'/{run}',
                                      '--params-file', str(params[run]), '--log-dir',
                                      str(paths.logs / run)], f'the {run} stack')
              for run in RUNS]
    for run in RUNS:
        (paths.logs / run).mkdir(parents=True, exist_ok=True)
    supervisor = Supervisor(stacks, env, Output(PROG, [c.name for c in stacks], False,
                                                echo=False),
                            log_dir=paths.logs, sigterm_after=BRINGUP_SIGTERM_AFTER,
                            stop_timeout=BRINGUP_STOP_TIMEOUT)
    supervisor.start()
    reports, codes, logs = {}, {}, {}
    try:
        procs = {}
        for run in RUNS:
            logs[run] = open(paths.logs / f'tracking_{run}.log', 'w')  # noqa: SIM115
            procs[run] = subprocess.Popen(
                [exe['tracking_report'], '--ros-args', '-r', f'__ns:=/{run}',
                 '-p', f'duration:={args.duration:.1f}', '-p',
                 f'transient:={args.transient:.3f}', '-p', 'start:=step',
                 '-p', f'plot:={paths.figure(run)}', '-p',
                 f'summary:={paths.report_summary(run)}', '-p',
                 f'title:=Sensor-less PI tracking, {run} model, simulated {args.scenario} rig'],
                stdout=logs[run], stderr=subprocess.STDOUT, env=env)
        steps.running = list(procs.values())
        for run, proc in procs.items():
            codes[run] = proc.wait()
        steps.running = []
        dead = supervisor.dead()
    finally:
        for proc in steps.running:
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                proc.wait()
        for log in logs.values():
            log.close()
        supervisor.stop()
    for run in RUNS:
        path = paths.report_summary(run)
        if codes.get(run) == 0 and path.is_file():
            reports[run] = json.loads(path.read_text())
    if steps.interrupted:
        return reports, 130
    bad = [run for run in RUNS if codes.get(run) != 0]
    if bad:
        print(f"demo: tracking_report failed for {', '.join(bad)} "
              f"(exit {', '.join(str(codes.get(r)) for r in bad)})", file=sys.stderr, flush=True)
        return reports, 1
    if dead:
        for child in dead:
            print(f'demo: {child.name} stopped early; its log:', file=sys.stderr)
            print('\n'.join(list(child.tail)[-LOG_TAIL_LINES:]), file=sys.stderr, flush=True)
        return reports, 1
    return reports, 0


if __name__ == '__main__':
    sys.exit(main())
