"""Topic-level test support shared by the packages' tests (a small launch_testing stand-in):
node executables as real separate processes and an rclpy probe node in the test process, both on
a ROS domain of their own.

Isolation: every test module gets a ROS_DOMAIN_ID in 1..101 derived from the pid and the module
name, and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, set in the child's environment and in this
process's environment before rclpy.init (each module has its own rclpy Context).

A package's test/conftest.py imports the fixtures it uses:

    from pam_common.testing import node_process, probe, ros_context, ros_domain  # noqa: F401

    def test_x(node_process, probe):
        sim = node_process('sim_node', 'pam_driver', '-p', 'timing:=lockstep')
        got = probe.subscribe(Pressures, '/pam/pressures')
        sim.wait_for(lambda: len(got) > 0, 30.0, 'first pressures sample')
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
import zlib
from pathlib import Path

import pytest

from pam_common.executables import executable_candidates, find_executable
from pam_common.node_params import ConfigError
from pam_common.stamps import stamp_ns  # noqa: F401 - the tests import it from here too

#: The project venv when running from a source checkout (make setup); None on a colcon install.
VENV = Path(sys.prefix) if (Path(sys.prefix) / 'pyvenv.cfg').exists() else None
STARTUP_TIMEOUT = 45.0   # s: first message from a fresh process on a loaded 2-core machine
STOP_TIMEOUT = 10.0      # s: SIGINT -> exit


def executable(name: str, package: str) -> str:
    """Path of a node executable (pam_common.executables), or fail the test."""
    path = find_executable(name, package)
    if path is None:
        pytest.fail(f'{name} not found in: {", ".join(executable_candidates(name, package))}: '
                    'run `make setup` first')
    return path


def domain_id_for(module_name: str) -> int:
    """A ROS_DOMAIN_ID in 1..101, different for each (process, module) in practice."""
    return (os.getpid() * 31 + zlib.crc32(module_name.encode())) % 101 + 1


def child_env(domain_id: int) -> dict:
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               AMENT_PREFIX_PATH=env.get('AMENT_PREFIX_PATH') or str(VENV or ''),
               PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
    env.pop('ROS_LOCALHOST_ONLY', None)
    return env


def assert_imports_without_ament(module: str) -> None:
    """`python -c "import <module>"` succeeds in a process without AMENT_PREFIX_PATH (no ROS
    environment): a node's parameter table reads nothing installed at import, and its URDF
    default (joint_name, a Deferred one) is then '' instead of an error."""
    env = {k: v for k, v in os.environ.items() if k != 'AMENT_PREFIX_PATH'}
    code = (f'import {module} as m; from pam_common.node_params import defaults; '
            "print(repr(defaults(m.PARAMETERS).get('joint_name')))")
    done = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                          check=False, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "''", done.stdout


def wait_until(predicate, timeout: float, period: float = 0.01) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(period)
    return bool(predicate())


QUIET = 0.2       # s without a new answer after which feed_until_answered takes them all in


def feed_until_answered(feed_one, collectors, timeout: float = 20.0,
                        pause: float = 0.02) -> int:
    """Feed a node process one input at a time (feed_one(k), k = 0, 1, ...) until every
    collector (the probe's subscriptions to the node's answers) has a message, then clear them;
    returns how many inputs it took (the collectors are cleared once no answer came for QUIET
    s). Why: discovery matches each side of a publisher and a subscription on its own, and the
    probe sees only its own side: what the node publishes before ITS publisher knows the probe's
    subscription reaches nobody, so a test that feeds a fixed burst once and counts the answers
    can wait forever. A node whose state the inputs change must be reset after this (ukf_node:
    its ~/reset service)."""
    end = time.monotonic() + timeout
    k = 0
    while not all(len(c) for c in collectors):
        assert time.monotonic() < end, f'no answer on every topic to {k} inputs'
        feed_one(k)
        k += 1
        time.sleep(pause)
    counted = -1                     # the answers to the last inputs may still be on their way
    while counted != sum(len(c) for c in collectors) and time.monotonic() < end:
        counted = sum(len(c) for c in collectors)
        time.sleep(QUIET)
    for collector in collectors:
        collector.clear()
    return k


def log_lines(text: str, severity: str, logger: str | None = None) -> list[str]:
    """The rclpy console lines of `text` (a process's stderr) at `severity` ('DEBUG', 'INFO',
    ...), of `logger` (e.g. 'pam.ukf_node': the node's namespace and name) if given; the
    default format is `[DEBUG] [<time>] [<logger>]: <message>`."""
    return [line for line in text.splitlines() if line.startswith(f'[{severity}] ')
            and (logger is None or f'] [{logger}]: ' in line)]


def wait_for_log(process, severity: str, logger: str, text: str, timeout: float = 10.0) -> list:
    """Wait until `process` logged a line holding `text` at `severity` from `logger`; the lines
    of that logger at that severity so far."""
    process.wait_for(lambda: any(text in line
                                 for line in log_lines(process.stderr, severity, logger)),
                     timeout, f'the {severity} line {text!r} of {logger}')
    return log_lines(process.stderr, severity, logger)


def assert_no_debug_lines(process) -> None:
    """Stop `process` (exit code 0) and check that it printed no DEBUG line at all (DEBUG is
    off unless --log-level turns it on)."""
    assert process.stop() == 0, process.stderr
    lines = log_lines(process.stderr + process.stdout, 'DEBUG')
    assert lines == [], lines


# ---------------------------------------------------------------------------- processes
def read_child_output(f) -> str:
    """All a child process has written so far to `f`, the file its stdout or stderr goes to.
    The child's descriptor shares this open file's offset: a seek here would move where the
    child writes next, and a line it wrote meanwhile would overwrite the start of the file (a
    test read sim_node's first INFO lines cut and overwritten so). pread reads at an offset
    without moving it."""
    fd = f.fileno()
    return os.pread(fd, os.fstat(fd).st_size, 0).decode(errors='replace')


class NodeProcess:
    """A node executable as a child process with its output captured to files; `prefix` (e.g.
    ['ip', 'netns', 'exec', NAME]) runs it through a command that execs it (same pid)."""

    def __init__(self, name, package, args, env, cwd, prefix=()):
        self.name = name
        self.args = [*prefix, executable(name, package), *args]
        self._out = tempfile.TemporaryFile(mode='w+b')   # noqa: SIM115 - closed by close()
        self._err = tempfile.TemporaryFile(mode='w+b')   # noqa: SIM115 - closed by close()
        self.proc = subprocess.Popen(self.args, env=env, cwd=cwd, stdout=self._out,
                                     stderr=self._err, stdin=subprocess.DEVNULL)

    def _read(self, f) -> str:
        return read_child_output(f)

    @property
    def stderr(self) -> str:
        return self._read(self._err)

    @property
    def stdout(self) -> str:
        return self._read(self._out)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def wait_for(self, predicate, timeout: float, what: str) -> None:
        """Wait until predicate() holds; fail early (with the child's stderr) if it exits."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return
            if not self.alive():
                # what it sent just before exiting may still be on its way
                if wait_until(predicate, min(1.0, max(0.0, end - time.monotonic()))):
                    return
                pytest.fail(f'{self.name} exited with code {self.proc.returncode} while waiting '
                            f'for {what}; stderr:\n{self.stderr}')
            time.sleep(0.01)
        if not predicate():
            pytest.fail(f'timed out after {timeout:.0f} s waiting for {what}; {self.name} stderr:\n'
                        f'{self.stderr}')

    def wait_exit(self, timeout: float) -> int:
        return self.proc.wait(timeout=timeout)

    def stop(self) -> int | None:
        """SIGINT, then SIGKILL if it does not exit within STOP_TIMEOUT."""
        if self.alive():
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=STOP_TIMEOUT)
        return self.proc.returncode

    def close(self):
        self.stop()
        self._out.close()
        self._err.close()


DOMAIN_LOCKS = Path(tempfile.gettempdir())   # pam_ros_domain_<id>.lock: one holder per domain


def claim_domain(module_name: str):
    """(domain, lock file): the first ROS_DOMAIN_ID from domain_id_for(module_name) on, in
    1..101, that no other test process of this machine holds (an exclusive flock, released when
    the file is closed or the process ends). Two test runs at once (two checkouts, a developer's
    run beside CI's) otherwise shared a domain now and then: a probe received another run's
    messages (seen: pi_node counting 19620 commands in a test that sent 170 estimates)."""
    import fcntl
    first = domain_id_for(module_name)
    for k in range(101):
        domain = (first - 1 + k) % 101 + 1
        lock = open(DOMAIN_LOCKS / f'pam_ros_domain_{domain}.lock', 'w')   # noqa: SIM115
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return domain, lock
        except BlockingIOError:
            lock.close()
    pytest.fail('every ROS domain in 1..101 is held by another test process of this machine')


@pytest.fixture(scope='module')
def ros_domain(request) -> int:
    """This module's ROS_DOMAIN_ID, held for the module (claim_domain); also exported to this
    process's environment."""
    domain, lock = claim_domain(request.module.__name__)
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_LOCALHOST_ONLY', None)
    yield domain
    lock.close()


@pytest.fixture
def node_process(request, ros_domain, tmp_path):
    """Factory: node_process(name, package, *ros_args) starts `name --ros-args *ros_args` (or the
    exact argv given with raw=True) on this module's domain. Every process is stopped at
    teardown (SIGINT, then SIGKILL), last started first (a client before what it depends on,
    e.g. driver_node before its emulator), its output attached to the test report."""
    started: list[NodeProcess] = []

    def start(name: str, package: str, *args, raw: bool = False) -> NodeProcess:
        argv = list(args) if raw else ['--ros-args', *args]
        process = NodeProcess(name, package, argv, child_env(ros_domain), cwd=tmp_path)
        started.append(process)
        return process

    yield start
    for i, process in reversed(list(enumerate(started))):
        code = process.stop()
        label = f'{process.name} #{i + 1}'
        request.node.add_report_section(
            'teardown', f'{label} stderr (exit code {code}, argv {process.args[1:]})',
            process.stderr)
        out = process.stdout
        if out.strip():
            request.node.add_report_section('teardown', f'{label} stdout', out)
        process.close()


# ---------------------------------------------------------------------------- rclpy probe
class Collector:
    """Messages of one subscription as (receive time, message), thread-safe."""

    def __init__(self):
        self._lock = threading.Lock()
        self._items: list = []
        self.subscription = None   # set by Probe.subscribe

    def add(self, msg) -> None:
        with self._lock:
            self._items.append((time.monotonic(), msg))

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)

    def items(self) -> list:
        with self._lock:
            return list(self._items)

    def messages(self) -> list:
        return [m for _, m in self.items()]

    def since(self, t: float) -> list:
        return [m for r, m in self.items() if r >= t]

    def clear(self) -> None:
        with self._lock:
            self._items.clear()


class Probe:
    """An rclpy node of the test process, spun by a background thread."""

    def __init__(self, context, name: str):
        import rclpy
        from rclpy.node import Node
        from rclpy.task import Future

        from pam_common.executors import is_events_executor, make_executor

        self._rclpy = rclpy
        self.context = context
        self.node = Node(name, context=context)
        self._executor = make_executor(events=True, context=context)
        self._events = is_events_executor(self._executor)
        self._executor.add_node(self.node)
        self._done = Future()
        self._error: list = []
        self._thread = threading.Thread(target=self._spin, name=f'{name}_spin', daemon=True)
        self._thread.start()

    def _spin(self):
        try:
            while not self._done.done() and self.context.ok():
                self._executor.spin_until_future_complete(self._done, timeout_sec=0.2)
        except Exception as exc:  # noqa: BLE001 - surfaced by close()
            if self.context.ok() and not self._done.done():
                self._error.append(exc)

    def subscribe(self, msg_type, topic: str, callback=None, depth: int = 100) -> Collector:
        """Collect every message of `topic`; callback(msg) runs first in the spin thread. `depth`
        at most pam_common.qos.RECORD_DEPTH: a deeper keep-last queue keeps the oldest samples
        and refuses the newer ones once full (Fast DDS's reader cap)."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        from .qos import RECORD_DEPTH
        if not 0 < depth <= RECORD_DEPTH:
            raise ValueError(f'depth {depth}: a subscription keeps 1 to {RECORD_DEPTH} samples')

        collector = Collector()

        def on_message(msg):
            if callback is not None:
                callback(msg)
            collector.add(msg)

        qos = QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)
        collector.subscription = self._in_spin_thread(
            lambda: self.node.create_subscription(msg_type, topic, on_message, qos))
        return collector

    def unsubscribe(self, collector: Collector) -> None:
        """Stop `collector`'s subscription (its messages stay): a probe that keeps taking 1 kHz
        topics it no longer reads loads the test process and delays what it does read."""
        subscription = getattr(collector, 'subscription', None)
        if subscription is not None:
            collector.subscription = None
            self._in_spin_thread(lambda: self.node.destroy_subscription(subscription))

    def _in_spin_thread(self, make, timeout: float = 10.0):
        """make() run by the spin thread, between two callbacks; its result. The EventsExecutor
        is not safe against entities added from another thread while it spins: about one
        subscription in 25 made by the test thread never received a message."""
        task = self._executor.create_task(make)
        end = time.monotonic() + timeout
        while not task.done():
            if time.monotonic() > end or not self._thread.is_alive():
                raise RuntimeError(f'{self.node.get_name()}: the spin thread did not run a task')
            time.sleep(0.002)
        return task.result()

    def publisher(self, msg_type, topic: str, depth: int = 100):
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        qos = QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)
        return self._in_spin_thread(lambda: self.node.create_publisher(msg_type, topic, qos))

    def client(self, srv_type, name: str):
        """A service client of the probe's node."""
        return self._in_spin_thread(lambda: self.node.create_client(srv_type, name))

    def close(self):
        if not self._done.done():
            self._done.set_result(None)
        try:
            self._executor.wake()
        except Exception:  # noqa: BLE001
            pass
        self._thread.join(timeout=5.0)
        self._executor.remove_node(self.node)
        self.node.destroy_node()
        self._executor.shutdown()
        if self._error:
            raise self._error[0]


@pytest.fixture(scope='module')
def ros_context(ros_domain):
    """An rclpy Context of this module, initialised on its domain."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain)
    yield context
    context.try_shutdown()


@pytest.fixture
def probe(ros_context, request):
    name = 'test_probe_' + ''.join(c if c.isalnum() else '_' for c in request.node.name)[:60]
    p = Probe(ros_context, name)
    yield p
    p.close()


# ---------------------------------------------------------------------------- helpers
def diagnostic_statuses(collector: Collector, node: str = 'sim_node') -> list:
    """All DiagnosticStatus received of `node`, in order: a fully qualified name
    ('/pam/sim_node': that node only) or a bare node name ('sim_node': in any namespace),
    pam_common.diagnostics.is_status_of."""
    from .diagnostics import is_status_of
    return [s for array in collector.messages() for s in array.status
            if is_status_of(s.name, node)]


class DriverRigProbe:
    """What a driver_node test reads and sends through its probe (the rig behind the driver:
    pam-emulator or the reference board on simavr). A subclass sets `probe`, `driver` (the
    driver_node NodeProcess), `diagnostics` (a /diagnostics Collector) and `commands` (a
    /pam/valve_command publisher)."""

    NODE = '/pam/driver_node'

    def status(self, after: float = 0.0):
        """driver_node's latest status received after monotonic time `after` (or None)."""
        from .diagnostics import is_status_of
        statuses = [s for r, a in self.diagnostics.items() if r >= after for s in a.status
                    if is_status_of(s.name, self.NODE)]
        return statuses[-1] if statuses else None

    def values(self, after: float = 0.0) -> dict:
        s = self.status(after)
        return {kv.key: kv.value for kv in s.values} if s else {}

    def wait_values(self, predicate, timeout: float, what: str) -> dict:
        self.driver.wait_for(lambda: bool(self.values()) and predicate(self.values()), timeout,
                             what)
        return self.values()

    def send(self, u1, u2, duration: float = 0.0, period: float = 0.01) -> float:
        """Publish the command (V) every `period` s for `duration` s (once if 0); the
        monotonic time of the last one."""
        end = time.monotonic() + duration
        while True:
            msg = self.commands.msg_type()
            msg.header.stamp = self.probe.node.get_clock().now().to_msg()
            msg.u1, msg.u2 = float(u1), float(u2)
            self.commands.publish(msg)
            if time.monotonic() >= end:
                return time.monotonic()
            time.sleep(period)


def all_finite(values) -> bool:
    return all(math.isfinite(v) for v in values)


def installed_config(name: str, package: str) -> str:
    """Path of a config file in the installed share folder of a package."""
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory(package)) / 'config' / name
    except Exception as exc:  # noqa: BLE001
        pytest.fail(f'cannot find the installed config {name}: {exc}')
    return str(share)


# ---------------------------------------------------------------------------- params files
#: Params files rcl refuses, by kind: (text, the line the one-line error names); text None: the
#: file does not exist. mixed_type_list is judged by rcl's own parse (pam_common.params_files).
MALFORMED_PARAMS_FILES = {
    'unclosed_bracket': ('/**:\n  ros__parameters:\n    safe_command: [5.5, 5.5\n', 3),
    'tab_indentation': ('/**:\n  ros__parameters:\n\tkp_angle: 30.0\n', 3),
    'list_under_ros__parameters': ('/**:\n  ros__parameters:\n    - kp_angle\n    - 30.0\n', 3),
    'mixed_type_list': ('/**:\n  ros__parameters:\n    safe_command: [5.5,\n      5]\n', 4),
    'missing': (None, None),
}


def malformed_params_file(folder: Path, kind: str) -> tuple[Path, int | None]:
    """MALFORMED_PARAMS_FILES[kind] written to folder/<kind>.yaml (not for 'missing'): the path
    and the line the error must name."""
    text, line = MALFORMED_PARAMS_FILES[kind]
    path = folder / f'{kind}.yaml'
    if text is not None:
        path.write_text(text)
    return path, line


def assert_params_file_error(process: NodeProcess, prefix: str, path: Path,
                             line: int | None) -> None:
    """The process refused the params file `path`: exit code 2, and stderr exactly one line,
    `<prefix> error: params file <path>: ...`, ending in `(line N)` when line is given."""
    code = process.wait_exit(STARTUP_TIMEOUT)
    err = process.stderr
    assert code == 2, f'exit code {code}; stderr:\n{err}'
    lines = err.splitlines()
    assert len(lines) == 1 and 'Traceback' not in err, f'not one line:\n{err}'
    assert lines[0].startswith(f'{prefix} error: params file {path}: '), lines[0]
    if line is not None:
        assert lines[0].endswith(f'(line {line})'), lines[0]


def assert_node_refuses_params_file(node_process, folder: Path, node: str, package: str,
                                    kind: str) -> None:
    """`node --ros-args --params-file <MALFORMED_PARAMS_FILES[kind]>` exits with code 2 and one
    line `[node] error: params file ...` (assert_params_file_error)."""
    path, line = malformed_params_file(folder, kind)
    process = node_process(node, package, '--params-file', str(path))
    assert_params_file_error(process, f'[{node}]', path, line)


# ---------------------------------------------------------------------------- parameter choices
def assert_takes_exactly(build_config, specs, name: str, names) -> list:
    """The string parameter `name` of a node's table `specs` offers exactly `names` (its choices,
    in that order); each of them builds a config with build_config({name: value}) (returned, in
    order) and near misses ('', '0', 'x', a name in upper case or with a trailing space) fail with
    the one-line choice error listing the names."""
    spec = next(s for s in specs if s.name == name)
    assert spec.choices == tuple(names), spec.choices
    built = [build_config({name: value}) for value in names]
    near_misses = ['', '0', 'x'] + [n.upper() for n in names] + [n + ' ' for n in names]
    for value in near_misses:
        with pytest.raises(ConfigError) as caught:
            build_config({name: value})
        assert str(caught.value) == (f"parameter '{name}': unknown value {value!r}; "
                                     f"choose one of: {', '.join(names)}")
    return built


# ---------------------------------------------------------------------------- the node skeleton
def assert_follows_the_skeleton(node_process, node: str, package: str, specs) -> None:
    """The node skeleton (pam_common.node_skeleton) as a user meets it, with real processes:
    `node --help` prints a usage listing every parameter of `specs` and exits 0; an argument
    that is not a ROS argument is one line and exit code 2; a misspelt parameter (the longest
    name without its last letter) is a warning naming the closest known one."""
    from pam_common.node_params import unknown_parameter_warning
    shown = node_process(node, package, '--help', raw=True)
    assert shown.wait_exit(STARTUP_TIMEOUT) == 0, shown.stderr
    usage = shown.stdout
    assert usage.startswith(f'usage: {node} '), usage
    listed = {line.split()[0] for line in usage.splitlines()
              if line.startswith('  ') and not line.startswith('   ')}
    assert {spec.name for spec in specs} <= listed, usage
    assert shown.stderr == '', shown.stderr

    stray = node_process(node, package, '--bogus', raw=True)
    assert stray.wait_exit(STARTUP_TIMEOUT) == 2, stray.stderr
    assert stray.stderr.splitlines() == [
        f"{node}: error: unknown argument '--bogus'; parameters are set with --ros-args -p "
        f'NAME:=VALUE (see {node} --help)'], stray.stderr

    name = max((spec.name for spec in specs), key=len)
    typo = name[:-1]
    warning = unknown_parameter_warning(typo, specs, node)
    assert f"did you mean '{name}'?" in warning
    misspelt = node_process(node, package, '-p', f'{typo}:=1')
    misspelt.wait_for(lambda: warning in misspelt.stderr, STARTUP_TIMEOUT, 'the warning')
    assert 'Traceback' not in misspelt.stderr, misspelt.stderr


# ---------------------------------------------------------------------------- threads from /proc
def thread_state(pid: int, tid: int) -> dict:
    """A thread of a running process as the kernel shows it: policy (/proc/<pid>/task/<tid>/stat
    field 41: os.SCHED_OTHER, os.SCHED_FIFO ...), rt_priority (field 40), cpus
    (Cpus_allowed_list of its status, e.g. '0-1') and comm (its name)."""
    import re
    task = f'/proc/{pid}/task/{tid}'
    with open(f'{task}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()      # fields[0] is field 3 (state)
    with open(f'{task}/status') as f:
        cpus = re.search(r'^Cpus_allowed_list:\s*(\S+)', f.read(), re.M).group(1)
    with open(f'{task}/comm') as f:
        comm = f.read().strip()
    return {'policy': int(fields[41 - 3]), 'rt_priority': int(fields[40 - 3]), 'cpus': cpus,
            'comm': comm}


def process_locked_kb(pid: int) -> int:
    """VmLck of /proc/<pid>/status: the process's locked memory, kB."""
    from pam_common.realtime import locked_memory_kb
    return locked_memory_kb(pid)


def logged_tid(lines: list[str], text: str) -> int:
    """The tid of the first line holding `text`, as the real-time knobs name a thread: '...
    thread NAME (tid N)' (pam_common.realtime)."""
    import re
    for line in lines:
        if text in line:
            return int(re.search(r'\(tid (\d+)\)', line).group(1))
    raise AssertionError(f'no line with {text!r} in {lines}')
