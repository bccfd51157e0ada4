"""bag_play: publishes a bag's messages from their serialized bytes on their original schedule
(a `ros2 bag play` stand-in).

A background thread reads the bag (the selected topics from `start_offset` on) chunk by chunk
into a bounded read-ahead queue (`read_ahead_size` messages: memory stays bounded, playing starts
at once however long the bag); a dedicated thread publishes each message's CDR bytes at
t0 + (t_msg - t_first) / rate on absolute deadlines (no drift). Options:
rate factor, loop, topic selection, remapping, start offset, start paused (resume with the
`~/resume` service, std_srvs/Trigger; `~/pause` pauses), /clock publishing at a fixed rate
(the frozen bag time while paused, as `ros2 bag play --clock` does; never ahead of the next
message to send, so after a stall /clock does not run past unsent data).
At the end it waits (at most `wait_for_all_acked`) for reliable subscribers to acknowledge every
message: a sample not acknowledged when the writer's process exits is lost.
At the start (after `delay`; started paused: at the first ~/resume) it waits at most
`wait_for_subscribers` for a matched subscription on every topic it plays: discovery matches each
pair of processes on its own and can take one announcement period (3 s), and a message sent
before that is lost to the late subscriber (the subscriber's process can see its side of the
match before the player's side is done, so it cannot tell the player when to resume). Messages
sent on a topic before it had any subscriber are counted: a warning when it gets its first, and
the totals in the end summary.
Bad input (missing metadata.yaml, truncated or corrupt .mcap, a type with no installed
package, a topic recorded with another definition of its type than the installed one: its
channel's RIHS01 topic_type_hash, or the hash of its embedded definition, differs from the
installed type's, so no subscriber could read it) is one error line naming the file and the
problem, exit code 2, before anything is published; a damaged chunk inside an otherwise
complete file (its CRC does not match, or it does not decompress) is found when playback
reaches it: the messages before it are played, then an error naming the file and the chunk, exit
code 2 too (docs/stopping.md, Exit codes).
"""

from __future__ import annotations

import queue
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np
from rclpy.duration import Duration
from rclpy.logging import LoggingSeverity
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future

from pam_bag.bag_record import message_class, split_list
from pam_bag.bags import EXIT_BAD_INPUT, BagError, open_bag
from pam_bag.read_ahead import END, ReadAhead
from pam_common.diagnostics import ERROR, OK, WARN, DiagnosticsPublisher
from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    ConfigError,
    NodeConfig,
    ParamSpec,
    check_all,
    usage_text,
)
from pam_common.node_skeleton import node_main, parameter_values
from pam_common.qos import CLOCK_QOS
from pam_common.stamps import ns_pair
from pam_common.topics import CLOCK

NODE_NAME = 'bag_play'
SPIN_AHEAD = 0.0005   # s: sleep until this close to a deadline, then busy-wait
LATENESS_KEPT = 1_000_000   # the last send latenesses kept for the p50/p99 report (8 MB)

PARAMETERS = (
    ParamSpec('bag', '', 'string', '', 'Bag directory (with metadata.yaml) to play.'),
    ParamSpec('rate', 1.0, 'double', '', 'Playback speed factor.', range=(0.01, 100.0)),
    ParamSpec('loop', False, 'bool', '', 'Play again from the start when the bag ends.'),
    ParamSpec('topics', '', 'string', '', "Comma-separated topics to play; '': all."),
    ParamSpec('remap', '', 'string', '',
              "Comma-separated FROM:=TO topic remappings, e.g. '/pam/pressures:=/x/pressures'."),
    ParamSpec('start_offset', 0.0, 'double', 's', 'Start this far into the bag.',
              range=(0.0, 1e7)),
    ParamSpec('start_paused', False, 'bool', '',
              'Wait for the ~/resume service (std_srvs/Trigger) before playing.'),
    ParamSpec('clock', 0.0, 'double', 'Hz',
              'Publish the bag time on /clock at this rate (also while paused); 0: no /clock.',
              range=(0.0, 10000.0)),
    ParamSpec('delay', 0.5, 'double', 's',
              'Wait this long after creating the publishers (for subscribers to match).',
              range=(0.0, 60.0)),
    ParamSpec('wait_for_subscribers', 4.0, 'double', 's',
              'After `delay` (start_paused: at the first ~/resume), wait at most this long '
              'until every played topic has a matched subscription (DDS discovery can take one '
              '3 s announcement period), then play; 0: do not wait.', range=(0.0, 600.0)),
    ParamSpec('read_ahead_size', 10000, 'integer', 'messages',
              'Messages read ahead of playback by a background thread (memory stays bounded '
              'however long the bag).', range=(100, 10_000_000)),
    ParamSpec('wait_for_all_acked', 2.0, 'double', 's',
              'At the end, wait at most this long for reliable subscribers to acknowledge every '
              'message (as `ros2 bag play --wait-for-all-acked`); 0: exit at once.',
              range=(0.0, 60.0)),
    HARDWARE_ID_PARAM,
)

SUMMARY = [
    'Plays a ROS 2 rosbag2 MCAP bag: publishes the serialized messages on their original',
    'schedule (rate, loop, topic selection, remapping, start offset, start paused, /clock).',
]


def parse_remap(text: str) -> dict[str, str]:
    result = {}
    for item in split_list(text):
        source, sep, target = item.partition(':=')
        if not sep or not source.strip() or not target.strip():
            raise ConfigError(f"parameter 'remap': expected FROM:=TO, got {item!r}")
        result[source.strip()] = target.strip()
    return result


@dataclass(frozen=True)
class PlayOptions(NodeConfig):
    """bag_play's checked parameters (the table above: units, ranges, defaults), as rosbag2's
    PlayOptions."""

    bag: str
    rate: float
    loop: bool
    topics: str
    remap: str
    start_offset: float
    start_paused: bool
    clock: float
    delay: float
    wait_for_subscribers: float
    read_ahead_size: int
    wait_for_all_acked: float
    hardware_id: str


def build_config(values: dict) -> PlayOptions:
    """Check the values against the table (a bag is given, the remap rules parse); ConfigError
    names the parameter."""
    check_all(PARAMETERS, values)
    if not values['bag']:
        raise ConfigError("parameter 'bag': give the bag directory (-p bag:=PATH)")
    parse_remap(values['remap'])
    return PlayOptions.from_values(values)


class BagPlayer(Node):
    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.config = config = parameter_values(self, PARAMETERS, check=build_config)
        remap = parse_remap(config.remap)
        topics = split_list(config.topics) or None
        try:
            self.bag = open_bag(config.bag, topics, config.start_offset)
        except BagError as exc:
            raise ConfigError(str(exc)) from exc
        self.publishers_by_index = []
        for name in self.bag.topic_names:
            msgtype = self.bag.topics[name]
            cls = message_class(msgtype)
            if cls is None:
                raise ConfigError(f'{self.bag.path}: unknown message type {msgtype!r} of topic '
                                  f'{name}: its package is not installed here')
            qos = self._qos(self.bag.qos.get(name, []))
            self.publishers_by_index.append(
                self.create_publisher(cls, remap.get(name, name), qos))
        if self.bag.unchecked:
            self.get_logger().warn(
                f'{", ".join(self.bag.unchecked)}: the bag gives no type hash or readable '
                'definition (or the type is not in the typestore): not checked against the '
                'installed types; a subscriber receives nothing if they differ')
        self.clock_pub = None
        if config.clock > 0.0:
            from rosgraph_msgs.msg import Clock
            self.clock_pub = self.create_publisher(Clock, CLOCK, CLOCK_QOS)
            self._clock_msg = Clock
        from std_srvs.srv import Trigger
        self.create_service(Trigger, '~/resume', self._on_resume)
        self.create_service(Trigger, '~/pause', self._on_pause)
        self.finished = Future()
        self.lateness_ns = np.zeros(LATENESS_KEPT, dtype=np.int64)   # a ring, by published
        self.published = 0
        self.read_waits = 0       # 0.1 s waits for the read-ahead (the reading fell behind)
        # per publisher: whether it has had a matched subscription, messages sent before that
        self.matched = [False] * len(self.publishers_by_index)
        self.sent_unmatched = [0] * len(self.publishers_by_index)
        self.exit_code = 0
        self._running = threading.Event()
        if not config.start_paused:
            self._running.set()
        self._quit = threading.Event()
        DiagnosticsPublisher(self, 'bag player', config.hardware_id, self._report)
        self._thread = threading.Thread(target=self._play, name='bag_play', daemon=True)
        self._thread.start()
        offset = config.start_offset
        self.get_logger().info(
            f'playing {len(self.bag.topic_names)} topics ({self.bag.message_count} messages) '
            f'of {self.bag.path}' + (f' from {offset:g} s in' if offset else '') +
            f' at rate {config.rate:g}' +
            (' (paused: call ~/resume)' if config.start_paused else ''))

    def _report(self):
        """/diagnostics: messages played of the bag's, paused, sent before a subscriber
        matched; ERROR after a damaged chunk, WARN while messages were lost that way."""
        total = self.bag.message_count
        lost = sum(self.sent_unmatched)
        paused = not self._running.is_set()
        values = {'bag': str(self.bag.path), 'messages played': self.published,
                  'messages in the bag': total, 'paused': paused, 'rate': self.config.rate,
                  'loop': self.config.loop,
                  'sent before a subscriber matched': lost, 'read-ahead waits': self.read_waits}
        if self.exit_code:
            return ERROR, 'stopped at a damaged chunk', values
        if self.finished.done():
            message = f'played {self.published} messages'
        elif paused:
            message = f'paused after {self.published} of {total} messages'
        else:
            message = f'playing: {self.published} of {total} messages'
        if lost:
            return WARN, f'{message}; {lost} sent before a subscriber matched', values
        return OK, message, values

    @staticmethod
    def _qos(offered) -> QoSProfile:
        from rosbags.interfaces import QosDurability, QosReliability
        reliable = all(q.reliability != QosReliability.BEST_EFFORT for q in offered)
        latched = bool(offered) and all(q.durability == QosDurability.TRANSIENT_LOCAL
                                        for q in offered)
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                          reliability=(ReliabilityPolicy.RELIABLE if reliable
                                       else ReliabilityPolicy.BEST_EFFORT),
                          durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                      else DurabilityPolicy.VOLATILE))

    def _on_resume(self, request, response):
        response.success = not self._running.is_set()
        response.message = 'resumed' if response.success else 'already playing'
        if response.success:
            self.get_logger().info('resumed; matched subscriptions: ' + ', '.join(
                f'{pub.topic_name} {pub.get_subscription_count()}'
                for pub in self.publishers_by_index))
        self._running.set()
        return response

    def _on_pause(self, request, response):
        response.success = self._running.is_set()
        response.message = 'paused' if response.success else 'already paused'
        self._running.clear()
        self.get_logger().debug(f'~/pause: {response.message}')
        return response

    def _wait_running(self, bag_ns: int) -> int:
        """Block while paused, publishing /clock at the frozen bag time `bag_ns`; returns the
        paused time in ns."""
        start = time.monotonic_ns()
        if self._running.is_set():
            return 0
        debug = self.get_logger().is_enabled_for(LoggingSeverity.DEBUG)
        if debug:
            self.get_logger().debug(f'paused at bag time {(bag_ns - self.bag.first_ns) * 1e-9:.3f}'
                                    f' s ({self.published} messages published)')
        period = 1.0 / self.config.clock if self.clock_pub is not None else 0.1
        while not self._running.is_set() and not self._quit.is_set():
            if self.clock_pub is not None:
                self._publish_clock(bag_ns)
            self._running.wait(period)
        paused = time.monotonic_ns() - start
        if debug and not self._quit.is_set():
            self.get_logger().debug(f'playing again after {paused * 1e-9:.3f} s paused')
        return paused

    def _publish_clock(self, bag_ns: int) -> None:
        msg = self._clock_msg()
        msg.clock.sec, msg.clock.nanosec = ns_pair(bag_ns)
        self.clock_pub.publish(msg)

    def _wait_for_subscribers(self) -> None:
        """Block until every publisher has a matched subscription, at most
        `wait_for_subscribers` s; on timeout log the topics without one and go on."""
        start = time.monotonic()
        end = start + self.config.wait_for_subscribers
        while not self._quit.is_set():
            missing = [pub.topic_name for pub in self.publishers_by_index
                       if pub.get_subscription_count() == 0]
            if not missing:
                self.get_logger().info(f'every topic has a subscriber (waited '
                                       f'{time.monotonic() - start:.2f} s); playing')
                return
            if time.monotonic() >= end:
                self.get_logger().info(f'playing; no subscriber yet on: {", ".join(missing)}')
                return
            self._quit.wait(0.01)

    def _count_unmatched(self, index: int) -> None:
        """Before publishing on publisher `index`: count the message when the topic has never
        had a subscriber (it is lost to any that matches later); warn once at the first one."""
        pub = self.publishers_by_index[index]
        if pub.get_subscription_count() == 0:
            self.sent_unmatched[index] += 1
            return
        self.matched[index] = True
        if self.sent_unmatched[index]:
            self.get_logger().warn(
                f'{pub.topic_name}: first subscriber matched after {self.sent_unmatched[index]} '
                'messages of it were sent (lost to it)')

    def _wait_for_all_acked(self) -> None:
        """Messages a reliable subscriber has not yet acknowledged are lost when the process
        exits: wait for them (at most `wait_for_all_acked` s in all). Not after Ctrl-C/SIGTERM:
        the ROS context is shut down then, and so are the publishers."""
        end = time.monotonic() + self.config.wait_for_all_acked
        for pub in self.publishers_by_index:
            left = end - time.monotonic()
            if left <= 0 or not self.context.ok():
                return
            try:
                acked = pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
            except RuntimeError:     # the context went down meanwhile (a late signal)
                return
            if not acked:
                self.get_logger().warn(f'{pub.topic_name}: not every message was acknowledged '
                                       f'within wait_for_all_acked')

    def _play(self) -> None:
        source = None
        try:
            time.sleep(self.config.delay)
            if not self.config.start_paused and self.config.wait_for_subscribers > 0:
                self._wait_for_subscribers()
            source = ReadAhead(self._passes(), capacity=self.config.read_ahead_size,
                               name='bag_read')
            self._play_passes(source)
        except BagError as exc:     # a damaged chunk: what came before it was played
            self.get_logger().error(f'{exc}; stopping')
            self.exit_code = EXIT_BAD_INPUT
        finally:
            if source is not None:
                source.close()
            if not self.finished.done():
                self.finished.set_result(0)

    def _passes(self):
        """The selected messages, then None (the end of a pass); again while looping."""
        while True:
            played = False
            for item in self.bag.messages():
                played = True
                yield item
            yield None
            if not (self.config.loop and played):
                return

    def _next(self, source):
        """The next item of the read-ahead (END once stopped)."""
        while not self._quit.is_set():
            try:
                return source.get(timeout=0.1)
            except queue.Empty:
                self.read_waits += 1
        return END

    def _play_passes(self, source) -> None:
        rate = self.config.rate
        clock_period = (1e9 / self.config.clock) if self.clock_pub is not None else None
        pubs, lateness, matched = self.publishers_by_index, self.lateness_ns, self.matched
        first = self.bag.first_ns
        item = self._next(source)
        passes = 0
        while item is not END:
            self._wait_running(first)
            if not passes and self.config.start_paused and self.config.wait_for_subscribers > 0:
                self._wait_for_subscribers()      # at the first ~/resume, as an unpaused start
            t0 = time.monotonic_ns()
            passes += 1
            if self.get_logger().is_enabled_for(LoggingSeverity.DEBUG):
                self.get_logger().debug(f'pass {passes} started: {self.published} messages '
                                        f'published before it, rate {rate:g}')
            next_clock = t0
            while item is not None and item is not END:       # one pass over the bag
                t_msg, topic, data = item
                due = t0 + int((t_msg - first) / rate)
                while True:
                    if self._quit.is_set():
                        return
                    if not self._running.is_set():
                        paused = self._wait_running(first + (time.monotonic_ns() - t0) * rate)
                        t0 += paused
                        due += paused
                    now = time.monotonic_ns()
                    if clock_period is not None and now >= next_clock:
                        # never ahead of the next message to send: after a stall, /clock
                        # waits at its time until the backlog is sent
                        self._publish_clock(min(first + (now - t0) * rate, t_msg))
                        next_clock = now + clock_period
                    wait = due - now
                    if wait <= 0:
                        break
                    if clock_period is not None:
                        wait = min(wait, max(0, next_clock - now))
                    if wait > SPIN_AHEAD * 1e9:
                        time.sleep((wait - SPIN_AHEAD * 1e9) * 1e-9)
                if not matched[topic]:
                    self._count_unmatched(topic)
                pubs[topic].publish(data)
                lateness[self.published % LATENESS_KEPT] = time.monotonic_ns() - due
                self.published += 1
                item = self._next(source)
            if item is None:
                item = self._next(source)     # the next pass, or END

    def finish(self) -> int:
        self._quit.set()
        self._running.set()
        self._thread.join(timeout=5.0)
        self._wait_for_all_acked()
        logger = self.get_logger()
        late = np.sort(self.lateness_ns[:min(self.published, LATENESS_KEPT)])
        lateness = ''
        if len(late):
            p50, p99 = late[len(late) // 2], late[min(len(late) - 1, int(len(late) * 0.99))]
            lateness = f'; send lateness p50 {p50 / 1e3:.0f} us, p99 {p99 / 1e3:.0f} us'
        logger.info(f'published {self.published} messages{lateness}')
        lost = [f'{pub.topic_name} {n}' for pub, n in zip(self.publishers_by_index,
                                                           self.sent_unmatched, strict=True)
                if n]
        if lost:
            logger.info(f'sent before any subscriber matched: {", ".join(lost)}')
        if self.read_waits:
            logger.warning(f'playback waited {self.read_waits} times 0.1 s for the bag to be '
                           'read (a slow disk? a larger read_ahead_size may help)')
        return self.exit_code


def main(args=None) -> int:
    return node_main(BagPlayer, NODE_NAME, usage_text(NODE_NAME, SUMMARY, PARAMETERS, examples=[
        f'{NODE_NAME} --ros-args -p bag:=out/run1',
        f'{NODE_NAME} --ros-args -p bag:=out/run1 -p rate:=2.0 -p loop:=true '
        "-p topics:=/pam/pressures -p remap:=/pam/pressures:=/replay/pressures",
    ]), args)


if __name__ == '__main__':
    sys.exit(main())
