"""sim_node's real-time knobs (thread_priority, cpu_affinity, lock_memory), a real
process checked from the outside.

Granted (this machine runs the tests as root: SCHED_FIFO and mlockall are permitted): the INFO
lines name the executor thread (the main thread: its tid is the pid) and the sampler thread with
their tids; /proc/<pid>/task/<tid>/stat (rt_priority, field 40; policy, field 41) and
/proc/<pid>/task/<tid>/status (Cpus_allowed_list) show both threads at SCHED_FIFO 50 on CPU 0,
and /proc/<pid>/status VmLck the memory locked; the middleware's threads, started with the node
before its constructor applied the knobs, keep normal scheduling; /diagnostics reports the same.

Refused: the same node started through prlimit (RLIMIT_RTPRIO 0, RLIMIT_MEMLOCK 64 KiB) and
setpriv (CAP_SYS_NICE and CAP_IPC_LOCK dropped from the bounding set, so root's exec does not
regain them), as for a user with no limits.conf entry: a WARN line per refused knob saying what
to set, normal scheduling, the affinity still granted (it needs no privilege), and the node runs
on: it publishes its samples and its /diagnostics status is WARN naming the refused knobs.
"""

from __future__ import annotations

import os
import shutil

import pytest
from diagnostic_msgs.msg import DiagnosticArray

from pam_common.diagnostics import status_values
from pam_common.testing import (
    NodeProcess,
    child_env,
    log_lines,
    logged_tid,
    process_locked_kb,
    thread_state,
)
from pam_interfaces.msg import Pressures

STARTUP = 45.0                 # s, first message from a fresh process (loaded machine)
KNOBS = ('-p', 'thread_priority:=50', '-p', 'cpu_affinity:=[0]', '-p', 'lock_memory:=true')
SCHED_OTHER, SCHED_FIFO = os.SCHED_OTHER, os.SCHED_FIFO
UNPRIVILEGED = ['prlimit', '--rtprio=0', '--memlock=65536:65536', 'setpriv',
                '--inh-caps=-sys_nice,-ipc_lock', '--bounding-set=-sys_nice,-ipc_lock', '--']

pytestmark = pytest.mark.skipif(os.geteuid() != 0, reason='the granted path needs root here')


def wait_for_lines(process, severity: str, texts: list[str]) -> list[str]:
    process.wait_for(lambda: all(any(t in line for line in log_lines(process.stderr, severity,
                                                                         'pam.sim_node'))
                                 for t in texts), STARTUP, f'the {severity} lines {texts}')
    return log_lines(process.stderr, severity, 'pam.sim_node')


def latest_status(diagnostics) -> tuple[int, str, dict]:
    for _, msg in reversed(diagnostics.items()):
        for status in msg.status:
            if status.name.startswith('/pam/sim_node: '):
                return status.level[0], status.message, status_values(status)
    return -1, '', {}


def assert_runs_on(process, probe, helpers) -> None:
    """The node publishes samples with a counter that advances."""
    samples = probe.subscribe(Pressures, '/pam/pressures')
    process.wait_for(lambda: len(samples) > 200, STARTUP, '200 pressure samples')
    counters = [m.sample for m in samples.messages()]
    assert counters == sorted(counters) and counters[-1] - counters[0] >= 199


def test_granted_to_the_executor_and_the_sampler_thread(sim_node, probe, helpers):
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics')
    sim = sim_node(*KNOBS)
    info = wait_for_lines(sim, 'INFO', [
        'SCHED_FIFO priority 50 granted to thread executor (tid ',
        'SCHED_FIFO priority 50 granted to thread sim_node_sampler (tid ',
        'CPU affinity 0 granted to thread executor (tid ',
        'CPU affinity 0 granted to thread sim_node_sampler (tid ',
        'memory locked (mlockall MCL_CURRENT|MCL_FUTURE): '])
    pid = sim.proc.pid
    executor = logged_tid(info, 'granted to thread executor')
    sampler = logged_tid(info, 'granted to thread sim_node_sampler')
    assert executor == pid                       # the main thread spins the executor
    assert sampler != pid
    for tid in (executor, sampler):
        state = thread_state(pid, tid)
        assert (state['policy'], state['rt_priority'], state['cpus']) == (SCHED_FIFO, 50, '0'), \
            (tid, state)
    assert process_locked_kb(pid) > 10 * 1024
    middleware = [thread_state(pid, int(t)) for t in os.listdir(f'/proc/{pid}/task')]
    middleware = [s for s in middleware if s['comm'].startswith('dds.')]
    assert middleware and all(s['policy'] == SCHED_OTHER for s in middleware), middleware
    assert log_lines(sim.stderr, 'WARN', 'pam.sim_node') == []
    assert_runs_on(sim, probe, helpers)
    sim.wait_for(lambda: 'sim_node_sampler thread' in latest_status(diagnostics)[2], STARTUP,
                 'the knobs on /diagnostics')
    _, _, values = latest_status(diagnostics)
    assert values['executor thread'] == 'SCHED_FIFO priority 50, CPUs 0'
    assert values['sim_node_sampler thread'] == 'SCHED_FIFO priority 50, CPUs 0'
    assert float(values['memory locked (MiB)']) > 10.0


@pytest.mark.skipif(not (shutil.which('setpriv') and shutil.which('prlimit')),
                    reason='setpriv and prlimit (util-linux) drop the privileges')
def test_refused_without_the_privileges_the_node_warns_and_runs_on(ros_domain, tmp_path, probe,
                                                                   helpers, request):
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics')
    sim = NodeProcess('sim_node', 'pam_driver', ['--ros-args', *KNOBS], child_env(ros_domain),
                      cwd=tmp_path, prefix=UNPRIVILEGED)
    try:
        warn = wait_for_lines(sim, 'WARN', [
            'SCHED_FIFO priority 50 refused for thread executor (tid ',
            'SCHED_FIFO priority 50 refused for thread sim_node_sampler (tid ',
            'memory lock refused: '])
        fifo = [line for line in warn if 'SCHED_FIFO' in line]
        assert all('EPERM: no CAP_SYS_NICE and RLIMIT_RTPRIO 0 < 50' in line and 'ulimit -r' in
                   line and '--cap-add SYS_NICE' in line for line in fifo), fifo
        memory = [line for line in warn if 'memory lock refused' in line]
        assert 'no CAP_IPC_LOCK' in memory[0] and 'ulimit -l unlimited' in memory[0], memory
        info = wait_for_lines(sim, 'INFO', ['CPU affinity 0 granted to thread sim_node_sampler'])
        pid = sim.proc.pid
        sampler = logged_tid(warn, 'thread sim_node_sampler')
        for tid in (logged_tid(warn, 'thread executor'), sampler):
            state = thread_state(pid, tid)
            assert (state['policy'], state['rt_priority'], state['cpus']) == (SCHED_OTHER, 0,
                                                                              '0'), state
        assert logged_tid(info, 'thread sim_node_sampler') == sampler
        assert process_locked_kb(pid) == 0
        assert_runs_on(sim, probe, helpers)
        sim.wait_for(lambda: 'real-time knobs refused' in latest_status(diagnostics)[1],
                     STARTUP, 'the refused knobs on /diagnostics')
        level, message, values = latest_status(diagnostics)
        assert level >= 1, message              # WARN (or worse)
        assert 'SCHED_FIFO priority 50 refused for thread executor' in message
        assert 'memory lock refused' in message
        assert values['executor thread'] == 'SCHED_OTHER, CPUs 0'
        assert sim.stop() == 0, sim.stderr
    finally:
        request.node.add_report_section('teardown', 'sim_node stderr', sim.stderr)
        sim.close()
