"""Live stacks of the fault campaign (benchmarks/fault_campaign.py): node processes on an isolated
ROS domain, an rclpy probe that feeds their inputs and watches every output, and the counts the
campaign reports (deaths, non-finite values published, tracebacks).

A Stack keeps its processes by name; ensure() (re)starts every one that is missing or dead and
waits until each is ready (its first /diagnostics status, or its own readiness check), so a case
that killed or crashed a node leaves the next case a whole stack. Output watching runs in the
probe's spin thread: every float of every message received on the watched topics (arrays and
nested messages included, /diagnostics values that read as numbers) is checked for non-finite
values, with the time, topic and field of each one kept.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from pam_common.diagnostics import is_status_of
from pam_common.executables import find_executable
from pam_common.qos import RECORD_DEPTH
from pam_common.testing import DOMAIN_LOCKS, Collector, NodeProcess, Probe, child_env, wait_until

STARTUP = 60.0        # s: a fresh node's first /diagnostics on a loaded 2-core machine
DIAG_WAIT = 4.0       # s: a fresh /diagnostics status (nodes publish about 1 Hz)
TOOL_TIMEOUT = 120.0  # s: one command-line tool run


def campaign_domain() -> int:
    """A ROS_DOMAIN_ID of the campaign in 200..229, apart from the tests' 1..101 and the
    benchmarks' 110..199, held by an exclusive flock for this process's life the way the tests
    hold theirs (pam_common.testing.DOMAIN_LOCKS: two runs at once never share a domain);
    exported to this process (rclpy.init and child_env read it)."""
    import fcntl
    for k in range(30):
        domain = 200 + (os.getpid() + k) % 30
        lock = open(DOMAIN_LOCKS / f'pam_ros_domain_{domain}.lock', 'w')   # noqa: SIM115
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.close()
            continue
        _HELD.append(lock)
        os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
        os.environ.pop('ROS_LOCALHOST_ONLY', None)
        return domain
    raise SystemExit('every ROS domain in 200..229 is held by another process of this machine')


_HELD: list = []     # the lock file of the domain held


def executable(name: str, package: str) -> str:
    path = find_executable(name, package)
    if path is None:
        raise SystemExit(f'{name} ({package}) not found: run `make setup` first')
    return path


def traceback_count(text: str) -> int:
    return text.count('Traceback (most recent call last)')


# ---------------------------------------------------------------------------- non-finite values
@dataclass
class NonFinite:
    """One non-finite value received: when (monotonic s), where, what."""

    time: float
    topic: str
    field: str
    value: str


def _float_items(value):
    """The floats of a message field's value: a float, a sequence or numpy array of numbers."""
    if isinstance(value, float):
        return (value,)
    if isinstance(value, (list, tuple)) or hasattr(value, 'tolist'):
        items = value.tolist() if hasattr(value, 'tolist') else value
        return tuple(v for v in items if isinstance(v, float))
    return ()


def diagnostic_number_strings(text: str) -> list[str]:
    """The parts of a /diagnostics value that read as numbers ('1.5', 'nan', '5.5, 5.5')."""
    numbers = []
    for part in text.split(','):
        try:
            float(part)
        except ValueError:
            continue
        numbers.append(part.strip())
    return numbers


def non_finite_fields(msg, prefix: str = '') -> list[tuple[str, str]]:
    """(field path, value) of every non-finite number in a message: float fields, float arrays,
    nested messages and sequences of them; for a diagnostic_msgs/KeyValue its value string."""
    if type(msg).__name__ == 'KeyValue':
        return [(prefix.rstrip('.'), s) for s in diagnostic_number_strings(msg.value)
                if not math.isfinite(float(s))]
    found = []
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        path = f'{prefix}{name}'
        if hasattr(value, 'get_fields_and_field_types'):
            found += non_finite_fields(value, path + '.')
        elif isinstance(value, list) and value and hasattr(value[0],
                                                           'get_fields_and_field_types'):
            for i, item in enumerate(value):
                label = getattr(item, 'name', '') or getattr(item, 'key', '') or str(i)
                found += non_finite_fields(item, f'{path}[{label}].')
        else:
            found += [(path, repr(v)) for v in _float_items(value) if not math.isfinite(v)]
    return found


class OutputWatch:
    """Counts the messages and non-finite values received on the watched topics."""

    def __init__(self):
        self._lock = threading.Lock()
        self.hits: list[NonFinite] = []
        self.received: dict[str, int] = {}

    def check(self, topic: str, msg) -> None:
        bad = non_finite_fields(msg)
        now = time.monotonic()
        with self._lock:
            self.received[topic] = self.received.get(topic, 0) + 1
            self.hits += [NonFinite(now, topic, f, v) for f, v in bad]

    def between(self, start: float, end: float) -> list[NonFinite]:
        with self._lock:
            return [h for h in self.hits if start <= h.time < end]


# ---------------------------------------------------------------------------- processes
@dataclass
class NodeSpec:
    """A process of a stack: executable, package, the argv after the executable, and how to
    tell it is ready."""

    exe: str
    package: str
    args: tuple = ()
    diag_name: str | None = None     # /diagnostics status name prefix; None: no diagnostics
    ready: object = None             # ready(stack, since) -> bool, besides its diagnostics


@dataclass
class Tool:
    """A finished run of a command-line tool."""

    argv: list
    code: int | None              # None: killed after TOOL_TIMEOUT (a hang)
    stdout: str
    stderr: str
    seconds: float

    @property
    def died(self) -> bool:
        """Killed by a signal or hung: a death (an exit code, however bad, is an answer)."""
        return self.code is None or self.code < 0

    @property
    def tracebacks(self) -> int:
        return traceback_count(self.stdout) + traceback_count(self.stderr)

    def lines(self) -> list[str]:
        return [line for line in self.stderr.splitlines() if line.strip()]


def run_tool(exe: str, package: str, args, env: dict, cwd, timeout: float = TOOL_TIMEOUT,
             interrupt: tuple | None = None) -> Tool:
    """Run a command-line tool (or a node that ends by itself) to its end. interrupt=(sig,
    when): send signal `sig` as soon as when(pid) holds (polled every ms)."""
    argv = [executable(exe, package), *map(str, args)]
    start = time.monotonic()
    proc = subprocess.Popen(argv, env=env, cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True,
                            start_new_session=True)
    try:
        if interrupt is not None:
            sig, when = interrupt
            while proc.poll() is None and time.monotonic() < start + timeout:
                if when(proc.pid):
                    break
                time.sleep(0.001)
            proc.send_signal(sig)
        out, err = proc.communicate(timeout=max(timeout - (time.monotonic() - start), 1.0))
        code = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        code = None
    return Tool([exe, *map(str, args)], code, out, err, time.monotonic() - start)


def maps_holds(*names: str):
    """when(pid) for run_tool's interrupt: the process has mapped a file whose path holds one
    of `names` (e.g. a C extension: its imports are under way)."""
    def when(pid: int) -> bool:
        try:
            maps = Path(f'/proc/{pid}/maps').read_text()
        except OSError:
            return False
        return any(name in maps for name in names)
    return when


class Stack:
    """The processes of one group of cases, the probe's watch of their outputs."""

    def __init__(self, probe: Probe, domain: int, folder: Path, specs: dict[str, NodeSpec],
                 outputs: list[tuple[type, str]]):
        self.probe = probe
        self.env = child_env(domain)
        self.folder = folder
        self.specs = specs
        self.procs: dict[str, NodeProcess] = {}
        self.killed: set[str] = set()      # killed on purpose in the current case
        self.watch = OutputWatch()
        self.topics: dict[str, Collector] = {}
        from diagnostic_msgs.msg import DiagnosticArray
        for msg_type, topic in [*outputs, (DiagnosticArray, '/diagnostics')]:
            self.topics[topic] = probe.subscribe(
                msg_type, topic, lambda m, t=topic: self.watch.check(t, m), depth=RECORD_DEPTH)
        self._finished_tracebacks = 0      # of processes replaced by a restart
        self._reported: set[int] = set()   # ids of the processes whose death was reported

    # --- processes -------------------------------------------------------------------------
    def ensure(self) -> list[str]:
        """Start every process that is missing or dead, in spec order; wait until each is ready.
        Returns the names started."""
        started = []
        for name, spec in self.specs.items():
            old = self.procs.get(name)
            if old is not None and old.alive():
                continue
            if old is not None:
                self._finished_tracebacks += traceback_count(old.stderr + old.stdout)
                old.close()
            self.procs[name] = NodeProcess(spec.exe, spec.package, list(spec.args), self.env,
                                           cwd=self.folder)
            started.append(name)
            self._wait_ready(name, spec, time.monotonic())
        self.killed.clear()
        return started

    def _wait_ready(self, name: str, spec: NodeSpec, since: float) -> None:
        proc = self.procs[name]

        def ready():
            if spec.diag_name and self.status(spec.diag_name, since) is None:
                return False
            return spec.ready is None or spec.ready(self, since)
        end = time.monotonic() + STARTUP
        while time.monotonic() < end and proc.alive():
            if ready():
                return
            time.sleep(0.05)
        raise RuntimeError(f'{name} not ready after {STARTUP:.0f} s (alive {proc.alive()}); '
                           f'stderr:\n{proc.stderr[-3000:]}')

    def kill(self, name: str) -> float:
        """SIGKILL a process on purpose (not a death of the case); the monotonic time."""
        self.killed.add(name)
        t = time.monotonic()
        self.procs[name].proc.kill()
        self.procs[name].proc.wait(timeout=10.0)
        return t

    def deaths(self) -> list[str]:
        """Processes dead that the case did not kill, not reported before: name and exit
        code."""
        found = [(n, p) for n, p in self.procs.items()
                 if not p.alive() and n not in self.killed and id(p) not in self._reported]
        self._reported.update(id(p) for _, p in found)
        return [f'{n} (exit {p.proc.returncode})' for n, p in found]

    def tracebacks(self) -> int:
        return self._finished_tracebacks + sum(traceback_count(p.stderr + p.stdout)
                                               for p in self.procs.values())

    def close(self) -> None:
        for name in reversed(list(self.procs)):
            self.procs[name].close()

    # --- /diagnostics ----------------------------------------------------------------------
    def status(self, node: str, after: float = 0.0):
        """The latest DiagnosticStatus of `node` (a bare node name or a fully qualified one,
        pam_common.diagnostics.is_status_of) received after the monotonic time `after`, or
        None."""
        found = None
        for t, array in self.topics['/diagnostics'].items():
            if t < after:
                continue
            for s in array.status:
                if is_status_of(s.name, node):
                    found = s
        return found

    def values(self, name_prefix: str, after: float = 0.0) -> dict:
        s = self.status(name_prefix, after)
        return {kv.key: kv.value for kv in s.values} if s else {}

    def fresh_values(self, name_prefix: str, after: float, timeout: float = DIAG_WAIT) -> dict:
        """The values of the first status of name_prefix received after `after` (waits)."""
        wait_until(lambda: self.status(name_prefix, after) is not None, timeout, 0.05)
        return self.values(name_prefix, after)


def number(values: dict, key: str, default: float = math.nan) -> float:
    """A /diagnostics value as a number (default if missing or not a number)."""
    try:
        return float(values[key])
    except (KeyError, ValueError):
        return default


def new_folder(parent: Path, name: str) -> Path:
    return Path(tempfile.mkdtemp(prefix=f'{name}_', dir=parent))
