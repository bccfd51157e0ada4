"""driver_node's real-time knobs: against pam-emulator over a real pty, with
thread_priority 40 and cpu_affinity [1], the executor thread (the main thread) and the serial
reader thread (`driver_reader`) are logged at INFO with their tids and run at SCHED_FIFO 40 on
CPU 1 (/proc/<pid>/task/<tid>), the samples stream, and /diagnostics reports both threads."""

import os

import pytest

from pam_common.testing import log_lines, logged_tid, thread_state
from test_driver_node import STARTUP, Rig  # the same test folder (pytest's prepend import mode)

LOGGER = 'pam.driver_node'

pytestmark = pytest.mark.skipif(os.geteuid() != 0 or (os.cpu_count() or 1) < 2,
                                reason='SCHED_FIFO needs root here; CPU 1 a second CPU')


def test_executor_and_reader_thread(node_process, probe, helpers, tmp_path):
    r = Rig(node_process, probe, helpers, tmp_path,
            driver_params=('thread_priority:=40', 'cpu_affinity:=[1]'))
    wanted = ('SCHED_FIFO priority 40 granted to thread executor (tid ',
              'CPU affinity 1 granted to thread executor (tid ',
              'SCHED_FIFO priority 40 granted to thread driver_reader (tid ',
              'CPU affinity 1 granted to thread driver_reader (tid ')
    r.driver.wait_for(lambda: all(any(w in line for line in log_lines(r.driver.stderr, 'INFO',
                                                                        LOGGER))
                                  for w in wanted), STARTUP, f'the INFO lines {wanted}')
    info = log_lines(r.driver.stderr, 'INFO', LOGGER)
    pid = r.driver.proc.pid
    executor = logged_tid(info, 'thread executor')
    reader = logged_tid(info, 'thread driver_reader')
    assert executor == pid and reader != pid
    for tid in (executor, reader):
        state = thread_state(pid, tid)
        assert (state['policy'], state['rt_priority'], state['cpus']) == (os.SCHED_FIFO, 40,
                                                                          '1'), (tid, state)
    count = len(r.pressures)
    r.driver.wait_for(lambda: len(r.pressures) > count + 200, STARTUP, '200 more samples')
    r.driver.wait_for(lambda: 'driver_reader thread' in r.values(), STARTUP,
                      'the knobs on /diagnostics')
    values = r.values()
    assert values['executor thread'] == 'SCHED_FIFO priority 40, CPUs 1'
    assert values['driver_reader thread'] == 'SCHED_FIFO priority 40, CPUs 1'
    assert log_lines(r.driver.stderr, 'WARN', LOGGER) == []
