"""pam-bringup's stop escalation on a child that hangs: SIGINT, SIGTERM, then the child's stacks
(SIGUSR1, pam_common.stack_dump) in the log, then SIGKILL, and a failed exit. A real child
process and real signals; the time limits shortened."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
import time

from pam_bringup import bringup as bringup_module
from pam_bringup.bringup import Bringup, Child, NodeSpec, Output

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


def test_a_child_that_does_not_stop_has_its_stacks_printed_then_is_killed(monkeypatch, capsys):
    monkeypatch.setattr(bringup_module, 'SIGTERM_AFTER', 0.5)
    monkeypatch.setattr(bringup_module, 'STOP_TIMEOUT', 1.5)
    child = Child(NodeSpec('hung_node', 'pam_bringup', 'test'), [sys.executable, '-c', HUNG])
    run = Bringup([child], dict(os.environ), Output([child.name], colour=False), log_dir=None)
    run.start()
    out = ''
    end = time.monotonic() + 30.0
    while 'ready' not in out and time.monotonic() < end:
        time.sleep(0.05)
        out += capsys.readouterr().out
    assert 'ready' in out, out
    try:
        run.stop()
    finally:
        if child.proc.poll() is None:
            child.proc.kill()
    out += capsys.readouterr().out
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


def test_a_child_without_the_stack_dump_is_still_killed(monkeypatch, capsys):
    """SIGUSR1 ends a process that did not enable the dump (its default action): still an
    unclean stop, reported as such."""
    monkeypatch.setattr(bringup_module, 'SIGTERM_AFTER', 0.5)
    monkeypatch.setattr(bringup_module, 'STOP_TIMEOUT', 1.5)
    plain = HUNG.replace('enable_stack_dump()', '')
    child = Child(NodeSpec('plain_node', 'pam_bringup', 'test'), [sys.executable, '-c', plain])
    run = Bringup([child], dict(os.environ), Output([child.name], colour=False), log_dir=None)
    run.start()
    end = time.monotonic() + 30.0
    out = ''
    while 'ready' not in out and time.monotonic() < end:
        time.sleep(0.05)
        out += capsys.readouterr().out
    try:
        run.stop()
    finally:
        if child.proc.poll() is None:
            child.proc.kill()
    assert run.report([]) == 1
    out += capsys.readouterr().out
    assert child.proc.returncode in (-9, -10), child.proc.returncode
    assert 'plain_node did not stop cleanly' in out, out


def test_stack_dump_signal_is_not_one_the_nodes_stop_on():
    from pam_common.stack_dump import STACK_DUMP_SIGNAL
    assert STACK_DUMP_SIGNAL not in (bringup_module.signal.SIGINT, bringup_module.signal.SIGTERM)
    assert subprocess.signal.Signals(STACK_DUMP_SIGNAL).name == 'SIGUSR1'
