"""pam-bringup: the whole PAM stack as separate processes, from one parameter file.

A small stand-in for `ros2 launch` (not installable with the pinned PyPI wheels): starts the rig
(sim_node, or driver_node with --rig driver), the estimator (ukf_node), the controller (pi_node)
and the reference generator (reference_node), each in a process group of its own, with

    <exe> --ros-args -r __ns:=<namespace> --params-file <file>

(the same standard ROS 2 params file for every node: one section per node, keyed by the node's
full name, e.g. `/pam/sim_node:`; `/**:` applies to every node). Each child's stdout and stderr
are merged into one pipe; a reader thread per child prefixes every line with `[node_name]` and
forwards it to our stdout (and, with --log-dir, writes the raw line to DIR/<node>.log).

Stopping: on SIGINT / SIGTERM / SIGHUP (Ctrl-C) or at the end of --duration every child gets
SIGINT (to its process group); children still running SIGTERM_AFTER later get SIGTERM (as ros2
launch does: a node may miss a SIGINT that arrives while it is still importing), and SIGKILL after
STOP_TIMEOUT, just after SIGUSR1 (a PAM node prints its threads' stacks into the log: where it
hung; pam_common.stack_dump). A second Ctrl-C kills at once. If pam-bringup itself is killed, the
children get SIGTERM (Linux parent-death signal).

Exit code: 0 after a requested stop when every child exited cleanly (0, or ended by our SIGINT /
SIGTERM; never after a SIGKILL); 1 when a child died while running (which one, and its exit code,
is logged; the others are then stopped) or did not stop cleanly; 2 on a usage or set-up error
(missing executable; a params file missing, unreadable or malformed: one line naming the file
and the line, the check every node makes), before anything is started.

No busy loops: the main thread sleeps in select() on a self-pipe that signal.set_wakeup_fd and
the per-child waiter threads write to.

Arming the driver (--rig driver with pi_node, unless --no-arm): driver_node latches its safe
output when the controller's start-up stalls longer than its command watchdog (or when it starts
with arm_at_start false). Once pi_node's valve_command has flowed steadily for ARM_STEADY s,
pam-bringup calls <namespace>/driver_node/arm (std_srvs/Trigger) from an rclpy node of its own
(thread DriverArmer), retrying a refusal (board not connected yet, sensor fault) every
ARM_RETRY s for up to ARM_TIMEOUT s. It arms once, at start-up only: a later watchdog trip or
e-stop stays latched until someone calls ~/arm.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import select
import shlex
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from pam_common.executables import executable_candidates, find_executable
from pam_common.params_files import check_params_file, ros_args_problem
from pam_common.stack_dump import STACK_DUMP_SIGNAL

PROG = 'pam-bringup'
PACKAGE = 'pam_bringup'
DEFAULT_NAMESPACE = '/pam'
SIGTERM_AFTER = 5.0      # s, SIGINT -> SIGTERM (as ros2 launch)
STOP_TIMEOUT = 10.0      # s, SIGINT -> SIGKILL
KILL_TIMEOUT = 5.0       # s, SIGKILL -> reaped
STACK_DUMP_WAIT = 1.0    # s for a hung node's stacks to reach the log before SIGKILL
READER_JOIN = 2.0        # s, last output of a child after it exited
# Exit codes of a child that count as a clean stop after we asked it to stop: rclpy nodes return 0
# on Ctrl-C / SIGTERM; one stopped while still importing exits 130 / 143 (pam_model.cli.startup);
# a process ended by the signal itself gives -2 / -15. A SIGKILL is never clean.
CLEAN_STOP_CODES = {0, -signal.SIGINT, 128 + signal.SIGINT, -signal.SIGTERM,
                    128 + signal.SIGTERM}
COLOURS = ('36', '33', '35', '32', '34', '96', '93')   # ANSI: cyan, yellow, magenta, ...
RIGS = {'sim': ('sim_node', 'pam_driver'), 'driver': ('driver_node', 'pam_driver')}
ARM_STEADY = 1.0         # s of valve_command without a gap > ARM_GAP before ~/arm
ARM_GAP = 0.2            # s
ARM_RETRY = 1.0          # s between ~/arm calls the driver refused
ARM_TIMEOUT = 60.0       # s after start: give up arming (say so)


@dataclass(frozen=True)
class NodeSpec:
    """One node of the stack: its name (= executable name = log prefix) and package."""

    name: str
    package: str
    role: str


def stack(args) -> list[NodeSpec]:
    """The nodes to start, in start order, for the parsed options."""
    rig_name, rig_package = RIGS[args.rig]
    nodes = [NodeSpec(rig_name, rig_package, f'rig ({args.rig})'),
             NodeSpec('ukf_node', 'pam_estimator', 'estimator')]
    if not args.no_reference:
        nodes.append(NodeSpec('reference_node', 'pam_controller', 'reference'))
    if not args.no_controller:
        nodes.append(NodeSpec('pi_node', 'pam_controller', 'controller'))
    # The bag recorder joins here once it exists (its own option to switch it off).
    return nodes


# ---------------------------------------------------------------------------- look-ups
def default_params_file() -> Path:
    """share/pam_bringup/config/bringup.yaml of the install, else of this source tree."""
    try:
        from ament_index_python.packages import get_package_share_directory
        installed = Path(get_package_share_directory(PACKAGE)) / 'config' / 'bringup.yaml'
        if installed.is_file():
            return installed
    except Exception:  # noqa: BLE001 - not installed: fall back to the source tree
        pass
    return Path(__file__).resolve().parent.parent / 'config' / 'bringup.yaml'


def _key_pattern(key: str) -> re.Pattern:
    """rcl's node-name matching of a params-file key: a leading '/' is implied, '*' is one
    name token, '**' any number of them (including none)."""
    tokens = key.strip('/').split('/') if key.strip('/') else []
    regex = ''
    for token in tokens:
        if token == '**':
            regex += '(?:/[^/]+)*'
        else:
            regex += '/' + ''.join('[^/]*' if c == '*' else re.escape(c) for c in token)
    return re.compile(f'^{regex}$')


def section_keys(path: Path) -> list[str]:
    """The node sections of a params file (nested keys joined with '/'); raises ValueError
    (ParamsFileError: one line, with the line number where there is one)."""
    return check_params_file(path)


def sections_for(node_fqn: str, keys: list[str]) -> list[str]:
    return [k for k in keys if _key_pattern(k).match(node_fqn)]


# ---------------------------------------------------------------------------- output
class Output:
    """Our stdout, shared by the reader threads and the main thread (one line at a time)."""

    def __init__(self, names: list[str], colour: bool):
        self._lock = threading.Lock()
        self._broken = False
        self.width = max(len(n) for n in names) + 2
        self._colours = {n: COLOURS[i % len(COLOURS)] for i, n in enumerate(names)}
        self._colour = colour

    def prefix(self, name: str) -> str:
        text = f'[{name}]'.ljust(self.width)
        if self._colour:
            return f'\033[{self._colours.get(name, "1")}m{text}\033[0m'
        return text

    def line(self, name: str, text: str) -> None:
        data = f'{self.prefix(name)} {text}\n'
        with self._lock:
            if self._broken:
                return
            try:
                sys.stdout.write(data)
                sys.stdout.flush()
            except (BrokenPipeError, ValueError, OSError):
                self._broken = True   # keep draining the children; stop writing
                try:   # and no BrokenPipeError again when Python flushes stdout at exit
                    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                except (OSError, ValueError):
                    pass

    def say(self, text: str) -> None:
        self.line(PROG, text)


# ---------------------------------------------------------------------------- children
@dataclass
class Child:
    spec: NodeSpec
    argv: list[str]
    proc: subprocess.Popen | None = None
    exited: threading.Event = field(default_factory=threading.Event)
    threads: list = field(default_factory=list)
    log: object = None
    killed: bool = False

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def code(self) -> int | None:
        return self.proc.returncode if self.exited.is_set() else None


def describe_code(code: int) -> str:
    if code < 0:
        try:
            return f'killed by {signal.Signals(-code).name}'
        except ValueError:
            return f'killed by signal {-code}'
    return f'exit code {code}'


def _child_setup():
    """In the child, before exec: a process group of its own (Ctrl-C in the terminal reaches
    only pam-bringup, which forwards it), and SIGTERM when pam-bringup dies (Linux)."""
    os.setpgid(0, 0)
    if _PRCTL is not None:
        _PRCTL(1, signal.SIGTERM)   # PR_SET_PDEATHSIG


def _load_prctl():
    try:
        import ctypes
        return ctypes.CDLL(None, use_errno=True).prctl
    except Exception:  # noqa: BLE001 - not Linux: no parent-death signal
        return None


_PRCTL = _load_prctl() if sys.platform.startswith('linux') else None


class Bringup:
    def __init__(self, children: list[Child], env: dict, output: Output, log_dir: Path | None):
        self.children = children
        self.env = env
        self.out = output
        self.log_dir = log_dir
        self.signals: list[int] = []
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)

    # -- waking the main thread (signal-safe: a byte on a pipe)
    def _wake(self) -> None:
        try:
            os.write(self._wake_w, b'.')
        except BlockingIOError:
            pass   # the pipe is full: the main thread has plenty to wake up for

    def _sleep(self, timeout: float | None) -> None:
        if timeout is not None and timeout <= 0:
            return
        try:
            select.select([self._wake_r], [], [], timeout)
        except InterruptedError:
            pass
        try:
            while os.read(self._wake_r, 4096):
                pass
        except BlockingIOError:
            pass

    def _on_signal(self, signum, frame) -> None:   # noqa: ARG002
        self.signals.append(signum)   # the main thread acts on it (set_wakeup_fd wakes it)

    def install_signal_handlers(self) -> None:
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, self._on_signal)
        signal.set_wakeup_fd(self._wake_w, warn_on_full_buffer=False)

    # -- starting
    def start(self) -> None:
        """Start every child, then their reader and waiter threads (no fork while threads of
        ours run, so preexec_fn is safe). On an error (raised), the children that did start are
        watched as usual: stop() then stops them."""
        try:
            for child in self.children:
                if self.log_dir is not None:
                    child.log = open(self.log_dir / f'{child.name}.log', 'w',  # noqa: SIM115
                                     encoding='utf-8', errors='replace')
                child.proc = subprocess.Popen(
                    child.argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT, env=self.env, preexec_fn=_child_setup,
                    close_fds=True)
                self.out.say(f'started {child.name} ({child.spec.role}), pid '
                             f'{child.proc.pid}: {shlex.join(child.argv)}')
        finally:
            for child in self.children:
                if child.proc is None and child.log is not None:
                    child.log.close()
            self.children = [c for c in self.children if c.proc is not None]
            for child in self.children:
                reader = threading.Thread(target=self._read, args=(child,),
                                          name=f'{child.name}-reader', daemon=True)
                waiter = threading.Thread(target=self._wait, args=(child,),
                                          name=f'{child.name}-waiter', daemon=True)
                child.threads = [reader, waiter]
                reader.start()
                waiter.start()

    def _read(self, child: Child) -> None:
        for raw in iter(child.proc.stdout.readline, b''):
            text = raw.decode('utf-8', errors='replace').rstrip('\r\n')
            self.out.line(child.name, text)
            if child.log is not None:
                try:
                    child.log.write(text + '\n')
                    child.log.flush()
                except (OSError, ValueError):
                    pass
        child.proc.stdout.close()

    def _wait(self, child: Child) -> None:
        child.proc.wait()
        child.exited.set()
        self._wake()

    # -- running and stopping
    def alive(self) -> list[Child]:
        return [c for c in self.children if not c.exited.is_set()]

    def run(self, duration: float | None) -> int:
        """Wait for a signal, the end of duration or a dead child; stop all; the exit code."""
        deadline = None if duration is None else time.monotonic() + duration
        dead: list[Child] = []
        while True:
            if self.signals:
                names = ', '.join(signal.Signals(s).name for s in self.signals)
                self.out.say(f'{names} received: stopping every node')
                break
            dead = [c for c in self.children if c.exited.is_set()]
            if dead:
                for child in dead:
                    self.out.say(f'{child.name} (pid {child.proc.pid}) died: '
                                 f'{describe_code(child.code)}; stopping the other nodes')
                break
            if deadline is not None and time.monotonic() >= deadline:
                self.out.say(f'--duration {duration:g} s elapsed: stopping every node')
                break
            self._sleep(None if deadline is None else deadline - time.monotonic())
        self.stop()
        return self.report(dead)

    def _signal_group(self, child: Child, sig: int) -> None:
        if child.exited.is_set():
            return
        try:
            os.killpg(child.proc.pid, sig)
        except ProcessLookupError:
            pass
        except PermissionError:
            child.proc.send_signal(sig)

    def _dump_stacks(self) -> None:
        """STACK_DUMP_SIGNAL to every child still running: a PAM node prints every thread's
        stack (pam_common.stack_dump), which its reader forwards; wait up to
        STACK_DUMP_WAIT for it. Where a hung node hangs is then in the log."""
        for child in self.alive():
            self._signal_group(child, STACK_DUMP_SIGNAL)
        end = time.monotonic() + STACK_DUMP_WAIT
        while self.alive() and time.monotonic() < end:
            self._sleep(0.05)

    def stop(self) -> None:
        """SIGINT to every child; SIGTERM after SIGTERM_AFTER (a node that missed the SIGINT,
        e.g. while still importing); SIGKILL after STOP_TIMEOUT or on a second stop request."""
        handled = len(self.signals)
        for child in self.alive():
            self._signal_group(child, signal.SIGINT)
        start = time.monotonic()
        term_at, end = start + SIGTERM_AFTER, start + STOP_TIMEOUT
        termed = False
        while self.alive():
            now = time.monotonic()
            if len(self.signals) > handled:
                self.out.say('second stop request: killing the remaining nodes')
                break
            if now >= end:
                self.out.say(f'still running {STOP_TIMEOUT:g} s after SIGINT: '
                             + ', '.join(c.name for c in self.alive())
                             + ': printing their threads\' stacks (SIGUSR1), then killing')
                self._dump_stacks()
                break
            if not termed and now >= term_at:
                termed = True
                self.out.say(f'still running {SIGTERM_AFTER:g} s after SIGINT: '
                             + ', '.join(c.name for c in self.alive()) + ': sending SIGTERM')
                for child in self.alive():
                    self._signal_group(child, signal.SIGTERM)
            self._sleep((end if termed else term_at) - now)
        for child in self.alive():
            child.killed = True
            self._signal_group(child, signal.SIGKILL)
        end = time.monotonic() + KILL_TIMEOUT
        for child in self.children:
            child.exited.wait(max(0.0, end - time.monotonic()))
        for child in self.children:
            for thread in child.threads:
                thread.join(READER_JOIN)
            if child.log is not None:
                child.log.close()

    def report(self, dead: list[Child]) -> int:
        """Exit code: 1 if a child died or did not stop cleanly, else 0."""
        codes = ', '.join(f'{c.name} {describe_code(c.code)}' if c.code is not None
                          else f'{c.name} still running' for c in self.children)
        unclean = [c for c in self.children
                   if c not in dead and (c.code not in CLEAN_STOP_CODES or c.killed)]
        if dead:
            self.out.say(f'failed: {", ".join(c.name for c in dead)} died ({codes})')
            return 1
        if unclean:
            self.out.say(f'failed: {", ".join(c.name for c in unclean)} did not stop cleanly '
                         f'({codes})')
            return 1
        self.out.say(f'all nodes stopped cleanly ({codes})')
        return 0


# ---------------------------------------------------------------------------- arming
class DriverArmer:
    """Calls <namespace>/driver_node/arm once the controller runs (see the module docstring), in
    a thread with an rclpy context of its own (no signal handlers: pam-bringup keeps its own)."""

    def __init__(self, namespace: str, domain_id: int | None, output: Output):
        self.namespace = namespace
        self.domain_id = domain_id
        self.out = output
        self.armed = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='driver-armer', daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(READER_JOIN)

    def _run(self) -> None:
        try:
            import rclpy
            from rclpy.context import Context
            from rclpy.executors import SingleThreadedExecutor
            from rclpy.signals import SignalHandlerOptions
            context = Context()
            rclpy.init(context=context, domain_id=self.domain_id,
                       signal_handler_options=SignalHandlerOptions.NO)
        except Exception as exc:  # noqa: BLE001 - pam-bringup runs on without it
            self.out.say(f'cannot arm driver_node (rclpy: {exc}): call ~/arm yourself')
            return
        try:
            node = rclpy.create_node('_pam_bringup_armer', namespace=self.namespace,
                                     context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            self._arm(node, executor)
        except Exception as exc:  # noqa: BLE001
            if not self._stop.is_set():
                self.out.say(f'arming driver_node failed ({type(exc).__name__}: {exc}): call '
                             '~/arm yourself')
        finally:
            context.try_shutdown()

    def _arm(self, node, executor) -> None:
        from pam_interfaces.msg import ValveCommand
        from std_srvs.srv import Trigger
        steady = {'since': None, 'last': -math.inf}

        def on_command(_msg) -> None:
            now = time.monotonic()
            if now - steady['last'] > ARM_GAP:
                steady['since'] = now
            steady['last'] = now

        node.create_subscription(ValveCommand, 'valve_command', on_command, 10)
        client = node.create_client(Trigger, 'driver_node/arm')
        service = f'{node.get_namespace().rstrip("/")}/driver_node/arm'
        deadline = time.monotonic() + ARM_TIMEOUT
        future, next_call, refused = None, 0.0, ''
        while not self._stop.is_set():
            executor.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            if future is not None and future.done():
                response = future.result()
                future = None
                if response is not None and response.success:
                    self.armed = True
                    self.out.say(f'the controller runs: {service}: {response.message}')
                    return
                message = response.message if response is not None else 'no response'
                if message != refused:
                    self.out.say(f'{service} refused: {message}; retrying every '
                                 f'{ARM_RETRY:g} s for up to {ARM_TIMEOUT:g} s')
                refused = message
                next_call = now + ARM_RETRY
            if now >= deadline:
                self.out.say(f'driver_node not armed {ARM_TIMEOUT:g} s after the start'
                             f'{f" ({refused})" if refused else ""}: call {service} yourself')
                return
            running = (steady['since'] is not None and now - steady['last'] <= ARM_GAP
                       and now - steady['since'] >= ARM_STEADY)
            if future is None and running and now >= next_call and client.service_is_ready():
                future = client.call_async(Trigger.Request())


# ---------------------------------------------------------------------------- command line
def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Start the PAM stack (rig, ukf_node, pi_node, reference_node) as separate '
                    'processes from one ROS 2 params file; prefix and forward their logs; stop '
                    'them all on Ctrl-C / SIGTERM; exit non-zero when any of them dies.',
        epilog='The params file is a standard ROS 2 one, passed to every node with '
               '`--ros-args --params-file FILE`: one section per node keyed by its full name '
               '(/pam/sim_node:, /pam/ukf_node:, /pam/pi_node:, /pam/reference_node:; '
               '/**/NAME: for any namespace; /**: for every node). A bare `sim_node:` key '
               'means /sim_node and does NOT apply under /pam. Exit codes: 0 requested stop '
               'with every node exiting cleanly, 1 a node died or did not stop cleanly, 2 usage '
               'or set-up error. Example: pam-bringup --no-controller --no-reference '
               '--duration 30 --domain-id 42 --log-dir out/logs')
    parser.add_argument('--params-file', metavar='FILE', type=Path,
                        help='ROS 2 params YAML with a section per node (default: '
                             'share/pam_bringup/config/bringup.yaml)')
    parser.add_argument('--rig', choices=sorted(RIGS), default='sim',
                        help="'sim': the simulated rig sim_node (default); 'driver': the "
                             "hardware driver driver_node (pam_driver)")
    parser.add_argument('--no-controller', action='store_true',
                        help='do not start pi_node')
    parser.add_argument('--no-reference', action='store_true',
                        help='do not start reference_node')
    parser.add_argument('--no-arm', action='store_true',
                        help='with --rig driver: do not call driver_node ~/arm once the '
                             'controller runs (default: arm it once, at start-up)')
    parser.add_argument('--duration', type=float, metavar='SECONDS',
                        help='stop everything after this long (exit 0 if every node was alive '
                             'and stopped cleanly); default: run until Ctrl-C / SIGTERM')
    parser.add_argument('--domain-id', type=int, metavar='N',
                        help='ROS_DOMAIN_ID of the nodes (default: inherited)')
    parser.add_argument('--namespace', default=DEFAULT_NAMESPACE, metavar='NS',
                        help=f'namespace of every node, -r __ns:=NS (default {DEFAULT_NAMESPACE})')
    parser.add_argument('--log-dir', type=Path, metavar='DIR',
                        help="also write each node's raw output to DIR/<node>.log")
    parser.add_argument('--no-colour', '--no-color', dest='colour', action='store_false',
                        help='no coloured prefixes (default: coloured when stdout is a terminal '
                             'and NO_COLOR is unset)')
    args = parser.parse_args(argv)
    if args.duration is not None and not args.duration > 0:
        parser.error(f'--duration must be > 0 s, got {args.duration:g}')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        parser.error(f'--domain-id must be in 0..232, got {args.domain_id}')
    ns = args.namespace.strip()
    if not ns.startswith('/'):
        ns = '/' + ns
    if ns != '/':
        ns = ns.rstrip('/')
    if not re.fullmatch(r'/|(/[A-Za-z_][A-Za-z0-9_]*)+', ns):
        parser.error(f'--namespace {args.namespace!r} is not a valid ROS namespace')
    args.namespace = ns
    return args


def child_environment(args, colour: bool) -> dict:
    env = dict(os.environ)
    if args.domain_id is not None:
        env['ROS_DOMAIN_ID'] = str(args.domain_id)
    env['PYTHONUNBUFFERED'] = '1'   # print() of a node reaches us line by line
    if colour and 'RCUTILS_COLORIZED_OUTPUT' not in env:
        env['RCUTILS_COLORIZED_OUTPUT'] = '1'   # a pipe, but a terminal in the end
    return env


def error(text: str) -> int:
    print(f'{PROG}: error: {text}', file=sys.stderr, flush=True)
    return 2


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    nodes = stack(args)

    params_file = (args.params_file or default_params_file()).expanduser().resolve()
    # the nodes' own check (pam_common.params_files, rcl's parse included), before any start
    problem = ros_args_problem([PROG, '--ros-args', '--params-file', str(params_file)])
    if problem is not None:
        missing = not (args.params_file or params_file.exists())
        return error(problem + (' (run `make setup`, or pass --params-file)' if missing else ''))
    try:
        keys = section_keys(params_file)
    except ValueError as exc:
        return error(str(exc))

    argv_of = {}
    for node in nodes:
        exe = find_executable(node.name, node.package)
        if exe is None:
            where = '; '.join(executable_candidates(node.name, node.package))
            hint = ' (run `make setup` or source scripts/env.sh / your install)'
            return error(f"executable '{node.name}' of {node.package} not found{hint}; looked "
                         f'in: {where}')
        argv_of[node.name] = [exe, '--ros-args', '-r', f'__ns:={args.namespace}',
                              '--params-file', str(params_file)]

    log_dir = None
    if args.log_dir is not None:
        log_dir = args.log_dir.expanduser().resolve()
        try:
            log_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            return error(f'cannot create --log-dir {log_dir}: {exc.strerror}')

    colour = args.colour and sys.stdout.isatty() and 'NO_COLOR' not in os.environ
    output = Output([PROG] + [n.name for n in nodes], colour)
    env = child_environment(args, colour)
    children = [Child(node, argv_of[node.name]) for node in nodes]
    bringup = Bringup(children, env, output, log_dir)

    output.say(f"ROS_DOMAIN_ID={env.get('ROS_DOMAIN_ID', '(unset: 0)')}, namespace "
               f"{args.namespace}, params file {params_file}"
               + (f', logs in {log_dir}' if log_dir else '')
               + (f', duration {args.duration:g} s' if args.duration else ', Ctrl-C to stop'))
    for node in nodes:
        fqn = args.namespace.rstrip('/') + '/' + node.name
        matching = sections_for(fqn, keys)
        if not [k for k in matching if k.strip('/') != '**']:
            output.say(f'warning: no section of the params file is for {fqn} (sections: '
                       f'{", ".join(keys) or "none"}): it runs with its defaults'
                       + (' and /**' if matching else ''))

    bringup.install_signal_handlers()
    try:
        bringup.start()
    except (OSError, subprocess.SubprocessError) as exc:
        output.say(f'error: could not start a node: {exc}')
        bringup.stop()
        return 1
    armer = None
    if args.rig == 'driver' and not args.no_controller and not args.no_arm:
        armer = DriverArmer(args.namespace, args.domain_id, output)
        armer.start()   # after the children: no fork while its threads run
    try:
        return bringup.run(args.duration)
    finally:
        if armer is not None:
            armer.stop()


if __name__ == '__main__':
    sys.exit(main())
