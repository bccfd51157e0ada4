"""Real-time scheduling, CPU affinity and locked memory for the calling thread (Linux; no ROS).

The knobs real-time ROS users know from ros2_control's controller_manager (its `thread_priority`,
`cpu_affinity` and `lock_memory` parameters, applied with realtime_tools' configure_sched_fifo,
set_current_thread_affinity and lock_memory): each function here tries one of them and returns a
Grant (granted, one-line message) instead of raising, so a node that is not permitted a knob
logs the message and goes on at normal scheduling.

    grant = set_sched_fifo(80)        # SCHED_FIFO priority 80 for THIS thread
    grant = set_cpu_affinity([1])     # this thread on CPU 1 only
    grant = lock_memory()             # mlockall(MCL_CURRENT | MCL_FUTURE): the whole process

On Linux the scheduling calls act on a thread: sched_setscheduler(0, ...) and
sched_setaffinity(0, ...) change the calling thread only (pid 0 is "the caller", and a Linux
"pid" given to these calls is a thread id), and a thread started afterwards by that thread
inherits its policy, priority and affinity. Threads that exist already keep theirs.
mlockall covers the whole process.

When the kernel refuses (EPERM: no CAP_SYS_NICE and an RLIMIT_RTPRIO below the priority; ENOMEM
or EPERM for mlockall: no CAP_IPC_LOCK and RLIMIT_MEMLOCK too small), the message says what to
set: `ulimit -r` / `ulimit -l`, /etc/security/limits.conf, systemd's LimitRTPRIO/LimitMEMLOCK,
docker's --cap-add/--ulimit (docs/realtime.md).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import os
import platform
import resource
import threading
from collections.abc import Iterable
from typing import NamedTuple

PRIORITY_RANGE = (1, 99)        # SCHED_FIFO priorities on Linux (sched_get_priority_min/max)
CAP_SYS_NICE = 23               # linux/capability.h
CAP_IPC_LOCK = 14

#: What to set so that SCHED_FIFO is permitted (one line, for the warnings).
RTPRIO_HOWTO = ('to permit it: `ulimit -r 99` in the shell that starts the node (needs the hard '
                'limit), or /etc/security/limits.conf `@realtime - rtprio 98` (log in again), '
                'systemd LimitRTPRIO=98, docker run --cap-add SYS_NICE --ulimit rtprio=99; see '
                'docs/realtime.md')
#: What to set so that mlockall is permitted.
MEMLOCK_HOWTO = ('to permit it: `ulimit -l unlimited`, or /etc/security/limits.conf '
                 '`@realtime - memlock unlimited` (log in again), systemd LimitMEMLOCK=infinity, '
                 'docker run --ulimit memlock=-1 (or --cap-add IPC_LOCK); see docs/realtime.md')


class Grant(NamedTuple):
    """What one knob came to: granted or not, and a one-line message saying which and why."""

    granted: bool
    message: str


def thread_id() -> int:
    """The calling thread's kernel thread id (tid: /proc/<pid>/task/<tid>)."""
    return threading.get_native_id()


def thread_label(name: str) -> str:
    """'thread <name> (tid N)' of the calling thread, as the messages name it."""
    return f'thread {name} (tid {thread_id()})'


def has_capability(cap: int) -> bool:
    """Whether the process holds the capability in its effective set (/proc/self/status)."""
    try:
        with open('/proc/self/status') as f:
            for line in f:
                if line.startswith('CapEff:'):
                    return bool(int(line.split()[1], 16) >> cap & 1)
    except OSError:
        pass
    return False


def _limit_text(limit: int) -> str:
    return 'unlimited' if limit == resource.RLIM_INFINITY else str(limit)


# --- SCHED_FIFO -------------------------------------------------------------------------------

def set_sched_fifo(priority: int, name: str = 'this') -> Grant:
    """SCHED_FIFO with `priority` (1..99) for the calling thread (named `name` in the message)."""
    who = thread_label(name)
    low, high = PRIORITY_RANGE
    if not low <= priority <= high:
        return Grant(False, f'SCHED_FIFO priority {priority} refused for {who}: a priority is '
                            f'{low}..{high}; the thread keeps its scheduling')
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as exc:
        if exc.errno == errno.EPERM:
            soft = resource.getrlimit(resource.RLIMIT_RTPRIO)[0]
            why = (f'EPERM: no CAP_SYS_NICE and RLIMIT_RTPRIO {_limit_text(soft)} < {priority}'
                   if not has_capability(CAP_SYS_NICE) else
                   'EPERM (with CAP_SYS_NICE: a cgroup without a real-time budget, '
                   'cpu.rt_runtime_us?)')
            return Grant(False, f'SCHED_FIFO priority {priority} refused for {who}: {why}; the '
                                f'thread keeps normal scheduling (SCHED_OTHER); {RTPRIO_HOWTO}')
        return Grant(False, f'SCHED_FIFO priority {priority} refused for {who}: '
                            f'{errno.errorcode.get(exc.errno, exc.errno)}: {exc.strerror}; the '
                            'thread keeps normal scheduling (SCHED_OTHER)')
    return Grant(True, f'SCHED_FIFO priority {priority} granted to {who}')


def scheduling(tid: int = 0) -> tuple[int, int]:
    """(policy, priority) of thread `tid` (0: the calling thread)."""
    return os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority


def scheduling_text(tid: int = 0) -> str:
    """'SCHED_FIFO priority 80', 'SCHED_OTHER' ... of thread `tid` (0: the calling thread)."""
    try:
        policy, priority = scheduling(tid)
    except OSError as exc:
        return f'unknown ({exc.strerror})'
    names = {os.SCHED_OTHER: 'SCHED_OTHER', os.SCHED_FIFO: 'SCHED_FIFO', os.SCHED_RR: 'SCHED_RR',
             os.SCHED_BATCH: 'SCHED_BATCH', os.SCHED_IDLE: 'SCHED_IDLE'}
    name = names.get(policy, f'policy {policy}')
    return f'{name} priority {priority}' if policy in (os.SCHED_FIFO, os.SCHED_RR) else name


# --- CPU affinity -----------------------------------------------------------------------------

def cpu_list_text(cpus: Iterable[int]) -> str:
    """'0-2,5' of {0, 1, 2, 5} (the kernel's list format, as in /proc/<pid>/status)."""
    ordered, runs = sorted(set(cpus)), []
    for cpu in ordered:
        if runs and cpu == runs[-1][1] + 1:
            runs[-1][1] = cpu
        else:
            runs.append([cpu, cpu])
    return ','.join(str(a) if a == b else f'{a}-{b}' for a, b in runs) or 'none'


def set_cpu_affinity(cpus: Iterable[int], name: str = 'this') -> Grant:
    """The calling thread on `cpus` only. Granted when the thread's CPUs are then exactly
    those: the kernel drops CPUs the process may not use (offline, outside its cpuset) and
    refuses a set with none it may use (EINVAL)."""
    wanted = set(cpus)
    who = thread_label(name)
    asked = cpu_list_text(wanted)
    try:
        os.sched_setaffinity(0, wanted)
    except (OSError, ValueError, OverflowError) as exc:
        reason = (f'{errno.errorcode.get(exc.errno, exc.errno)}: {exc.strerror}'
                  if isinstance(exc, OSError) else str(exc))
        return Grant(False, f'CPU affinity {asked} refused for {who}: {reason} (this machine has '
                            f'{os.cpu_count()} CPUs, 0..{(os.cpu_count() or 1) - 1}); the thread '
                            f'runs on CPUs {cpu_list_text(os.sched_getaffinity(0))}')
    got = os.sched_getaffinity(0)
    if got != wanted:
        return Grant(False, f'CPU affinity {asked} only partly granted to {who}: it runs on CPUs '
                            f'{cpu_list_text(got)} (CPUs {cpu_list_text(wanted - got)} are not '
                            'available to this process)')
    return Grant(True, f'CPU affinity {asked} granted to {who}')


def cpus_text(tid: int = 0) -> str:
    """The CPUs thread `tid` (0: the calling thread) may run on, as '0-1'."""
    try:
        return cpu_list_text(os.sched_getaffinity(tid))
    except OSError as exc:
        return f'unknown ({exc.strerror})'


# --- locked memory ----------------------------------------------------------------------------

def _mcl_flags() -> tuple[int, int]:
    """(MCL_CURRENT, MCL_FUTURE): 1 and 2 on most architectures (x86, arm, aarch64, riscv);
    0x2000 and 0x4000 on powerpc, sparc and alpha (asm/mman.h)."""
    if platform.machine().startswith(('ppc', 'powerpc', 'sparc', 'alpha')):
        return 0x2000, 0x4000
    return 1, 2


def locked_memory_kb(pid: int | str = 'self') -> int:
    """VmLck of /proc/<pid>/status: the process's locked memory (kB); 0 if not readable."""
    try:
        with open(f'/proc/{pid}/status') as f:
            for line in f:
                if line.startswith('VmLck:'):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return 0


def lock_memory() -> Grant:
    """mlockall(MCL_CURRENT | MCL_FUTURE): every page of the process, now and later, stays in
    RAM (no page fault to disk, no swap-out on the 1 kHz path). The whole process, every thread.
    Later allocations then fail rather than go beyond RLIMIT_MEMLOCK (no limit with
    CAP_IPC_LOCK)."""
    libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6', use_errno=True)
    current, future = _mcl_flags()
    if libc.mlockall(current | future) == 0:
        return Grant(True, 'memory locked (mlockall MCL_CURRENT|MCL_FUTURE): '
                           f'{locked_memory_kb() / 1024:.0f} MiB of the process locked now, every '
                           'later page too')
    code = ctypes.get_errno()
    soft = resource.getrlimit(resource.RLIMIT_MEMLOCK)[0]
    if code in (errno.ENOMEM, errno.EPERM) and not has_capability(CAP_IPC_LOCK):
        limit = 'unlimited' if soft == resource.RLIM_INFINITY else f'{soft // 1024} KiB'
        why = (f'{errno.errorcode[code]}: no CAP_IPC_LOCK and RLIMIT_MEMLOCK {limit} is less '
               'than the process')
    else:
        why = f'{errno.errorcode.get(code, code)}: {os.strerror(code)}'
    return Grant(False, f'memory lock refused: {why}; pages may be faulted in or swapped on the '
                        f'1 kHz path; {MEMLOCK_HOWTO}')


# --- the kernel -------------------------------------------------------------------------------

def has_realtime_kernel() -> bool:
    """Whether the kernel is a PREEMPT_RT one (/sys/kernel/realtime, or PREEMPT_RT in its
    version string), as realtime_tools' has_realtime_kernel tells it."""
    try:
        with open('/sys/kernel/realtime') as f:
            if f.read().strip() == '1':
                return True
    except OSError:
        pass
    return 'PREEMPT_RT' in os.uname().version
