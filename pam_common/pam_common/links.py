"""In-process links: the 1 kHz path of a composed stack as function calls, not DDS messages.

Why: in rclpy, a message between two nodes of one process goes through the middleware like any
other: serialised, written, taken by the executor, deserialised and dispatched. Measured on the
2-core development machine, a publish plus its dispatch by the EventsExecutor costs about 130 us
per message, against about 10 us for a publish nobody in the process receives; a composed stack
moves four such messages per sample (pressures, estimate, valve_command twice), most of a core at
1 kHz, ten times the models' own compute. rclcpp's intra-process transport (a message handed to
the subscriptions of the same process as a pointer, no serialisation) and ros2_control's chained
controllers (one update loop calls the controllers in order) avoid that cost; rclpy has neither.

What: when a composing process (pam_container --links) enables the links before it builds its
nodes, a publication on a topic that a node of the same process subscribes is handed to that
node's callback directly, in the publishing thread, as the same message object; it is published
on DDS as well, for the subscriptions of other processes and hosts (tracking_report, a bag
recorder, a live view), only while any exists. A node is a LinkedNode (a plain rclpy Node when
the links are off: no cost, no change). The nodes stay separate nodes, each with its parameters,
services and /diagnostics, each runnable alone over DDS.

Trade-offs, chosen and written down (docs/composition.md):
- a linked subscription has no DDS subscription: a publisher of another process on a linked
  topic is not heard by the composed node (as a chained controller takes its reference from the
  controller before it, not from a topic), and the ROS graph shows no subscriber of it in the
  container; run without --links (the default) to inject messages from outside;
- one process-wide re-entrant lock, `ProcessLinks.lock`, serialises every callback of the linked
  nodes (timers, services, parameter callbacks, DDS subscriptions and the linked deliveries): a
  delivery runs in the publisher's thread (e.g. sim_node's sampler), so without it two threads
  could run one node's callbacks at once, which a single-threaded executor never does;
- the subscriber receives the publisher's message object, not a copy: a publisher must not
  change a message after publishing it (the stack's nodes build a new message per sample);
- whether another process subscribes is asked of DDS at most every RECOUNT_PERIOD (the count
  costs a few us, and a linked publisher asks it with every message): a subscription of another
  process gets its first messages up to that long after it matched (discovery takes longer);
- a node's loop timer (LinkedNode.create_loop_timer: reference_node's profile) is run by the
  sample loop of its namespace once one drives it (ProcessLinks.drive: sim_node's sampler),
  every round(period / sample period) samples in the loop's thread, as ros2_control's update
  loop runs each controller at a division of its rate; an rclpy timer otherwise, and again once
  the loop stops. Why: an rclpy timer on the EventsExecutor wakes two threads per firing (its
  timer thread, then the executor's), about 90 us of CPU each time on the development machine,
  against about 10 us for the callback itself in the loop, which is awake anyway. So such a
  timer follows the samples: it stalls with the loop (a reference has nothing to follow then).
  A watchdog must not be one (pi_node's feedback timeout stays an rclpy timer).
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable

from rclpy.node import Node

__all__ = ['LinkedNode', 'LoopTimer', 'ProcessLinks', 'SampleLoop', 'disable_links',
           'enable_links', 'process_links']

_ACTIVE: list[ProcessLinks] = []      # the process's links once enabled (one at most)
RECOUNT_PERIOD = 0.1                  # s between two counts of a topic's other-process readers
LOOP_TIMER_TOLERANCE = 0.01           # a loop runs a timer whose period is a whole number of
                                      # sample periods within this fraction


def enable_links() -> ProcessLinks:
    """Turn the in-process links on for every LinkedNode built from now on in this process."""
    if not _ACTIVE:
        _ACTIVE.append(ProcessLinks())
    return _ACTIVE[0]


def disable_links() -> None:
    """Turn the links off for nodes built from now on (tests that build nodes both ways)."""
    _ACTIVE.clear()


def process_links() -> ProcessLinks | None:
    """The process's links, None when they are off (the default)."""
    return _ACTIVE[0] if _ACTIVE else None


class LinkedSubscription:
    """A node's subscription in a linked process: fed directly by the linked publishers of its
    topic, and by DDS (a real subscription) only while the process has no publisher of it."""

    def __init__(self, node: Node, msg_type, topic_name: str, callback: Callable,
                 make_dds: Callable[[], object]):
        self.node = node
        self.msg_type = msg_type
        self.topic_name = topic_name
        self.callback = callback
        self._make_dds = make_dds
        self.dds = None

    def open_dds(self) -> None:
        if self.dds is None:
            self.dds = self._make_dds()

    def close_dds(self) -> None:
        if self.dds is not None:
            self.node.destroy_subscription(self.dds)
            self.dds = None


class LinkedPublisher:
    """A publisher whose messages reach the linked subscriptions of its topic directly, and DDS
    only while a subscription of another process matches. Other attributes: the rclpy one's."""

    def __init__(self, links: ProcessLinks, publisher, local: list[LinkedSubscription]):
        self._publisher = publisher
        self._local = local             # shared with ProcessLinks: later subscriptions join it
        self._links = links
        self._lock = links.lock
        self.topic_name = publisher.topic_name
        self.msg_type = publisher.msg_type
        self._outside = 0               # subscriptions of other processes, last counted
        self._recount_at = 0.0          # time.monotonic() of the next count

    def outside_subscriptions(self) -> int:
        """The subscriptions of other processes (on DDS), counted at most every
        RECOUNT_PERIOD."""
        now = time.monotonic()
        if now >= self._recount_at:
            self._outside = self._publisher.get_subscription_count()
            self._recount_at = now + RECOUNT_PERIOD
        return self._outside

    def get_subscription_count(self) -> int:
        """Subscriptions on DDS (other processes) plus the linked ones of this process."""
        return self.outside_subscriptions() + len(self._local)

    def publish(self, msg) -> None:
        if self._local and self._links.is_open:
            with self._lock:
                for subscription in self._local:
                    subscription.callback(msg)
        if self.outside_subscriptions():
            self._publisher.publish(msg)

    def __getattr__(self, name):
        return getattr(self._publisher, name)


class LoopTimer:
    """A node's periodic callback that the process's sample loop runs when one drives the
    process (every `every` samples), and its rclpy `timer` otherwise (see ProcessLinks.drive)."""

    def __init__(self, node: Node, period: float, callback: Callable, timer):
        self.node = node
        self.period = period            # s
        self.callback = callback        # not serialised: the loop calls it under the lock
        self.timer = timer              # rclpy timer (its callback serialised)
        self.every = 0                  # samples between two calls while driven (0: not)
        self.count = 0                  # samples since the last call while driven

    def describe(self) -> str:
        return (f'{self.node.get_fully_qualified_name()} {1.0 / self.period:g} Hz timer: '
                + (f'every {self.every} samples of the loop' if self.every else 'rclpy timer'))


class SampleLoop:
    """The loop timers one sample loop drives (ProcessLinks.drive)."""

    def __init__(self, links: ProcessLinks):
        self._links = links
        self.timers: list[LoopTimer] = []

    def tick(self) -> None:
        """One sample of the loop, in its thread: its loop timers that are due run, under the
        process's lock (nothing before the links are open)."""
        if not self._links.is_open:
            return
        with self._links.lock:
            for loop_timer in self.timers:
                loop_timer.count += 1
                if loop_timer.count >= loop_timer.every:
                    loop_timer.count = 0
                    loop_timer.callback()

    def release(self) -> None:
        """The loop stopped: its timers are rclpy timers again."""
        with self._links.lock:
            for loop_timer in self.timers:
                loop_timer.every = 0
                try:
                    loop_timer.timer.reset()
                except Exception:  # noqa: BLE001 - the node is going away (shutdown)
                    pass
            self.timers.clear()


class ProcessLinks:
    """The links of one process: its publishers and subscriptions by topic and message type."""

    def __init__(self):
        self.lock = threading.RLock()
        self.is_open = False    # deliveries start once every node of the process is built
        self._subscriptions: dict[tuple[str, type], list[LinkedSubscription]] = {}
        self._published: dict[tuple[str, type], list[str]] = {}   # -> publishing nodes
        self.loop_timers: list[LoopTimer] = []

    def open(self) -> None:
        """Start the deliveries: every node of the process is built (a node that publishes
        from a thread of its own, e.g. sim_node's sampler, may start before the others exist;
        its messages until now reached only DDS, as an executor that does not spin yet)."""
        self.is_open = True

    def serialised(self, callback: Callable) -> Callable:
        """callback, run under the process's lock."""
        lock = self.lock

        @functools.wraps(callback)
        def locked(*args, **kwargs):
            with lock:
                return callback(*args, **kwargs)
        return locked

    def publisher(self, node: Node, publisher) -> LinkedPublisher:
        key = (publisher.topic_name, publisher.msg_type)
        local = self._subscriptions.setdefault(key, [])
        with self.lock:
            self._published.setdefault(key, []).append(node.get_fully_qualified_name())
            for subscription in local:       # subscribed before this publisher existed
                subscription.close_dds()
        return LinkedPublisher(self, publisher, local)

    def subscription(self, node: Node, msg_type, topic_name: str, callback: Callable,
                     make_dds: Callable[[], object]) -> LinkedSubscription:
        key = (topic_name, msg_type)
        subscription = LinkedSubscription(node, msg_type, topic_name, callback, make_dds)
        with self.lock:
            self._subscriptions.setdefault(key, []).append(subscription)
            if key not in self._published:
                subscription.open_dds()
        return subscription

    def drive(self, sample_period: float, namespace: str) -> SampleLoop:
        """A sample loop of `sample_period` s (sim_node's sampler) in `namespace` (its joint's)
        takes over the loop timers of that namespace's nodes that no loop drives yet and whose
        period is a whole number of sample periods (within LOOP_TIMER_TOLERANCE): their rclpy
        timers are cancelled, SampleLoop.tick() calls them every that many samples, and
        SampleLoop.release() hands them back. Two joints in one process: each sampler drives its
        own joint's timers."""
        loop = SampleLoop(self)
        with self.lock:
            for loop_timer in self.loop_timers:
                every = round(loop_timer.period / sample_period)
                if loop_timer.every or loop_timer.node.get_namespace() != namespace \
                        or every < 1 or abs(every * sample_period - loop_timer.period) \
                        > LOOP_TIMER_TOLERANCE * loop_timer.period:
                    continue
                loop_timer.timer.cancel()
                loop_timer.every, loop_timer.count = every, 0
                loop.timers.append(loop_timer)
        return loop

    def links(self) -> list[str]:
        """One line per linked topic: 'topic: publisher -> subscriber, ...'."""
        lines = []
        for key, publishers in sorted(self._published.items(), key=lambda item: item[0][0]):
            subscribers = self._subscriptions.get(key, [])
            if subscribers:
                lines.append(f"{key[0]}: {', '.join(publishers)} -> " + ', '.join(
                    s.node.get_fully_qualified_name() for s in subscribers))
        return lines


class LinkedNode(Node):
    """A Node whose publishers, subscriptions and callbacks take part in the process's links
    when they are on (pam_container --links), and a plain rclpy Node otherwise."""

    def create_publisher(self, msg_type, topic, qos_profile, **kwargs):
        publisher = super().create_publisher(msg_type, topic, qos_profile, **kwargs)
        links = process_links()
        return publisher if links is None else links.publisher(self, publisher)

    def create_subscription(self, msg_type, topic, callback, qos_profile, **kwargs):
        links = process_links()
        if links is None:
            return super().create_subscription(msg_type, topic, callback, qos_profile, **kwargs)
        make = functools.partial(super().create_subscription, msg_type, topic,
                                 links.serialised(callback), qos_profile, **kwargs)
        return links.subscription(self, msg_type, self.resolve_topic_name(topic), callback, make)

    def create_timer(self, timer_period_sec, callback, *args, **kwargs):
        links = process_links()
        if links is not None:
            callback = links.serialised(callback)
        return super().create_timer(timer_period_sec, callback, *args, **kwargs)

    def create_loop_timer(self, timer_period_sec: float, callback: Callable):
        """A periodic callback that a sample loop of the process may run in its thread instead
        of an rclpy timer (links on, see ProcessLinks.drive); an rclpy timer (returned) always
        exists. Only for a callback that may stall with the loop: never a watchdog."""
        timer = self.create_timer(timer_period_sec, callback)
        links = process_links()
        if links is not None:
            with links.lock:
                links.loop_timers.append(LoopTimer(self, timer_period_sec, callback, timer))
        return timer

    def create_plain_timer(self, timer_period_sec, callback):
        """rclpy's timer, never under the process's lock: for a callback that takes the lock
        itself only around what needs it (DiagnosticsPublisher)."""
        return super().create_timer(timer_period_sec, callback)

    def create_service(self, srv_type, srv_name, callback, *args, **kwargs):
        links = process_links()
        if links is not None:
            callback = links.serialised(callback)
        return super().create_service(srv_type, srv_name, callback, *args, **kwargs)

    def add_on_set_parameters_callback(self, callback):
        links = process_links()
        return super().add_on_set_parameters_callback(
            callback if links is None else links.serialised(callback))

    def add_post_set_parameters_callback(self, callback):
        links = process_links()
        return super().add_post_set_parameters_callback(
            callback if links is None else links.serialised(callback))
