"""Executor choice and spinning shared by the PAM nodes.

rclpy.experimental.EventsExecutor cuts the cost of a 1 kHz subscription to about half of the
default executor's. But with the Jazzy wheels (ros-rclpy 7.1.6 on PyPI) its blocking spin() with
no timeout busy-waits (a full core while idle) and never returns on Ctrl-C. Spinning it in bounded
slices (spin_until_future_complete on a future that never completes, with a timeout) blocks
properly and lets SIGINT through as KeyboardInterrupt / ExternalShutdownException. Use
spin(executor) below instead of executor.spin().

EventsExecutor timers do not follow /clock under use_sim_time: nodes that run on simulated time
must ask for the default executor (events=False).
"""

from __future__ import annotations

import faulthandler
import signal
import sys
import threading
import time
from contextlib import contextmanager

import rclpy
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.task import Future

SPIN_SLICE = 0.5  # s, longest time the executor blocks before re-checking the context
SHUTDOWN_GRACE = 4.5  # s a node has to exit after Ctrl-C/SIGTERM (pam-bringup escalates at 5 s)
SHUTDOWN_SETTLE = 1.0  # s an executor error may precede the context's shutdown on Ctrl-C


def make_executor(events: bool = True, context=None):
    """EventsExecutor if events and available, else SingleThreadedExecutor."""
    if events:
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor(context=context)
        except ImportError:
            pass
    return SingleThreadedExecutor(context=context)


def is_events_executor(executor) -> bool:
    return not isinstance(executor, Executor)


def spin(executor, context=None) -> None:
    """Execute callbacks until the context shuts down (e.g. on Ctrl-C).

    Raises what executor.spin() raises on Ctrl-C (KeyboardInterrupt or
    ExternalShutdownException): catch both in main().
    """
    if not is_events_executor(executor):
        executor.spin()
        return
    context = context if context is not None else executor.context
    never = Future()
    while context.ok():
        try:
            executor.spin_until_future_complete(never, timeout_sec=SPIN_SLICE)
        except RuntimeError:
            # The wheels' EventsExecutor can raise "Unable to convert call argument" when the
            # context shuts down under it (Ctrl-C): that is a shutdown, not a failure.
            if not shuts_down(context):
                raise
    raise rclpy.executors.ExternalShutdownException()


def shuts_down(context, within: float = SHUTDOWN_SETTLE) -> bool:
    """True if the context is shut down or goes down within `within` s. After Ctrl-C the
    executor can fail (a callback torn down under it) a moment before rclpy's signal handling
    has marked the context shut down: an error then is part of the shutdown, not a failure."""
    end = time.monotonic() + within
    while context.ok():
        if time.monotonic() >= end:
            return False
        time.sleep(0.01)
    return True


@contextmanager
def interrupts_deferred():
    """SIGINT and SIGTERM ignored inside the block (main thread only): a node finishing its
    output, e.g. bag_record closing its bag, is not cut short by a second Ctrl-C."""
    try:
        previous = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:          # not the main thread: nothing to defer
        previous = {}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


class ShutdownWatchdog:
    """Once the ROS context is shut down (Ctrl-C, SIGTERM), the process must be gone within
    `grace` s; if not, faulthandler (a C thread, it needs no GIL) prints every thread's stack to
    stderr and exits with code 1. A node that hangs at shutdown (seen once in CI: pi_node ignored
    SIGINT and SIGTERM and was killed, cause not reproduced) then ends with a diagnosis instead
    of waiting for SIGKILL. disarm() before intended work after a stop (a finite node's
    finish(), e.g. bag_record closing its bag)."""

    def __init__(self, context, grace: float = SHUTDOWN_GRACE):
        self._lock = threading.Lock()
        self._disarmed = False
        self._grace = grace
        threading.Thread(target=self._watch, args=(context,), name='shutdown_watchdog',
                         daemon=True).start()

    def _watch(self, context) -> None:
        while context.ok():
            time.sleep(0.1)
        with self._lock:
            if not self._disarmed:
                faulthandler.dump_traceback_later(self._grace, exit=True)

    def disarm(self) -> None:
        with self._lock:
            self._disarmed = True
            faulthandler.cancel_dump_traceback_later()


def run_node(node_factory, name: str, args=None, stop=None) -> int:
    """The main() of a PAM node: init, build the node, spin, shut down.

    Returns the exit code: 0 after Ctrl-C/SIGTERM, 2 when the node's configuration is invalid
    (ConfigError, printed as one line). An exception raised because the context was shut down
    while the node was still starting (an early Ctrl-C) also counts as a clean stop.
    The executor is an EventsExecutor unless the node runs on simulated time.
    A node with a `finished` Future runs until it completes (or Ctrl-C), and its `finish()` gives
    the exit code; further SIGINT/SIGTERM are ignored while it finishes. `stop(node)`, if given,
    runs before the node is destroyed. Any other node must be gone SHUTDOWN_GRACE s after
    Ctrl-C/SIGTERM (ShutdownWatchdog).
    """
    from .node_params import ConfigError
    rclpy.init(args=args)
    watchdog = ShutdownWatchdog(rclpy.get_default_context())
    node = None
    try:
        try:
            node = node_factory()
            executor = make_executor(events=not node.get_parameter('use_sim_time').value)
            executor.add_node(node)
            if getattr(node, 'finished', None) is None:
                spin(executor)
            else:
                while rclpy.ok() and not node.finished.done():
                    executor.spin_until_future_complete(node.finished, timeout_sec=SPIN_SLICE)
        except ConfigError as exc:
            print(f'[{name}] error: {exc}', file=sys.stderr)
            return 2
        except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
            pass
        except Exception:
            if not shuts_down(rclpy.get_default_context()):
                raise
        if getattr(node, 'finished', None) is not None:   # also after an early Ctrl-C
            watchdog.disarm()
            with interrupts_deferred():
                return node.finish()
        return 0
    finally:
        if node is not None:
            if stop is not None:
                stop(node)
            node.destroy_node()
        rclpy.try_shutdown()
