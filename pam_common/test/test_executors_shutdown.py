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
