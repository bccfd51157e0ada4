"""Supervision of child processes: start them, forward their output, stop them, report.

Generic: it knows commands, names and signals, nothing of PAM (which nodes make the stack is
pam_bringup.stack; the command line that ties them is pam_bringup.bringup).

Each child runs in a process group of its own (a Ctrl-C in the terminal reaches only the
supervising process, which forwards it) and gets SIGTERM when that process dies (Linux
parent-death signal). Its stdout and stderr are merged into one pipe; a reader thread per child
prefixes every line with `[name]` (coloured on a terminal) and writes it to our stdout, keeps
the last TAIL_LINES lines (Child.tail, for error messages) and, with a log folder, writes the raw
line to DIR/<name>.log.

Stopping (Supervisor.stop): SIGINT to every child's process group; children still running
SIGTERM_AFTER later get SIGTERM (as ros2 launch does: a node may miss a SIGINT that arrives while
it is still importing), and SIGKILL after STOP_TIMEOUT, just after STACK_DUMP_SIGNAL (SIGUSR1: a
node that enabled pam_common.stack_dump prints its threads' stacks into the log: where it hung).
A second stop request kills at once.

Exit code (Supervisor.report): 0 when every child exited cleanly after we asked it to stop (0, or
ended by our SIGINT / SIGTERM; never after a SIGKILL), 1 when a child died while running or did
not stop cleanly.

No busy loops: the main thread sleeps in select() on a self-pipe that signal.set_wakeup_fd and
the per-child waiter threads write to.
"""

from __future__ import annotations

import collections
import os
import select
import shlex
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from pam_common.stack_dump import STACK_DUMP_SIGNAL

SIGTERM_AFTER = 5.0      # s, SIGINT -> SIGTERM (as ros2 launch)
STOP_TIMEOUT = 10.0      # s, SIGINT -> SIGKILL
KILL_TIMEOUT = 5.0       # s, SIGKILL -> reaped
STACK_DUMP_WAIT = 1.0    # s for a hung child's stacks to reach the log before SIGKILL
READER_JOIN = 2.0        # s, last output of a child after it exited
TAIL_LINES = 50          # lines of each child's output kept in memory (Child.tail)
# Exit codes of a child that count as a clean stop after we asked it to stop: rclpy nodes return 0
# on Ctrl-C / SIGTERM; one stopped while still importing exits 130 / 143 (pam_model.cli.startup);
# a process ended by the signal itself gives -2 / -15. A SIGKILL is never clean.
CLEAN_STOP_CODES = {0, -signal.SIGINT, 128 + signal.SIGINT, -signal.SIGTERM,
                    128 + signal.SIGTERM}
COLOURS = ('36', '33', '35', '32', '34', '96', '93')   # ANSI: cyan, yellow, magenta, ...
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


# ---------------------------------------------------------------------------- output
class Output:
    """Our stdout, shared by the reader threads and the main thread (one line at a time).
    `own_name` prefixes the supervisor's own lines (say()); echo False: print nothing (the
    children's output still goes to Child.tail and the log files)."""

    def __init__(self, own_name: str, names: list[str], colour: bool, echo: bool = True):
        names = [own_name, *names]
        self.own_name = own_name
        self._lock = threading.Lock()
        self._mute = not echo    # no echo, or our stdout is gone
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
            if self._mute:
                return
            try:
                sys.stdout.write(data)
                sys.stdout.flush()
            except (BrokenPipeError, ValueError, OSError):
                self._mute = True   # keep draining the children; stop writing
                try:   # and no BrokenPipeError again when Python flushes stdout at exit
                    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                except (OSError, ValueError):
                    pass

    def say(self, text: str) -> None:
        self.line(self.own_name, text)


def child_environment(domain_id: int | None = None, colour: bool = False) -> dict:
    """Our environment for the children: ROS_DOMAIN_ID when given, unbuffered Python output (a
    node's print() reaches us line by line), rcutils colours when our output is coloured."""
    env = dict(os.environ)
    if domain_id is not None:
        env['ROS_DOMAIN_ID'] = str(domain_id)
    env['PYTHONUNBUFFERED'] = '1'
    if colour and 'RCUTILS_COLORIZED_OUTPUT' not in env:
        env['RCUTILS_COLORIZED_OUTPUT'] = '1'   # a pipe, but a terminal in the end
    return env


# ---------------------------------------------------------------------------- children
@dataclass
class Child:
    """One child process: its name (the output prefix and log file name), command and role (said
    when it starts)."""

    name: str
    argv: list[str]
    role: str = ''
    proc: subprocess.Popen | None = None
    exited: threading.Event = field(default_factory=threading.Event)
    threads: list = field(default_factory=list)
    log: object = None
    killed: bool = False
    tail: collections.deque = field(default_factory=lambda: collections.deque(maxlen=TAIL_LINES))

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
    only the supervisor, which forwards it), and SIGTERM when the supervisor dies (Linux)."""
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


class Supervisor:
    """Starts `children`, watches them, stops them all (see the module docstring)."""

    def __init__(self, children: list[Child], env: dict, output: Output,
                 log_dir: Path | None = None, cwd: str | Path | None = None,
                 sigterm_after: float = SIGTERM_AFTER, stop_timeout: float = STOP_TIMEOUT):
        self.children = children
        self.env = env
        self.out = output
        self.log_dir = log_dir
        self.cwd = cwd
        self.sigterm_after = sigterm_after
        self.stop_timeout = stop_timeout
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

    def _on_signal(self, signum, frame) -> None:
        self.signals.append(signum)   # the main thread acts on it (set_wakeup_fd wakes it)

    def install_signal_handlers(self) -> None:
        """SIGINT, SIGTERM and SIGHUP become stop requests (main thread only)."""
        for sig in STOP_SIGNALS:
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
                    stderr=subprocess.STDOUT, env=self.env, cwd=self.cwd,
                    preexec_fn=_child_setup,   # noqa: PLW1509 - before our threads start
                    close_fds=True)
                self.out.say(f'started {child.name} ({child.role}), pid '
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
            child.tail.append(text)
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

    def dead(self) -> list[Child]:
        """The children that exited (before stop(): died)."""
        return [c for c in self.children if c.exited.is_set()]

    def run(self, duration: float | None = None, duration_name: str = 'duration') -> int:
        """Wait for a stop signal, the end of `duration` s (called `duration_name` in what we
        say) or a dead child; stop all; the exit code (report())."""
        deadline = None if duration is None else time.monotonic() + duration
        dead: list[Child] = []
        while True:
            if self.signals:
                names = ', '.join(signal.Signals(s).name for s in self.signals)
                self.out.say(f'{names} received: stopping every node')
                break
            dead = self.dead()
            if dead:
                for child in dead:
                    self.out.say(f'{child.name} (pid {child.proc.pid}) died: '
                                 f'{describe_code(child.code)}; stopping the other nodes')
                break
            if deadline is not None and time.monotonic() >= deadline:
                self.out.say(f'{duration_name} {duration:g} s elapsed: stopping every node')
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
        """SIGINT to every child; SIGTERM after sigterm_after (a node that missed the SIGINT,
        e.g. while still importing); SIGKILL after stop_timeout or on a second stop request."""
        handled = len(self.signals)
        for child in self.alive():
            self._signal_group(child, signal.SIGINT)
        start = time.monotonic()
        term_at, end = start + self.sigterm_after, start + self.stop_timeout
        termed = False
        while self.alive():
            now = time.monotonic()
            if len(self.signals) > handled:
                self.out.say('second stop request: killing the remaining nodes')
                break
            if now >= end:
                self.out.say(f'still running {self.stop_timeout:g} s after SIGINT: '
                             + ', '.join(c.name for c in self.alive())
                             + ': printing their threads\' stacks (SIGUSR1), then killing')
                self._dump_stacks()
                break
            if not termed and now >= term_at:
                termed = True
                self.out.say(f'still running {self.sigterm_after:g} s after SIGINT: '
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

    def codes(self) -> str:
        """Every child's end: 'name exit code N' / 'name killed by SIG...' / 'name still
        running', comma-separated."""
        return ', '.join(f'{c.name} {describe_code(c.code)}' if c.code is not None
                         else f'{c.name} still running' for c in self.children)

    def report(self, dead: list[Child]) -> int:
        """Exit code: 1 if a child died (`dead`) or did not stop cleanly, else 0."""
        codes = self.codes()
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
