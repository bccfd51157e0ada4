"""run_node: a finite node's finish() (bag_record closing its bag) is not cut short by a second
Ctrl-C: a real process, real signals."""

import signal
import subprocess
import sys
import textwrap

from pam_driver.testing import child_env

NODE = textwrap.dedent('''
    import os, signal, sys, time
    from rclpy.node import Node
    from rclpy.task import Future
    from pam_driver.executors import run_node

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


HANGING = textwrap.dedent('''
    import sys, time
    from rclpy.node import Node
    from pam_driver.executors import run_node

    class Hanging(Node):
        def __init__(self):
            super().__init__('hanging_test_node')
            self.timer = self.create_timer(0.05, self.spinning)

        def spinning(self):
            self.destroy_timer(self.timer)
            print('spinning', flush=True)

    def stop_that_hangs(node):
        time.sleep(60)                               # a shutdown that never completes

    sys.exit(run_node(Hanging, 'hanging_test_node', stop=stop_that_hangs))
''')


def test_a_node_that_hangs_at_shutdown_exits_with_its_stacks(ros_domain):
    """ShutdownWatchdog: SHUTDOWN_GRACE after Ctrl-C the hung process prints its threads'
    stacks (naming where it hangs) and exits with code 1, instead of waiting for SIGKILL."""
    import time
    from pam_driver.executors import SHUTDOWN_GRACE
    process = subprocess.Popen([sys.executable, '-c', HANGING], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=child_env(ros_domain))
    assert process.stdout.readline().strip() == 'spinning'
    start = time.monotonic()
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=30)
    took = time.monotonic() - start
    assert process.returncode == 1, err
    assert SHUTDOWN_GRACE - 0.5 < took < SHUTDOWN_GRACE + 5.0, took
    assert 'Timeout' in err and 'stop_that_hangs' in err, err
