"""run_node's stop, on real processes and real signals: a finite node's finish() (bag_record
closing its bag) is not cut short by a second Ctrl-C; a node that hangs at shutdown (asleep, or
blocking with the GIL held) exits with its stacks (ShutdownWatchdog); SIGUSR1 prints the stacks
of a running node; a second Ctrl-C interrupts a node that does not stop; a node on simulated time
(rclpy's default executor) stops at once."""

import signal
import subprocess
import sys
import textwrap

import pytest

from pam_common.testing import child_env

NODE = textwrap.dedent('''
    import os, signal, sys, time
    from rclpy.node import Node
    from rclpy.task import Future
    from pam_common.executors import run_node

    class Finite(Node):
        def __init__(self):
            super().__init__('finite_test_node')
            self.finished = Future()
            self.timer = self.create_timer(0.05, self.spinning)

        def spinning(self):
            if self.timer is not None:
                self.destroy_timer(self.timer)
                self.timer = None
                print('spinning', flush=True)

        def finish(self):
            os.kill(os.getpid(), signal.SIGINT)      # the user presses Ctrl-C again
            time.sleep(0.3)                          # ... while the output is being closed
            print('finished', flush=True)
            return 0

    sys.exit(run_node(Finite, 'finite_test_node'))
''')


def test_a_second_ctrl_c_does_not_cut_finish_short(ros_domain):
    process = subprocess.Popen([sys.executable, '-c', NODE], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=child_env(ros_domain))
    assert process.stdout.readline().strip() == 'spinning'
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=30)
    assert process.returncode == 0, err
    assert 'finished' in out and 'KeyboardInterrupt' not in err


def spinning_node(stop_body: str) -> str:
    """A node that prints 'spinning' once spinning, then idles; its stop hook runs stop_body."""
    return textwrap.dedent('''
        import ctypes, sys, time
        from rclpy.node import Node
        from pam_common.executors import run_node

        class Spinning(Node):
            def __init__(self):
                super().__init__('spinning_test_node')
                self.timer = self.create_timer(0.05, self.spinning)

            def spinning(self):
                self.destroy_timer(self.timer)
                print('spinning', flush=True)

        def stop_hook(node):
            STOP_BODY

        sys.exit(run_node(Spinning, 'spinning_test_node', stop=stop_hook))
    ''').replace('STOP_BODY', stop_body)


HANGING = spinning_node('time.sleep(60)')           # a shutdown that never completes
# blocks in C *holding the GIL* (PyDLL does not release it), as a deadlock between the GIL and a
# lock in a C extension would: no Python thread runs any more
GIL_HANG = spinning_node('ctypes.PyDLL(None).sleep(60)')
IDLE_AT_STOP = spinning_node("print('ROS up at stop:', node.context.ok(), flush=True)")


def start_spinning(script: str, ros_domain, *args) -> subprocess.Popen:
    """The script as a process, once it printed its first line ('spinning' / 'started')."""
    process = subprocess.Popen([sys.executable, '-c', script, *args], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=child_env(ros_domain))
    assert process.stdout.readline().strip() in ('spinning', 'started')
    return process


@pytest.mark.parametrize('script', [HANGING, GIL_HANG], ids=['sleeping', 'gil_held'])
def test_a_node_that_hangs_at_shutdown_exits_with_its_stacks(ros_domain, script):
    """ShutdownWatchdog: SHUTDOWN_GRACE after Ctrl-C the hung process prints its threads'
    stacks (naming where it hangs) and exits with code 1, instead of waiting for SIGKILL. Armed
    by the main thread when the stop begins: also when the stop blocks every Python thread at
    once (GIL held)."""
    import time

    from pam_common.executors import SHUTDOWN_GRACE
    process = start_spinning(script, ros_domain)
    start = time.monotonic()
    process.send_signal(signal.SIGINT)
    _out, err = process.communicate(timeout=30)
    took = time.monotonic() - start
    assert process.returncode == 1, err
    assert SHUTDOWN_GRACE - 0.5 < took < SHUTDOWN_GRACE + 5.0, took
    assert 'Timeout' in err and 'stop_hook' in err, err


WATCHDOG_ARMED = textwrap.dedent('''
    import ctypes, rclpy
    from pam_common.executors import ShutdownWatchdog
    rclpy.init()
    watchdog = ShutdownWatchdog(rclpy.get_default_context(), grace=0.5)
    watchdog.arm()                     # the context stays up: only arm() can start the countdown
    print('armed', flush=True)
    ctypes.PyDLL(None).sleep(30)       # hung, GIL held
''')


def test_the_watchdog_armed_without_a_shutdown_still_fires(ros_domain):
    process = subprocess.Popen([sys.executable, '-c', WATCHDOG_ARMED], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=child_env(ros_domain))
    out, err = process.communicate(timeout=20)
    assert out.strip() == 'armed'
    assert process.returncode == 1 and 'Timeout' in err and '<module>' in err, err


def test_sigusr1_prints_the_stacks_and_the_node_runs_on(ros_domain):
    """`kill -USR1` on a node started by run_node prints every thread's stack (stack_dump),
    the main thread's in the spin; the node runs on and still stops cleanly on Ctrl-C."""
    import re
    import time

    from pam_common.stack_dump import STACK_DUMP_SIGNAL
    process = start_spinning(IDLE_AT_STOP, ros_domain)
    process.send_signal(STACK_DUMP_SIGNAL)
    time.sleep(1.0)
    assert process.poll() is None, 'SIGUSR1 ended the node'
    start = time.monotonic()
    process.send_signal(signal.SIGINT)        # the node is idle: no callback runs any more
    out, err = process.communicate(timeout=30)
    assert process.returncode == 0, err
    assert time.monotonic() - start < 3.0     # SPIN_SLICE + the shutdown, on a loaded machine
    assert 'ROS up at stop: True' in out      # the stop hook (driver_node's safe output) first
    assert re.search(r'Current thread 0x[0-9a-f]+ \(most recent call first\):\n'
                     r'(  File .*\n)*?  File ".*executors\.py", line \d+ in spin\n', err), err
    assert re.search(r'^Thread 0x[0-9a-f]+ ', err, flags=re.MULTILINE), err   # the other threads


def test_a_second_ctrl_c_interrupts_a_node_that_does_not_stop(ros_domain):
    """StopSignals: the first Ctrl-C asks for a stop; a second one raises KeyboardInterrupt
    where the node is (here in a stop that would hang), well before the watchdog's grace."""
    import time

    from pam_common.executors import SHUTDOWN_GRACE
    process = start_spinning(HANGING, ros_domain)
    process.send_signal(signal.SIGINT)
    time.sleep(1.0)
    assert process.poll() is None                  # in stop_hook
    start = time.monotonic()
    process.send_signal(signal.SIGTERM)
    _out, err = process.communicate(timeout=30)
    assert time.monotonic() - start < SHUTDOWN_GRACE - 1.0
    assert process.returncode == -signal.SIGINT, err   # an uncaught KeyboardInterrupt's exit
    assert 'KeyboardInterrupt' in err and 'stop_hook' in err and 'Timeout' not in err, err


IDLE = textwrap.dedent('''
    import sys
    from rclpy.node import Node
    from pam_common.executors import run_node

    class Idle(Node):
        def __init__(self):
            super().__init__('idle_test_node')
            print('started', flush=True)

    sys.exit(run_node(Idle, 'idle_test_node', args=sys.argv))
''')


def test_a_node_on_simulated_time_stops_on_ctrl_c_too(ros_domain):
    """use_sim_time: rclpy's default executor (spun with spin_once slices), no /clock, no
    callback at all: Ctrl-C still stops it at once, cleanly."""
    import time
    process = start_spinning(IDLE, ros_domain, '--ros-args', '-p', 'use_sim_time:=true')
    time.sleep(1.0)
    start = time.monotonic()
    process.send_signal(signal.SIGTERM)
    _out, err = process.communicate(timeout=30)
    assert process.returncode == 0, err
    assert time.monotonic() - start < 3.0
