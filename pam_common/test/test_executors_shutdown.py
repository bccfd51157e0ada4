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


def _overloaded_spin(stop_after: float | None, finish_after: float | None) -> float:
    """spin() on a real EventsExecutor that cannot keep up (a timer publishes 3 messages a ms
    to a subscription whose callback takes 1 ms), stopped `stop_after` s in (a stop request, as
    the signal handler records it) or with `until` completed `finish_after` s in, from another
    thread. Returns how long spin() took to return after that."""
    from rclpy.task import Future
    from std_msgs.msg import Float64

    from pam_common.executors import StopSignals, is_events_executor, make_executor, spin
    context = fresh_context()
    node = rclpy.create_node('overloaded', context=context)
    publisher = node.create_publisher(Float64, 'load', 1000)

    def busy(_msg):
        end = time.perf_counter() + 0.001
        while time.perf_counter() < end:
            pass
    node.create_subscription(Float64, 'load', busy, 1000)
    node.create_timer(0.001, lambda: [publisher.publish(Float64(data=1.0)) for _ in range(3)])
    executor = make_executor(context=context)
    assert is_events_executor(executor)
    executor.add_node(node)
    stop, until, asked = StopSignals(), Future(), []

    def ask():
        time.sleep(stop_after if stop_after is not None else finish_after)
        asked.append(time.monotonic())
        if stop_after is not None:
            stop.requested = 2              # SIGINT, as the handler records it
        else:
            until.set_result(True)
    threading.Thread(target=ask, daemon=True).start()
    try:
        spin(executor, stop, until=until, context=context)
        return time.monotonic() - asked[0]
    finally:
        executor.shutdown()
        node.destroy_node()
        context.shutdown()


def test_an_overloaded_executor_stops_soon_after_the_request():
    """With callbacks always ready, the EventsExecutor's slice does not end at its timeout (one
    lasted 3 to 7 s, and so did Ctrl-C of an overloaded composed stack): the stop request ends
    it at the next callback boundary."""
    assert _overloaded_spin(stop_after=3.0, finish_after=None) < 1.0
    assert _overloaded_spin(stop_after=None, finish_after=3.0) < 1.0
