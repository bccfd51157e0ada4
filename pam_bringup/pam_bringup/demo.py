"""pam-demo: the main job (`make demo`): the workflow a lab follows, on the simulated rig.

1. The calibration campaign on the simulated rig of --scenario (default 'realistic': the 'mild'
   parameter mismatch plus the unmodelled effects of a real rig: valve lag, dead volume, supply
   droop and ripple, force hysteresis, temperature drift, sensor offsets): pam-calibration-bags
   writes the locked and free runs as bags (batch simulator; --campaign full|quick) into
   OUT/demo/calibration.
2. pam-identify fits the model to them (partial: what the runs cannot identify keeps its prior
   value and the report says so) into OUT/demo/identified (params.yaml, kappa.csv,
   extensions.yaml, report.txt).
3. The nominal-vs-identified comparison on the batch closed loop with the plant's effects
   (pam_controller.closed_loop.simulate_closed_loop_with_effects; demo_workflow.batch_comparison):
   the scenario's plant stepped sample by sample, read through its sensor, the UKF (nominal
   model; identified model + extensions) and pi_node's gains from the parameter file, the
   paper-style angle steps (--seed, --duration s); per model the worst steady-state error
   against the TRUE angle, the worst settling and every step. Deterministic: it does not depend
   on the machine's load.
4. ONE real-time sensor-less run with the identified model: pam-bringup (composed) in
   /identified runs the simulated rig (sim_node at 1 kHz on the scenario), ukf_node, pi_node and
   reference_node (paper-style steps within +-20 deg, 8 s each); tracking_report records
   --duration seconds from the first step, reports per step the steady-state error against the
   TRUE angle, the settling time, the estimation error I / M / Q, and the run's real-time health
   from the rig's /diagnostics (pam_common.run_health). A run that was not real time is INVALID:
   its figures are printed as NOT results, and pam-demo exits 1.
The figure OUT/demo_tracking.png (the real-time run) and OUT/demo_summary.json ('comparison':
the batch figures; 'realtime': the real-time run's with its 'health'; 'valid').

OUT/demo is replaced by the next pam-demo (it carries a marker; a directory without it is never
removed). Node logs go to OUT/logs/. The ROS domain is --domain-id, else ROS_DOMAIN_ID, else a
random one in 110..199; discovery stays on this machine unless ROS_AUTOMATIC_DISCOVERY_RANGE says
otherwise.

Exit code: 0 done (the real-time run was real time); 1 a step failed (its output is printed), the
stack stopped early, or the real-time run was INVALID (not real time on this machine: the summary
is still written, with 'valid': false); 2 a usage or set-up error; 130 interrupted (Ctrl-C: the
tracking report prints what it recorded). SIGTERM / SIGHUP are passed on to the running step as
SIGINT.
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

import yaml

from pam_common.executables import executable_candidates, find_executable
from pam_common.timer_floor import measure_timer_floor

from .demo_workflow import (
    CAMPAIGNS,
    REALTIME_PRIORITY,
    REALTIME_RUN,
    DemoPaths,
    batch_comparison,
    comparison_lines,
    demo_models,
    demo_summary,
    loop_settings,
    write_run_params,
)
from .json_file import write_json
from .model_cost import measure_model_cost
from .stack import PACKAGE, default_params_file
from .supervisor import Child, Output, Supervisor

PROG = 'pam-demo'
DEFAULT_DURATION = 64.0      # s: the reference profile's 8 steps of 8 s
DEFAULT_SCENARIO = 'realistic'
DEMO_DOMAINS = (110, 199)    # the random ROS_DOMAIN_ID's range (inclusive)
LOG_TAIL_LINES = 30          # of a stack's log, when it stopped early
MODEL_COST_DEADLINES = 2000  # 1 ms deadlines of each paced timing (bare loop, models: 4 s)
BRINGUP_SIGTERM_AFTER = 20.0   # s after our SIGINT: more than pam-bringup's own stop (<= 16 s)
BRINGUP_STOP_TIMEOUT = 30.0    # s after our SIGINT: SIGKILL
#: the executables of each step, by package
EXECUTABLES = {'pam-calibration-bags': 'pam_estimator', 'pam-identify': 'pam_estimator',
               'pam-bringup': PACKAGE, 'tracking_report': PACKAGE}


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='The main job, the workflow a lab follows on the simulated rig: 1. the '
                    'calibration campaign (pam-calibration-bags), 2. pam-identify, 3. the '
                    'nominal-vs-identified comparison on the batch closed loop with the '
                    "plant's effects (deterministic, independent of the machine's load), 4. ONE "
                    'real-time sensor-less angle tracking run with the identified model '
                    '(pam-bringup + tracking_report in /identified), judged for its real-time '
                    'health; prints per step, writes OUT/demo_tracking.png (the real-time run) '
                    'and OUT/demo_summary.json.',
        epilog='Exit codes: 0 done, 1 a step failed, the stack stopped early or the real-time '
               'run was INVALID (not real time on this machine; its figures are not results), '
               '2 usage or set-up error, 130 interrupted. `make demo` runs it (DURATION=30 '
               'make demo: --duration 30).')
    parser.add_argument('--scenario', default=DEFAULT_SCENARIO, metavar='NAME|FILE',
                        help="the simulated rig's mismatch scenario: 'mild', 'strong', "
                             "'realistic', 'harsh', 'other_forms' or a scenario YAML (default "
                             f'{DEFAULT_SCENARIO})')
    parser.add_argument('--campaign', choices=sorted(CAMPAIGNS), default='full',
                        help="the calibration campaign: 'full' (3 lock angles, 10 s holds, 60 s "
                             "free run) or 'quick' (2 angles, 5 voltages, 30 s free run) "
                             '(default full)')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the campaign (profiles, sensor noise) and of the batch '
                             "comparison's reference steps and noise (default 0)")
    parser.add_argument('--duration', type=float, default=DEFAULT_DURATION, metavar='SECONDS',
                        help='how long the batch comparison simulates and the real-time run '
                             f'records (default {DEFAULT_DURATION:g})')
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
        f"1/4 calibration campaign on the simulated '{args.scenario}' rig (pam-calibration-bags)",
        [exe['pam-calibration-bags'], str(paths.calibration), '--scenario', args.scenario,
         '--seed', str(args.seed), *CAMPAIGNS[args.campaign]], paths.logs / 'calibration.log')
    if code:
        return code
    bags = sorted(str(p) for p in paths.calibration.iterdir() if p.is_dir())
    code = steps.run('2/4 identification (pam-identify --partial)',
                     [exe['pam-identify'], *bags, '-o', str(paths.identified), '--partial',
                      '--truth-scenario', args.scenario], paths.logs / 'identify.log')
    if code:
        return code
    identification = identification_summary(paths.identified)
    try:
        base = yaml.safe_load(default_params_file().read_text())
        settings = loop_settings(base)
        params = write_run_params(paths, default_params_file(), args.scenario)
    except (OSError, ValueError) as exc:
        return error(str(exc))
    print(f"demo: identified model in {paths.identified}/ (report.txt)"
          + ('' if identification['complete'] else '; kept at the prior: '
             + '; '.join(identification['not_identified'])), flush=True)

    print(f'demo: 3/4 batch comparison, nominal vs identified model, on the batch closed loop '
          f"with the '{args.scenario}' plant's effects ({args.duration:g} s of angle steps, "
          f"PI gains {settings['gains'][0]:g}, {settings['gains'][1]:g}) ...", flush=True)
    t3 = time.monotonic()
    comparison = batch_comparison(args.scenario, demo_models(paths.identified), settings,
                                  args.duration, args.seed)
    print(f'demo: 3/4 batch comparison: done in {time.monotonic() - t3:.0f} s; errors against '
          'the true angle:', flush=True)
    for line in comparison_lines(comparison):
        print('  ' + line, flush=True)
    if steps.interrupted:
        return 130

    # the machine's own timer, at the run's priority, just before it: the baseline its late
    # samples are read against (a bare sleep loop is already late now and then on a VM)
    floor = measure_timer_floor(priority=REALTIME_PRIORITY)
    print(f'demo: this machine now: {floor.line()}', flush=True)
    # and what the stack's own models cost here: a run on another machine reads against it
    cost = measure_model_cost(args.scenario, paths.identified, paced=MODEL_COST_DEADLINES)
    print(f'demo: this machine now: {cost.line()}', flush=True)
    realtime, code = track(args, exe, paths, params, env, steps)
    log = paths.logs / f'tracking_{REALTIME_RUN}.log'
    if log.is_file():
        print(f'\n=== real-time run, {REALTIME_RUN} model ===', flush=True)
        print(log.read_text(errors='replace').rstrip('\n'), flush=True)
    health = (realtime or {}).get('health') or {}
    valid = code == 0 and bool(realtime) and realtime.get('valid') is True
    write_json(paths.summary, demo_summary(args.scenario, args.campaign, identification,
                                           comparison, realtime, valid, floor.as_dict(),
                                           cost.as_dict()))
    if realtime is not None and realtime.get('valid') is False:
        print('demo: INVALID: the real-time run was not real time on this machine ('
              + '; '.join(health.get('reasons') or ['no reason given'])
              + '); its figures are not results', file=sys.stderr, flush=True)
        code = code or 1
    print(f'demo: summary {paths.summary}, figure {paths.figure(REALTIME_RUN)}; '
          f'{time.monotonic() - t0:.0f} s in all', flush=True)
    return code


def track(args, exe, paths: DemoPaths, params: dict, env: dict, steps: Steps):
    """Step 4: the identified stack and its report; (its summary dict or None, exit code). The
    report's exit 1 with a summary whose 'valid' is false is an INVALID run (not real time): the
    summary is returned, the exit code is 1."""
    run = REALTIME_RUN
    print(f'demo: 4/4 real-time sensor-less tracking with the {run} model, '
          f'{args.duration:g} s ...', flush=True)
    (paths.logs / run).mkdir(parents=True, exist_ok=True)
    # composed with in-process links (pam_common.links): rig -> UKF -> PI -> command as calls
    # in the rig's sampling thread; measured here closer to real time than the rig apart
    # (--rig-apart: two processes, but a DDS round trip and two interpreters per sample)
    stack = Child(f'bringup_{run}', [exe['pam-bringup'], '--links',
                                     '--namespace', f'/{run}',
                                     '--params-file', str(params[run]), '--log-dir',
                                     str(paths.logs / run)], f'the {run} stack')
    supervisor = Supervisor([stack], env, Output(PROG, [stack.name], False, echo=False),
                            log_dir=paths.logs, sigterm_after=BRINGUP_SIGTERM_AFTER,
                            stop_timeout=BRINGUP_STOP_TIMEOUT)
    supervisor.start()
    code = None
    try:
        with open(paths.logs / f'tracking_{run}.log', 'w') as log:
            proc = subprocess.Popen(
                [exe['tracking_report'], '--ros-args', '-r', f'__ns:=/{run}',
                 '-p', f'duration:={args.duration:.1f}', '-p',
                 f'transient:={args.transient:.3f}', '-p', 'start:=step', '-p', 'rig:=sim_node',
                 '-p', f'plot:={paths.figure(run)}', '-p',
                 f'summary:={paths.report_summary(run)}', '-p',
                 f'title:=Sensor-less PI tracking, {run} model, simulated {args.scenario} rig'],
                stdout=log, stderr=subprocess.STDOUT, env=env)
            steps.running = [proc]
            try:
                code = proc.wait()
            finally:
                steps.running = []
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)
                    proc.wait()
        dead = supervisor.dead()
    finally:
        supervisor.stop()
    path = paths.report_summary(run)
    report = json.loads(path.read_text()) if code in (0, 1) and path.is_file() else None
    if steps.interrupted:
        return report, 130
    if code != 0 and not (report is not None and report.get('valid') is False):
        print(f'demo: tracking_report failed for the {run} run (exit {code})', file=sys.stderr,
              flush=True)
        return report, 1
    if dead:
        for child in dead:
            print(f'demo: {child.name} stopped early; its log:', file=sys.stderr)
            print('\n'.join(list(child.tail)[-LOG_TAIL_LINES:]), file=sys.stderr, flush=True)
        return report, 1
    return report, code


if __name__ == '__main__':
    sys.exit(main())
