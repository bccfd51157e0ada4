"""The process-wide knobs are set once, by run_nodes (pam_common.executors), for whichever nodes
a process holds: a node process sees the short thread switch interval while its nodes are built,
and no node module sets it itself (it used to be set by sim_node's start and driver_node's
constructor, so a composed process's interval depended on which rig it held)."""

import re
import subprocess
import sys
import textwrap
from pathlib import Path

from pam_common import executors
from pam_common.testing import child_env

ROOT = Path(__file__).resolve().parents[2]
KNOB_CALL = re.compile(r'\bsetswitchinterval\s*\(')

NODE = textwrap.dedent('''
    import sys
    from rclpy.node import Node
    from rclpy.task import Future
    from pam_common.executors import run_node

    class Knobs(Node):
        def __init__(self):
            super().__init__('knobs_test_node')
            print('switch interval', sys.getswitchinterval(), flush=True)
            self.finished = Future()
            self.finished.set_result(None)

        def finish(self):
            return 0

    print('before', sys.getswitchinterval(), flush=True)
    sys.exit(run_node(Knobs, 'knobs_test_node'))
''')


def test_run_nodes_sets_the_switch_interval_before_the_nodes_are_built(ros_domain):
    done = subprocess.run([sys.executable, '-c', NODE], capture_output=True, text=True,
                          env=child_env(ros_domain), timeout=60)
    assert done.returncode == 0, done.stderr
    lines = dict(line.rsplit(' ', 1) for line in done.stdout.splitlines())
    assert float(lines['before']) == 0.005                  # Python's default
    assert float(lines['switch interval']) == executors.SWITCH_INTERVAL


def test_only_run_nodes_sets_the_switch_interval():
    sources = [f for package in ROOT.glob('pam_*/package.xml')
               for f in (package.parent / package.parent.name).rglob('*.py')]
    assert len(sources) > 20
    setters = sorted(str(f.relative_to(ROOT)) for f in sources if KNOB_CALL.search(f.read_text()))
    assert setters == ['pam_common/pam_common/executors.py']


COMPONENT = textwrap.dedent('''
    import gc
    import sys
    from rclpy.node import Node
    from rclpy.task import Future
    from pam_common.executors import run_nodes
    from pam_common.node_skeleton import Component

    class Starts(Node):
        def __init__(self):
            super().__init__('freeze_test_node')
            print('built', gc.get_freeze_count(), flush=True)
            self.finished = Future()

        def finish(self):
            return 0

    def start(node):
        print('started', gc.get_freeze_count(), flush=True)
        node.finished.set_result(None)

    sys.exit(run_nodes([Component('freeze_test_node', Starts, start=start)], 'freeze_test'))
''')


def test_run_nodes_freezes_the_heap_before_any_node_starts(ros_domain):
    """The full collection before gc.freeze takes tens of ms in a process holding rclpy, numpy
    and numba: done after sim_node's sampler started, it stalled the first samples (a 90 ms
    stall, 89 samples missed, measured on the development machine)."""
    done = subprocess.run([sys.executable, '-c', COMPONENT], capture_output=True, text=True,
                          env=child_env(ros_domain), timeout=60)
    assert done.returncode == 0, done.stderr
    counts = dict(line.rsplit(' ', 1) for line in done.stdout.splitlines())
    assert int(counts['built']) == 0
    assert int(counts['started']) > 1000       # the imported modules and the node, frozen
