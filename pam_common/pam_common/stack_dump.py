"""Where is a node stuck? `kill -USR1 PID` prints the stack of every thread of a PAM node.

faulthandler writes the stacks from the signal handler itself (C code, no GIL needed), so it
works while the process is deadlocked, and the node runs on afterwards. Every node started by
pam_common.executors.run_node enables it; pam-bringup sends the signal to a node that did not
stop, before it kills it. No rclpy import here: pam-bringup uses the constant.
"""

from __future__ import annotations

import faulthandler
import signal

STACK_DUMP_SIGNAL = signal.SIGUSR1


def enable_stack_dump() -> None:
    """STACK_DUMP_SIGNAL prints every thread's stack to stderr (instead of ending the process)."""
    faulthandler.register(STACK_DUMP_SIGNAL, all_threads=True)
