"""pam_common.links: in-process links between the nodes of one process (pam_container --links),
with real rclpy nodes and DDS: a linked message reaches the node of the same process as a call
in the publishing thread, DDS carries it only for a subscription of another participant, and the
callbacks of the linked nodes run one at a time under the process's lock."""

from __future__ import annotations

import threading
import time

import pytest
import rclpy
from rclpy.context import Context

from pam_common.executors import make_executor
from pam_common.links import LinkedNode, disable_links, enable_links, process_links
from pam_common.qos import SAMPLE_QOS
from pam_common.testing import wait_until
from pam_interfaces.msg import Pressures


@pytest.fixture
def links():
    links = enable_links()
    yield links
    disable_links()


@pytest.fixture
def context(ros_domain):
    context = Context()
    rclpy.init(context=context, domain_id=ros_domain)
    yield context
    context.try_shutdown()


def _sample(k: int) -> Pressures:
    msg = Pressures()
    msg.p1, msg.p2, msg.sample = 4.5e5, 4.4e5, k
    return msg


def test_links_are_off_by_default_and_a_linked_node_is_a_plain_node(context):
    assert process_links() is None
    node = LinkedNode('plain', context=context)
    pub = node.create_publisher(Pressures, 'p', SAMPLE_QOS)
    assert type(pub).__name__ == 'Publisher'
    node.destroy_node()


def test_a_linked_message_is_a_call_in_the_publishing_thread(links, context):
    source = LinkedNode('source', context=context)
    sink = LinkedNode('sink', context=context)
    got = []
    sink.create_subscription(Pressures, 'pressures',
                             lambda m: got.append((m, threading.get_ident())), SAMPLE_QOS)
    pub = source.create_publisher(Pressures, 'pressures', SAMPLE_QOS)
    assert links.links() == ['/pressures: /source -> /sink']
    msg = _sample(1)
    pub.publish(msg)
    assert got == [], 'nothing is delivered before the process opens its links'
    links.open()
    pub.publish(msg)
    # delivered before publish() returned, in this thread, the very object: no executor, no DDS
    assert got == [(msg, threading.get_ident())]
    assert pub.get_subscription_count() == 1      # the linked one; none on DDS
    source.destroy_node()
    sink.destroy_node()


def test_dds_carries_a_linked_topic_only_for_another_participant(links, context, ros_domain):
    links.open()
    node = LinkedNode('linked', context=context)
    local = []
    node.create_subscription(Pressures, 'pressures', local.append, SAMPLE_QOS)
    pub = node.create_publisher(Pressures, 'pressures', SAMPLE_QOS)
    # the subscription created before its publisher lost its DDS subscription when it appeared
    assert node.count_subscribers('/pressures') == 0
    other = Context()                     # another participant, as another process would be
    rclpy.init(context=other, domain_id=ros_domain)
    try:
        outside = rclpy.create_node('outside', context=other)
        remote = []
        outside.create_subscription(Pressures, '/pressures', remote.append, SAMPLE_QOS)
        executor = make_executor(context=other)
        executor.add_node(outside)
        assert wait_until(lambda: pub.get_subscription_count() == 2, 10.0)
        for k in range(1, 21):
            pub.publish(_sample(k))
        end = time.monotonic() + 10.0
        while len(remote) < 20 and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        assert [m.sample for m in remote] == list(range(1, 21))
        assert [m.sample for m in local] == list(range(1, 21)), 'each message once, directly'
        executor.shutdown()
    finally:
        other.try_shutdown()
    node.destroy_node()


def test_the_linked_nodes_callbacks_run_one_at_a_time(links, context):
    """A delivery from another thread (sim_node's sampler) and a timer of the executor's
    thread never overlap: both hold the process's lock."""
    links.open()
    source = LinkedNode('source', context=context)
    sink = LinkedNode('sink', context=context)
    inside, overlaps, calls = [0], [0], [0]

    def busy(*_):
        calls[0] += 1
        inside[0] += 1
        overlaps[0] += inside[0] > 1
        time.sleep(0.0005)
        inside[0] -= 1
    sink.create_subscription(Pressures, 'pressures', busy, SAMPLE_QOS)
    sink.create_timer(0.005, busy)
    pub = source.create_publisher(Pressures, 'pressures', SAMPLE_QOS)
    executor = make_executor(context=context)
    executor.add_node(sink)
    stop = threading.Event()

    def publisher():
        k = 0
        while not stop.is_set():
            k += 1
            pub.publish(_sample(k))
            time.sleep(0.001)
    thread = threading.Thread(target=publisher)
    thread.start()
    end = time.monotonic() + 1.0
    from rclpy.task import Future
    never = Future()
    while time.monotonic() < end:
        executor.spin_until_future_complete(never, timeout_sec=0.05)
    stop.set()
    thread.join()
    executor.shutdown()
    assert overlaps[0] == 0
    assert calls[0] > 300, 'both callers ran'
    source.destroy_node()
    sink.destroy_node()


def test_a_sample_loop_runs_the_loop_timers_it_divides(links, context):
    """ProcessLinks.drive: a loop timer of the loop's namespace whose period is a whole number
    of sample periods is run by the loop's tick() every that many samples, in the loop's
    thread, under the process's lock, its rclpy timer cancelled meanwhile; one that is not (or
    is faster than the loop, or of another namespace, or already driven) stays an rclpy timer;
    release() hands the driven ones back to rclpy."""
    node = LinkedNode('looped', namespace='/j1', context=context)
    other_joint = LinkedNode('looped', namespace='/j2', context=context)
    calls = []

    def record(name):
        def callback():
            free = []        # whether another thread could take the lock now
            other = threading.Thread(target=lambda: free.append(
                links.lock.acquire(blocking=False) and (links.lock.release() or True)))
            other.start()
            other.join()
            calls.append((name, threading.get_ident(), not free[0]))
        return callback
    every_10 = node.create_loop_timer(0.010, record('every_10'))
    uneven = node.create_loop_timer(0.0105, record('uneven'))
    faster = node.create_loop_timer(0.0005, record('faster'))
    plain = node.create_timer(0.010, record('plain'))
    j2 = other_joint.create_loop_timer(0.010, record('j2'))
    assert [t.timer for t in links.loop_timers] == [every_10, uneven, faster, j2]

    loop = links.drive(0.001, '/j1')
    assert [(t.timer, t.every) for t in loop.timers] == [(every_10, 10)]
    assert 'every 10 samples' in loop.timers[0].describe()
    assert '/j1/looped 100 Hz' in loop.timers[0].describe()
    assert every_10.is_canceled()
    assert not any(t.is_canceled() for t in (uneven, faster, plain, j2))
    assert links.drive(0.001, '/j1').timers == [], 'driven by one loop at most'
    for _ in range(5):
        loop.tick()
    assert calls == [], 'nothing runs before the links are open'
    links.open()
    for _ in range(35):
        loop.tick()
    me = threading.get_ident()
    assert calls == [('every_10', me, True)] * 3      # the 10th, 20th, 30th sample since open
    loop.release()
    assert not every_10.is_canceled()
    again = links.drive(0.002, '/j1')
    assert [t.every for t in again.timers] == [5]
    again.release()
    node.destroy_node()
    other_joint.destroy_node()


def test_a_loop_timer_without_links_is_an_rclpy_timer(context):
    node = LinkedNode('plain_loop', context=context)
    timer = node.create_loop_timer(0.01, lambda: None)
    assert type(timer).__name__ == 'Timer' and not timer.is_canceled()
    node.destroy_node()
