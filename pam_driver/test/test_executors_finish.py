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
