"""pam-bringup's stop escalation (pam_bringup.supervisor) on a child that hangs: SIGINT, SIGTERM,
then the child's stacks (SIGUSR1, pam_common.stack_dump) in the log, then SIGKILL, and a failed
exit. A real child process and real signals; the time limits shortened."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
import time

from pam_bringup.supervisor import STOP_SIGNALS, Child, Output, Supervisor

SIGTERM_AFTER = 0.5   # s (5 s in pam-bringup)
STOP_TIMEOUT = 1.5    # s (10 s)

HUNG = textwrap.dedent('''
    import signal, time
    from pam_common.stack_dump import enable_stack_dump
    signal.signal(signal.SIGINT, signal.SIG_IGN)      # deaf to SIGINT and SIGTERM, as a node
    signal.signal(signal.SIGTERM, signal.SIG_IGN)     # stuck in a deadlock would be
    enable_stack_dump()

    def hung_right_here():
        print('ready', flush=True)
        while True:
            time.sleep(0.1)

    hung_right_here()
''')


def stop_when_ready(name: str, script: str, capsys) -> tuple[Supervisor, Child, str]:
    """Supervise `python -c script` as `name`; once it printed 'ready' itself (the 'started'
    line quotes the script, 'ready' included), stop it: (supervisor, child, our output)."""
    child = Child(name, [sys.executable, '-c', script], 'test')
    run = Supervisor([child], dict(os.environ), Output('pam-bringup', [child.name], colour=False),
                     sigterm_after=SIGTERM_AFTER, stop_timeout=STOP_TIMEOUT)
    run.start()
    end = time.monotonic() + 30.0
    while 'ready' not in child.tail and time.monotonic() < end:
        time.sleep(0.05)
    assert 'ready' in child.tail, list(child.tail)
    try:
        run.stop()
    finally:
        if child.proc.poll() is None:
            child.proc.kill()
    return run, child, capsys.readouterr().out


def test_a_child_that_does_not_stop_has_its_stacks_printed_then_is_killed(capsys):
    run, child, out = stop_when_ready('hung_node', HUNG, capsys)
    assert run.report([]) == 1
    out += capsys.readouterr().out
    assert 'sending SIGTERM' in out
    assert "hung_node: printing their threads' stacks (SIGUSR1), then killing" in out, out
    # the stack, forwarded with the child's prefix, before the kill
    stack = re.search(r'^\[hung_node\]\s+File "<string>", line \d+ in hung_right_here$', out,
                      flags=re.MULTILINE)
    assert stack and stack.start() < out.index('did not stop cleanly'), out
    assert child.proc.returncode == -9 and child.killed
    assert 'hung_node did not stop cleanly' in out and 'killed by SIGKILL' in out, out


def test_a_child_without_the_stack_dump_is_still_killed(capsys):
    """SIGUSR1 ends a process that did not enable the dump (its default action): still an
    unclean stop, reported as such."""
    plain = HUNG.replace('enable_stack_dump()', '')
    run, child, out = stop_when_ready('plain_node', plain, capsys)
    assert run.report([]) == 1
    out += capsys.readouterr().out
    assert child.proc.returncode in (-9, -10), (child.proc.returncode, list(child.tail))
    assert 'plain_node did not stop cleanly' in out, out


def test_stack_dump_signal_is_not_one_the_nodes_stop_on():
    from pam_common.stack_dump import STACK_DUMP_SIGNAL
    assert STACK_DUMP_SIGNAL not in STOP_SIGNALS
    assert subprocess.signal.Signals(STACK_DUMP_SIGNAL).name == 'SIGUSR1'
