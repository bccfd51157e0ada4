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

import rclpy
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.task import Future

SPIN_SLICE = 0.5  # s, longest time the executor blocks before re-checking the context


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
        executor.spin_until_future_complete(never, timeout_sec=SPIN_SLICE)
    raise rclpy.executors.ExternalShutdownException()
