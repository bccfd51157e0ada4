"""The real-time knobs of the nodes on the 1 kHz path: parameters, where they apply, what is logged
and reported (the syscalls: pam_common.realtime).

Every node on the 1 kHz path (sim_node, driver_node, ukf_node, pi_node) holds the rows
REALTIME_PARAMS in its parameter table, read-only, as ros2_control's controller_manager names
them:

    thread_priority  int, 0..99    0 (default): normal scheduling; 1..99: SCHED_FIFO priority
    cpu_affinity     int[]         the CPUs the thread may run on; [] (default): any CPU
    lock_memory      bool          mlockall(MCL_CURRENT|MCL_FUTURE) for the whole process

They apply to the thread that runs the node's 1 kHz path: the executor thread (the node's
constructor runs on it: run_nodes builds the nodes on the thread that then spins them; a node
calls `knobs.apply_to_executor()` there) and the node's own thread when it has one (sim_node's
sampler, driver_node's serial reader: `knobs.apply_to_thread(name)` first thing in it). Threads
the process starts later inherit the setting (Linux); the middleware's threads, created with the
first node, do not. In a composed process (pam_container) every node shares one executor
thread: it gets the highest priority any node asks for and the union of the CPU sets the nodes
ask for (a node that leaves cpu_affinity empty adds no constraint); memory is locked once for
the process if any node asks.

Each knob a node asks for is logged once: INFO when granted ('SCHED_FIFO priority 80 granted to
thread sim_node_sampler (tid 1234)'), WARN with the fallback and what to set when refused; the
node runs on either way. `knobs.report` is a /diagnostics check (DiagnosticsPublisher.add_check):
the scheduling and CPUs of each thread, read live at each report, the memory locked, whether the
kernel is PREEMPT_RT; level WARN while a knob asked for was refused. Nothing here runs per sample.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass

from . import realtime
from .node_params import ParamSpec, fail

PRIORITY_RANGE = (0, 99)
CPU_RANGE = (0, 1023)           # CPU numbers a cpu_set_t holds (CPU_SETSIZE 1024)
EXECUTOR = 'executor'           # the executor thread's name in messages and /diagnostics

REALTIME_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('thread_priority', 0, 'integer', '',
              'Scheduling of the threads on the 1 kHz path (the executor thread and the '
              "node's own sampling/reading thread): 0 (the default) normal scheduling; 1..99 "
              'SCHED_FIFO with this priority (needs CAP_SYS_NICE or an rtprio limit: '
              'docs/realtime.md). Logged when granted, a warning when refused (the node runs on '
              'at normal scheduling).', range=PRIORITY_RANGE),
    ParamSpec('cpu_affinity', [], 'integer[]', '',
              'CPUs the threads on the 1 kHz path may run on, e.g. [1]; [] (the default): any '
              'CPU. In a composed process the executor thread gets the union of what its '
              'nodes ask.'),
    ParamSpec('lock_memory', False, 'bool', '',
              "Lock the process's memory in RAM (mlockall MCL_CURRENT|MCL_FUTURE: no page "
              'faults to disk, no swap-out); needs CAP_IPC_LOCK or a memlock limit.'),
)


def check_realtime(values: dict) -> dict:
    """cpu_affinity: a list of CPU numbers in CPU_RANGE ([] if not given; duplicates dropped,
    sorted). thread_priority's range is its ParamSpec's (check_all). Raises ConfigError naming
    the parameter; returns values."""
    cpus = values.get('cpu_affinity') or []
    if isinstance(cpus, (str, bytes)) or not all(
            isinstance(c, int) and not isinstance(c, bool) for c in cpus):
        fail('cpu_affinity', f'expected a list of CPU numbers, e.g. [0] or [0, 1], got {cpus!r}')
    low, high = CPU_RANGE
    bad = [c for c in cpus if not low <= c <= high]
    if bad:
        fail('cpu_affinity', f'CPU {bad[0]} is out of range [{low}, {high}]')
    values['cpu_affinity'] = sorted(set(cpus))
    return values


@dataclass(frozen=True)
class RealtimeRequest:
    """What a node asks for: priority 0 = normal scheduling, cpus () = any CPU."""

    priority: int = 0
    cpus: tuple[int, ...] = ()
    lock: bool = False

    @classmethod
    def from_values(cls, values: dict) -> RealtimeRequest:
        return cls(int(values['thread_priority']), tuple(values['cpu_affinity']),
                   bool(values['lock_memory']))

    @property
    def asked(self) -> bool:
        return bool(self.priority or self.cpus or self.lock)


def apply_to_this_thread(request: RealtimeRequest, name: str) -> list[realtime.Grant]:
    """The priority and affinity of `request` for the calling thread (what it asks only)."""
    grants = []
    if request.priority:
        grants.append(realtime.set_sched_fifo(request.priority, name))
    if request.cpus:
        grants.append(realtime.set_cpu_affinity(request.cpus, name))
    return grants


class _ProcessKnobs:
    """What the nodes of this process asked for the shared executor thread, merged: the highest
    priority, the union of the CPU sets; and whether memory is locked."""

    def __init__(self):
        self.lock = threading.Lock()
        self.priority = 0
        self.cpus: set[int] = set()
        self.memory_locked = False

    def merge(self, request: RealtimeRequest) -> RealtimeRequest:
        with self.lock:
            self.priority = max(self.priority, request.priority)
            self.cpus |= set(request.cpus)
            return RealtimeRequest(self.priority if request.priority else 0,
                                   tuple(sorted(self.cpus)) if request.cpus else (),
                                   request.lock)


_PROCESS = _ProcessKnobs()


class RealtimeKnobs:
    """A node's real-time knobs: apply them (logged), report them (a /diagnostics check).

        knobs = RealtimeKnobs(node.get_logger(), values)     # ConfigError: check_realtime
        knobs.apply_to_executor()                            # in the constructor
        knobs.apply_to_thread('sim_node_sampler')            # first thing in the node's thread
        diagnostics.add_check(knobs.report)
    """

    def __init__(self, logger, values: dict | RealtimeRequest):
        """`values`: the node's parameter values (checked here: ConfigError, check_realtime), or
        the RealtimeRequest of a node's frozen config."""
        self.request = (values if isinstance(values, RealtimeRequest)
                        else RealtimeRequest.from_values(check_realtime(values)))
        self._logger = logger
        self._threads: dict[str, int] = {}         # name -> tid of the threads it applied to
        self._refused: list[str] = []              # short texts of the knobs refused
        self._rt_kernel = realtime.has_realtime_kernel()

    def apply_to_executor(self) -> list[realtime.Grant]:
        """The knobs for the calling thread, the executor's (merged with the other nodes of the
        process), and the memory lock. Call it on the thread that will spin the node."""
        self._threads[EXECUTOR] = realtime.thread_id()
        merged = _PROCESS.merge(self.request)
        grants = apply_to_this_thread(merged, EXECUTOR)
        if merged.priority > self.request.priority or merged.cpus != self.request.cpus:
            grants = [realtime.Grant(g.granted, f'{g.message} (the executor thread is shared by '
                                                'the nodes of this process: the highest priority '
                                                'and the union of the CPUs they ask for)')
                      for g in grants]
        if self.request.lock:
            grants.append(self._lock_memory())
        self._log(grants)
        return grants

    def apply_to_thread(self, name: str) -> list[realtime.Grant]:
        """The knobs (priority, affinity) for the calling thread, the node's own (`name`)."""
        self._threads[name] = realtime.thread_id()
        grants = apply_to_this_thread(self.request, name)
        self._log(grants)
        return grants

    def _lock_memory(self) -> realtime.Grant:
        with _PROCESS.lock:
            if _PROCESS.memory_locked:
                return realtime.Grant(True, 'memory locked already (another node of this process '
                                            'asked for it)')
            grant = realtime.lock_memory()
            _PROCESS.memory_locked = grant.granted
            return grant

    def _log(self, grants: Sequence[realtime.Grant]) -> None:
        for grant in grants:
            if grant.granted:
                self._logger.info(grant.message)
            else:
                self._refused.append(grant.message.split(':', 1)[0])
                self._logger.warning(grant.message)

    def report(self):
        """A /diagnostics check: (level, problem, values)."""
        from .diagnostics import OK, WARN
        values = {f'{name} thread': f'{realtime.scheduling_text(tid)}, CPUs '
                                    f'{realtime.cpus_text(tid)}'
                  for name, tid in self._threads.items()}
        values['memory locked (MiB)'] = realtime.locked_memory_kb() / 1024.0
        values['PREEMPT_RT kernel'] = self._rt_kernel
        if self._refused:
            return WARN, 'real-time knobs refused: ' + '; '.join(self._refused), values
        return OK, '', values
