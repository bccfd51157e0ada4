#!/usr/bin/env python3
"""The whole stack in real time, N joints: CPU, sample -> command latency at the rig, losses.

For each mode, in one run (so the figures compare on the same, possibly busy, machine):
  separate  every node its own process (pam-bringup's default: 4 processes per joint);
  composed  every node of every joint in one process (pam_container --namespace j1 .. jN), or
            the joints split over --containers K processes (e.g. one per core);
  linked    composed, with the in-process links (pam_container --links, pam_common.links): the
            1 kHz path between the nodes of one process as function calls.
N joints are N complete stacks (sim_node, ukf_node, reference_node, pi_node) in namespaces
/j1 .. /jN (/pam for one joint) with the parameters of pam_bringup/config/bringup.yaml, on a
ROS domain of their own. After --warmup s the rigs' latency statistics are reset
(~/reset_statistics) and the stacks run --duration s more; then the figures of that window:
  CPU       % of one core per process and in all (/proc utime + stime over the window);
  latency   at the rig (sim_node): each valve command's arrival minus the stamp of the sample it
            answers, p50 / p99 / p99.9 / max over every joint's commands (the worst joint's
            figure for p99.9 and max);
  late      commands that arrived after the rig had taken the next sample (% of all);
  lost      samples lost on their way (gaps in the sample counter, counted by ukf_node and
            pi_node), and the simulated rig's late samples (taken more than a period after
            their deadline: the loop was not real time);
  cost      CPU per sample (the process CPU over the window / the samples the rigs took) beside
            the models' own compute per sample, measured in this process in the same run
            (pam_bringup.model_cost: sim step + sample with the scenario's effects, UKF step
            with the stack's model and extensions, PI step), back to back and paced at 1 kHz in
            one thread (a sleep to each 1 ms deadline, as sim_node's sampler: a loop that wakes
            a thousand times a second pays for the wake-ups and runs with cold caches, a floor
            no stack of such a loop gets under; the wake-up alone is printed too): the ratios
            are the stack's overhead, machine-independent enough to compare across machines
            (the absolute CPU is not: 23 % on one machine of a kind, 81 % on another). The
            first is over the models back to back with one wake-up (of a bare sleep loop: 16-20
            us here, the same in C: benchmarks/wake_up.c), the least a 1 kHz loop of the models
            needs per sample; the second, over the models back to back alone, also counts the
            machine's wake-up as overhead; the third, over the models paced, compares like with
            like but its baseline moves 2-3 x from run to run on a shared VM;
--scenario NAME sets the simulated rig's scenario (default: bringup.yaml's), --identified DIR
ukf_node's model (params.yaml, kappa.csv, extensions.yaml of a pam-identify output directory).
--rig driver runs the driver path instead: per joint a pam-emulator (the DAQ board on a pty, its
plant simulated, on --scenario if given) and driver_node, armed once the loop runs; the latency
is then timed by driver_node (the host's end of the serial line), and the window's driver
watchdog trips (the safe output after 50 ms without a command) and board vents (the board's own
250 ms watchdog) are printed: a real rig's loop opened. --hog N starts N CPU-bound processes
(`while True: pass`) beside the stack first.
Modes separate+rt and composed+rt are the same with the real-time knobs on every node (-p
thread_priority:=--realtime, default 80; cpu_affinity:=--rt-cpus; lock_memory with
--rt-lock-memory; docs/realtime.md); with --hog and no --modes, composed+rt runs too, so the
figures with and without the knobs come from one run.
The only extra load is this script's /diagnostics subscription (about 1 Hz per node).

    .venv/bin/python benchmarks/stack_load.py [--joints 1] [--duration 20] [--hog 0] [--rig sim]
        [--modes composed linked] [--scenario realistic] [--identified out/demo/identified]
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fault_stack import campaign_domain
from pam_bringup.model_cost import measure_model_cost
from pam_bringup.stack import default_params_file, stack_nodes
from pam_common.diagnostics import status_node, status_values
from pam_common.executables import find_executable

READY_TIMEOUT = 90.0    # s: every joint's loop closed (N x 4 Python processes starting)
HOG = 'while True: pass'


def namespaces(joints: int) -> list[str]:
    return ['/pam'] if joints == 1 else [f'/j{k + 1}' for k in range(joints)]


def params_file(folder: Path, ports: dict[str, str], scenario: str | None = None,
                identified: Path | None = None) -> Path:
    """bringup.yaml with its /pam/<node> sections keyed /**/<node> (every namespace), and each
    namespace's driver_node port (`ports`: namespace -> serial port) in a section of its own;
    sim_node on `scenario` and ukf_node on the `identified` model if given."""
    data = yaml.safe_load(default_params_file().read_text())
    out = {('/**/' + key.rsplit('/', 1)[-1] if key.startswith('/pam/') else key): section
           for key, section in data.items()}
    out['/**/driver_node']['ros__parameters'].pop('port', None)
    if scenario:
        out['/**/sim_node']['ros__parameters']['scenario'] = scenario
    if identified is not None:
        from pam_estimator.calibration_runs import identified_ukf_parameters
        out['/**/ukf_node']['ros__parameters'].update(identified_ukf_parameters(identified))
    for ns, port in ports.items():
        out[f'{ns}/driver_node'] = {'ros__parameters': {'port': port}}
    path = folder / 'stack_load_params.yaml'
    path.write_text(yaml.safe_dump(out, sort_keys=False))
    return path


def exe(name: str, package: str) -> str:
    path = find_executable(name, package)
    if path is None:
        raise SystemExit(f'{name} ({package}) is not installed: run `make setup`')
    return path


def knob_args(mode: str, args) -> list[str]:
    """The ROS arguments of the real-time knobs for a '+rt' mode (none for the others)."""
    if not mode.endswith('+rt'):
        return []
    knobs = ['-p', f'thread_priority:={args.realtime}']
    if args.rt_cpus:
        knobs += ['-p', f"cpu_affinity:=[{', '.join(str(c) for c in args.rt_cpus)}]"]
    return knobs + (['-p', 'lock_memory:=true'] if args.rt_lock_memory else [])


def commands(mode: str, rig: str, spaces: list[str], params: Path,
             ports: dict[str, str], knobs: list[str] = (),
             containers: int = 1, scenario: str | None = None) -> list[tuple[str, list[str]]]:
    """(label, argv) of every process of the mode (its knobs: knob_args): the emulated boards
    first (driver path; their plant on `scenario` if given)."""
    ros = ['--ros-args', '--params-file', str(params), *knobs]
    mode = mode.removesuffix('+rt')
    links = ['--links'] if mode == 'linked' else []
    mode = 'composed' if mode == 'linked' else mode
    plant = ['--scenario', scenario] if scenario else []
    boards = [(f'{ns} pam-emulator', [exe('pam-emulator', 'pam_driver'), '--link', ports[ns],
                                      '--initial-command', '5.5', '5.5', *plant])
              for ns in spaces if rig == 'driver']
    if mode == 'composed':
        groups = [spaces[k::containers] for k in range(min(containers, len(spaces)))]
        return [*boards, *[(f"pam_container {' '.join(group)}",
                            [exe('pam_container', 'pam_bringup'), '--rig', rig, *links,
                             '--namespace',
                             *group, *ros]) for group in groups]]
    return [*boards, *[(f'{ns}/{spec.name}', [exe(spec.name, spec.package), *ros[:1], '-r',
                                              f'__ns:={ns}', *ros[1:]])
                       for ns in spaces for spec in stack_nodes(rig)]]


def cpu_seconds(pid: int) -> float:
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


class Diagnostics:
    """The latest /diagnostics status of each node (full name), with its receive time."""

    def __init__(self, node):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        self.latest: dict[str, tuple[float, dict]] = {}
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on,
                                 QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))

    def _on(self, msg) -> None:
        now = time.monotonic()
        for status in msg.status:
            self.latest[status_node(status.name)] = (now, status_values(status))

    def value(self, node: str, key: str) -> float:
        try:
            return float(self.latest[node][1][key])
        except (KeyError, ValueError):
            return math.nan

    def fresh(self, nodes: list[str], since: float) -> bool:
        return all(n in self.latest and self.latest[n][0] > since for n in nodes)


def spin_until(executor, predicate, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
        if predicate():
            return True
    return False


def counters(diag: Diagnostics, spaces: list[str]) -> dict[str, float]:
    lost = sum(diag.value(f'{ns}/{n}', 'samples lost') for ns in spaces
               for n in ('ukf_node', 'pi_node'))
    late = sum(diag.value(f'{ns}/sim_node', 'late samples') for ns in spaces)
    taken = sum(diag.value(f'{ns}/sim_node', 'samples taken') for ns in spaces)
    # the driver path: the driver's command watchdog (safe output) and the board's own (vent)
    driver = {key: sum(diag.value(f'{ns}/driver_node', key) for ns in spaces)
              for key in DRIVER_TRIPS}
    return {'lost': lost, 'late samples': late, 'samples': taken, **driver}


#: driver_node's counters of the loop opened on the real rig's path
DRIVER_TRIPS = ('watchdog trips', 'board vents', 'samples received')


def call(node, executor, service: str) -> None:
    """Call a std_srvs/Trigger service; SystemExit if it is missing, silent or refuses."""
    from std_srvs.srv import Trigger
    client = node.create_client(Trigger, service)
    if not client.wait_for_service(timeout_sec=10.0):
        raise SystemExit(f'{service}: no such service')
    future = client.call_async(Trigger.Request())
    if not spin_until(executor, future.done, 10.0):
        raise SystemExit(f'{service}: no answer')
    if not future.result().success:
        raise SystemExit(f'{service}: refused: {future.result().message}')
    node.destroy_client(client)


def run_mode(mode: str, rig: str, spaces: list[str], params: Path, ports: dict[str, str], args,
             node, executor, diag) -> dict:
    env = dict(os.environ)
    procs = [(label, subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.PIPE, text=True))
             for label, argv in commands(mode, rig, spaces, params, ports,
                                         knob_args(mode, args), args.containers,
                                         args.scenario)]
    try:
        rig_name = stack_nodes(rig)[0].name
        sims = [f'{ns}/{rig_name}' for ns in spaces]
        everyone = [f'{ns}/{spec.name}' for ns in spaces for spec in stack_nodes(rig)]

        def closed() -> bool:
            return all(diag.value(f'{ns}/pi_node', 'commands published') > 0 and
                       diag.value(f'{ns}/ukf_node', 'samples estimated') > 0 for ns in spaces)
        if not spin_until(executor, closed, READY_TIMEOUT):
            dead = [f'{label} (exit {p.poll()}): {p.stderr.read()[-400:]}'
                    for label, p in procs if p.poll() is not None]
            raise SystemExit(f'{mode}: the loops did not close within {READY_TIMEOUT:.0f} s; '
                             f'dead: {dead or "none"}')
        if rig == 'driver':       # a watchdog trip while the stack started latches it safe
            for sim in sims:
                call(node, executor, f'{sim}/arm')
        spin_until(executor, lambda: False, args.warmup)
        for sim in sims:
            call(node, executor, f'{sim}/reset_statistics')
        t0 = time.monotonic()
        if not spin_until(executor, lambda: diag.fresh(everyone, t0), 10.0):
            raise SystemExit(f'{mode}: no fresh /diagnostics of every node')
        before = counters(diag, spaces)
        cpu0 = {label: cpu_seconds(p.pid) for label, p in procs}
        w0 = time.monotonic()
        spin_until(executor, lambda: False, args.duration)
        cpu1 = {label: cpu_seconds(p.pid) for label, p in procs}
        w1 = time.monotonic()
        if not spin_until(executor, lambda: diag.fresh(everyone, w1), 10.0):
            raise SystemExit(f'{mode}: no fresh /diagnostics of every node at the end')
        after = counters(diag, spaces)
        dead = [label for label, p in procs if p.poll() is not None]
        if dead:
            raise SystemExit(f'{mode}: died during the run: {dead}')
        cpu = {label: 100.0 * (cpu1[label] - cpu0[label]) / (w1 - w0) for label in cpu0}

        def worst(key: str) -> float:
            return max(diag.value(s, key) for s in sims)

        if mode.endswith('+rt'):    # what the knobs came to (a refusal is a WARN status)
            for s in sims:
                print(f"  {mode} {s}: executor thread "
                      f"{diag.latest[s][1].get('executor thread', '?')}", flush=True)
        timed = sum(diag.value(s, 'commands timed') for s in sims)
        late = sum(diag.value(s, 'commands after the next sample') for s in sims)
        return {
            'mode': mode, 'processes': len(procs), 'cpu': cpu, 'cpu total': sum(cpu.values()),
            'p50': worst('latency p50 (ms)'), 'p99': worst('latency p99 (ms)'),
            'p99.9': worst('latency p99.9 (ms)'), 'max': worst('latency max (ms)'),
            'late %': 100.0 * late / timed if timed else math.nan, 'commands': timed,
            'lost': after['lost'] - before['lost'],
            'late samples': after['late samples'] - before['late samples'],
            **{key: after[key] - before[key] for key in DRIVER_TRIPS},
            'cpu per sample': (sum(cpu1.values()) - sum(cpu0.values()))
            / (after['samples'] - before['samples'])
            if after['samples'] > before['samples'] else math.nan}
    finally:
        for _, p in procs:
            if p.poll() is None:
                p.send_signal(2)
        for _, p in procs:
            try:
                p.wait(timeout=15.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def print_results(results: list[dict], joints: int, hogs: int, duration: float,
                  rig: str) -> None:
    print(f'\n{joints} joint(s) at 1 kHz ({rig} rig), {hogs} CPU-bound process(es) beside, '
          f'window {duration:g} s; latency at the rig (worst joint), CPU in % of one core')
    print(f"{'mode':<11} {'procs':>5} {'CPU %':>7} {'p50 ms':>7} {'p99 ms':>7} {'p99.9 ms':>8} "
          f"{'max ms':>7} {'late %':>7} {'lost':>5} {'late smp':>8} {'commands':>9}")
    for r in results:
        print(f"{r['mode']:<11} {r['processes']:>5} {r['cpu total']:>7.1f} {r['p50']:>7.3f} "
              f"{r['p99']:>7.3f} {r['p99.9']:>8.3f} {r['max']:>7.2f} {r['late %']:>7.2f} "
              f"{r['lost']:>5.0f} {r['late samples']:>8.0f} {r['commands']:>9.0f}")
    if rig == 'driver':
        for r in results:
            print(f"  {r['mode']}: driver_node {r['samples received']:.0f} samples received, "
                  f"command watchdog trips (safe output) {r['watchdog trips']:.0f}, board vents "
                  f"{r['board vents']:.0f}")
    for r in results:
        print(f"  {r['mode']} CPU per process: "
              + ', '.join(f'{label} {c:.1f}' for label, c in r['cpu'].items()))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--joints', type=int, default=1, help='stacks side by side (default 1)')
    parser.add_argument('--duration', type=float, default=20.0, help='measured window, s')
    parser.add_argument('--warmup', type=float, default=5.0,
                        help='s after the loops close before the window starts')
    parser.add_argument('--hog', type=int, default=0, metavar='N',
                        help='N CPU-bound processes beside the stack')
    parser.add_argument('--modes', nargs='+',
                        choices=['separate', 'composed', 'linked', 'separate+rt',
                                 'composed+rt', 'linked+rt'],
                        help='default: separate composed, and composed+rt with --hog')
    parser.add_argument('--containers', type=int, default=1, metavar='K',
                        help='composed modes: the joints split over K pam_container processes '
                             '(default 1)')
    parser.add_argument('--realtime', type=int, default=80, metavar='PRIORITY',
                        help='thread_priority of the +rt modes (SCHED_FIFO 1..99, default 80)')
    parser.add_argument('--rt-cpus', type=int, nargs='+', metavar='CPU',
                        help='cpu_affinity of the +rt modes (default: any CPU)')
    parser.add_argument('--rt-lock-memory', action='store_true',
                        help='lock_memory in the +rt modes')
    parser.add_argument('--rig', choices=['sim', 'driver'], default='sim',
                        help='sim: sim_node; driver: pam-emulator + driver_node (default sim)')
    parser.add_argument('--scenario', metavar='NAME',
                        help="the simulated rig's scenario (default: bringup.yaml's)")
    parser.add_argument('--identified', type=Path, metavar='DIR',
                        help="ukf_node's model: a pam-identify output directory (params.yaml, "
                             'kappa.csv, extensions.yaml; default: the nominal model)')
    args = parser.parse_args(argv)
    if args.joints < 1 or args.duration <= 0 or args.warmup < 0 or args.hog < 0 or \
            args.containers < 1:
        parser.error('--joints >= 1, --duration > 0, --warmup >= 0, --hog >= 0, '
                     '--containers >= 1')
    if not 1 <= args.realtime <= 99:
        parser.error('--realtime: a SCHED_FIFO priority, 1..99')
    if args.modes is None:
        args.modes = ['separate', 'composed'] + (['composed+rt'] if args.hog else [])
    domain = campaign_domain()
    spaces = namespaces(args.joints)
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    rclpy.init()
    node = rclpy.create_node('stack_load_probe')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    diag = Diagnostics(node)
    hogs = [subprocess.Popen([sys.executable, '-c', HOG]) for _ in range(args.hog)]
    print(f'ROS_DOMAIN_ID={domain}; joints {", ".join(spaces)}; hogs {args.hog}', flush=True)
    results = []
    try:
        with tempfile.TemporaryDirectory() as folder:
            ports = {ns: str(Path(folder) / f'daq{k}') for k, ns in enumerate(spaces)}
            params = params_file(Path(folder), ports, args.scenario, args.identified)
            for mode in args.modes:
                diag.latest.clear()
                results.append(run_mode(mode, args.rig, spaces, params, ports, args, node,
                                        executor, diag))
                print(f'{mode}: done', flush=True)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
        node.destroy_node()
        rclpy.try_shutdown()
    print_results(results, args.joints, args.hog, args.duration, args.rig)
    if args.rig == 'sim':
        cost = measure_model_cost(args.scenario, args.identified)
        print(f'\n{cost.line()}; measured now in this process')
        for r in results:
            per_sample = r['cpu per sample']
            print(f"  {r['mode']}: stack CPU per sample {per_sample * 1e6:.1f} us = "
                  f"{per_sample / cost.with_wake_up:.1f} x the models back to back with one "
                  f"wake-up ({cost.with_wake_up * 1e6:.1f} us); "
                  f"{per_sample / cost.back_to_back:.1f} x the models back to back alone, "
                  f"{per_sample / cost.paced:.1f} x the models paced at 1 kHz")
    return 0


if __name__ == '__main__':
    sys.exit(main())
