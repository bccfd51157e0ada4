"""pam_common.executors.shuts_down: an executor error while the context is being shut down
counts as part of the shutdown only if the ROS context really goes down (real rclpy contexts, no
ROS graph needed)."""

import threading
import time

import rclpy
from rclpy.context import Context

from pam_common.executors import shuts_down


def fresh_context() -> Context:
    context = Context()
    rclpy.init(context=context)
    return context


def test_a_context_going_down_a_moment_later_counts_as_shutting_down():
    context = fresh_context()
    threading.Timer(0.2, context.shutdown).start()
    start = time.monotonic()
    assert shuts_down(context, within=2.0)
    assert 0.15 < time.monotonic() - start < 1.5


def test_a_context_that_stays_up_does_not():
    context = fresh_context()
    start = time.monotonic()
    assert not shuts_down(context, within=0.3)
    assert time.monotonic() - start >= 0.3
    context.shutdown()


def test_a_context_already_down_answers_at_once():
    context = fresh_context()
    context.shutdown()
    start = time.monotonic()
    assert shuts_down(context, within=5.0)
    assert time.monotonic() - start < 0.5


def _spin_with_a_failing_callback(stop_requested: bool):
    """spin() on a real executor whose timer callback fails as the EventsExecutor does when a
    second stop signal lands in a callback's argument conversion; the first signal recorded
    (or not) just before. Returns what spin() raised (None if it returned)."""
    from pam_common.executors import StopSignals, make_executor, spin
    context = fresh_context()
    node = rclpy.create_node('failing_callback', context=context)
    stop = StopSignals()

    def callback():
        if stop_requested:
            stop.requested = 2          # SIGINT, recorded by the handler
        raise RuntimeError("Unable to convert call argument '0' to Python object")
    node.create_timer(0.01, callback)
    executor = make_executor(context=context)
    executor.add_node(node)
    try:
        spin(executor, stop, context=context)
    except RuntimeError as exc:
        return exc
    finally:
        executor.shutdown()
        node.destroy_node()
        context.shutdown()
    return None


def test_an_executor_error_after_a_stop_signal_is_the_stop():
    assert _spin_with_a_failing_callback(stop_requested=True) is None
    assert isinstance(_spin_with_a_failing_callback(stop_requested=False), RuntimeError)
