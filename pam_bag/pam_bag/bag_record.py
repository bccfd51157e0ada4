"""bag_record: records topics into a Jazzy rosbag2 MCAP bag (a `ros2 bag record` stand-in).

Subscribes raw (the CDR bytes, never deserialised) to every topic under the chosen prefixes
(default: everything under /pam plus /diagnostics), or to an explicit topic list, discovering
topics as they appear, and writes each message with its receive time (ns since the epoch) through
pam_bag.bags (metadata.yaml v9, MCAP, zstd chunks; optionally split into several files by
size or duration, as `ros2 bag record -b/-d`). The subscriptions only queue the bytes; a
writer thread writes them, so a slow disk does not delay the callbacks.

Ctrl-C / SIGTERM (or `duration` elapsed) closes the bag cleanly. An existing output directory is
refused. A write error stops the recording: the bag is truncated to its last complete chunk and
closed readable, the error is logged, and the exit code is 1. On a crash (SIGKILL, power loss)
the .mcap holds every chunk written so far (at most `chunk_interval` of data is lost) but has no
summary and there is no metadata.yaml.
"""

from __future__ import annotations

import collections
import datetime
import sys
import threading
import time
from dataclasses import dataclass

from rclpy.logging import LoggingSeverity
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future

from pam_bag.bags import BagError, BagWriteError, BagWriter, check_split, known_type, qos_from_ints
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
from pam_common.stamps import ns_pair

NODE_NAME = 'bag_record'
SUB_DEPTH = 1000

PARAMETERS = (
    ParamSpec('output', '', 'string', '',
              "Bag directory to create (never overwritten); '': rosbag2_YYYY_MM_DD-HH_MM_SS."),
    ParamSpec('topics', '', 'string', '',
              "Comma-separated topics to record; '': every topic under `prefixes`."),
    ParamSpec('prefixes', '/pam,/diagnostics', 'string', '',
              'Comma-separated namespaces (or exact topics) recorded when `topics` is empty.'),
    ParamSpec('compression', 'zstd', 'string', '', 'Chunk compression.',
              choices=('zstd', 'none')),
    ParamSpec('chunk_interval', 1.0, 'double', 's',
              'Longest time before received messages are written to disk (what a crash loses).',
              range=(0.05, 60.0)),
    ParamSpec('max_bag_size', 0, 'integer', 'B',
              'Split the bag into files <output>_0.mcap, _1, ... of at most this size (plus a '
              'few kB of summary each), as `ros2 bag record -b`; 0: one file; else >= 100000.',
              range=(0, 2**62)),
    ParamSpec('max_bag_duration', 0.0, 'double', 's',
              'Split the bag into files of at most this span of receive times, as '
              '`ros2 bag record -d`; 0: no split by time; else >= 1.', range=(0.0, 1e7)),
    ParamSpec('discovery_period', 0.5, 'double', 's', 'How often to look for new topics.',
              range=(0.05, 10.0)),
    ParamSpec('duration', 0.0, 'double', 's', 'Stop after this long; 0: until Ctrl-C/SIGTERM.',
              range=(0.0, 1e7)),
    HARDWARE_ID_PARAM,
)

SUMMARY = [
    'Records topics (raw CDR, receive-time stamps) into a ROS 2 Jazzy rosbag2 bag directory:',
    'metadata.yaml version 9 + zstd-chunked MCAP file(s), as `ros2 bag record -s mcap` writes',
    '(one file, or split by max_bag_size / max_bag_duration).',
    'Stop with Ctrl-C or SIGTERM.',
]


def split_list(text: str) -> list[str]:
    return [t.strip() for t in text.split(',') if t.strip()]


def message_class(msgtype: str):
    """The rclpy message class of 'pkg/msg/Type'; None if its package is not installed."""
    import importlib
    try:
        package, kind, name = msgtype.split('/')
        return getattr(importlib.import_module(f'{package}.{kind}'), name)
    except (ValueError, ImportError, AttributeError):
        return None


def _duration_pair(duration) -> tuple[int, int]:
    return ns_pair(getattr(duration, 'nanoseconds', 0))


@dataclass(frozen=True)
class RecordOptions(NodeConfig):
    """bag_record's checked parameters (the table above: units, ranges, defaults), as
    rosbag2's RecordOptions."""

    output: str
    topics: str
    prefixes: str
    compression: str
    chunk_interval: float
    max_bag_size: int
    max_bag_duration: float
    discovery_period: float
    duration: float
    hardware_id: str


def build_config(values: dict) -> RecordOptions:
    """Check the values against the table and the split limits; ConfigError names the
    parameter."""
    check_all(PARAMETERS, values)
    try:
        check_split(values['max_bag_size'], values['max_bag_duration'])
    except BagError as exc:
        raise ConfigError(f'parameter {exc}') from exc
    return RecordOptions.from_values(values)


class BagRecorder(Node):
    """Discovers topics, subscribes raw, queues (topic, t_ns, bytes) for the writer thread."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.config = config = parameter_values(self, PARAMETERS, check=build_config)
        output = config.output or datetime.datetime.now().strftime(
            'rosbag2_%Y_%m_%d-%H_%M_%S')
        self.explicit = split_list(config.topics)
        self.prefixes = split_list(config.prefixes)
        try:
            self.bag = BagWriter(output, compression=config.compression,
                                 chunk_interval=config.chunk_interval,
                                 max_bag_size=config.max_bag_size,
                                 max_bag_duration=config.max_bag_duration)
        except BagError as exc:
            raise ConfigError(f"parameter 'output': {exc}") from exc
        self.finished = Future()
        self.queue: collections.deque = collections.deque()
        self.received = 0
        self.subscriptions_by_topic: dict[str, object] = {}
        self.skipped: set[str] = set()
        self._stop = threading.Event()
        self._writer = threading.Thread(target=self._write_loop, name='bag_writer', daemon=True)
        self._writer.start()
        self._discover()
        self.create_timer(config.discovery_period, self._discover)
        if config.duration > 0.0:
            self._stop_timer = self.create_timer(config.duration, self._on_duration)
        DiagnosticsPublisher(self, 'bag recorder', config.hardware_id, self._report)
        what = ', '.join(self.explicit) if self.explicit else (
            'everything under ' + ', '.join(self.prefixes))
        self.get_logger().info(f'recording {what} into {self.bag.path}')

    # ---------------------------------------------------------------- topics
    def _wanted(self, topic: str) -> bool:
        if self.explicit:
            return topic in self.explicit
        return any(topic == p or topic.startswith(p.rstrip('/') + '/') for p in self.prefixes)

    def _discover(self) -> None:
        if self.finished.done():
            return
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subscriptions_by_topic or topic in self.skipped:
                continue
            if not self._wanted(topic):
                continue
            msgtype = types[0]
            cls = message_class(msgtype)
            if len(types) > 1 or cls is None or not known_type(self.bag.typestore, msgtype):
                self.skipped.add(topic)
                self.get_logger().warn(f'not recording {topic}: type {", ".join(types)} '
                                       'unknown here or ambiguous')
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue
            offered = [qos_from_ints(p.qos_profile.history.value, p.qos_profile.depth,
                                     p.qos_profile.reliability.value,
                                     p.qos_profile.durability.value,
                                     p.qos_profile.liveliness.value,
                                     _duration_pair(p.qos_profile.deadline),
                                     _duration_pair(p.qos_profile.lifespan),
                                     _duration_pair(p.qos_profile.liveliness_lease_duration))
                       for p in publishers]
            reliable = all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                           for p in publishers)
            latched = all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                          for p in publishers)
            qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=SUB_DEPTH,
                             reliability=(ReliabilityPolicy.RELIABLE if reliable
                                          else ReliabilityPolicy.BEST_EFFORT),
                             durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                         else DurabilityPolicy.VOLATILE))
            try:
                self.bag.add_topic(topic, msgtype, offered)
            except BagError as exc:
                self.skipped.add(topic)
                self.get_logger().warn(f'not recording {topic}: {exc}')
                continue
            def on_message(data, topic=topic, queue=self.queue, clock=time.time_ns):
                queue.append((topic, clock(), data))
            self.subscriptions_by_topic[topic] = self.create_subscription(
                cls, topic, on_message, qos, raw=True)
            self.get_logger().info(f'subscribed to {topic} ({msgtype})')

    def _on_duration(self) -> None:
        self.destroy_timer(self._stop_timer)
        if not self.finished.done():
            self.finished.set_result(0)

    def _report(self):
        """/diagnostics: the topics, the messages written and queued, the file being written
        and the split files closed; ERROR after a write error, WARN while no topic is found."""
        counts = self.bag.counts()
        error = getattr(self, 'write_error', None)
        values = {'bag': str(self.bag.path), 'file': self.bag.mcap_path.name,
                  'split files closed': len(self.bag.files),
                  'topics recorded': len(self.subscriptions_by_topic),
                  'topics skipped': len(self.skipped),
                  'messages written': sum(counts.values()), 'messages queued': len(self.queue)}
        if error is not None:
            return ERROR, f'recording stopped: {error}', values
        if not self.subscriptions_by_topic:
            return WARN, 'no topic to record found yet', values
        return OK, (f"recording {values['topics recorded']} topics: "
                    f"{values['messages written']} messages written"), values

    # ---------------------------------------------------------------- writing
    def _write_loop(self) -> None:
        queue, bag = self.queue, self.bag
        closed = 0       # split files closed so far (their DEBUG lines logged)
        while True:
            try:
                while queue:
                    topic, t_ns, data = queue.popleft()
                    bag.write(topic, t_ns, data)
            except BagWriteError as exc:
                self.write_error = exc
                if not self.finished.done():
                    self.finished.set_result(1)
                return
            if len(bag.files) != closed:
                closed = self._log_files_closed(closed)
            if self._stop.is_set() and not queue:
                return
            time.sleep(0.005)

    def _log_files_closed(self, logged: int) -> int:
        """A DEBUG line for every split file closed since the first `logged`; their count."""
        files = list(self.bag.files)
        logger = self.get_logger()
        if logger.is_enabled_for(LoggingSeverity.DEBUG):
            for f in files[logged:]:
                logger.debug(f'split file {f.name} closed: {f.count} messages over '
                             f'{max(0, f.end_ns - f.start_ns) * 1e-9:.3f} s; next file '
                             f'{self.bag.mcap_path.name}')
        return len(files)

    def finish(self) -> int:
        """Stop the subscriptions, write what is queued, close the bag; the exit code."""
        for sub in list(self.subscriptions_by_topic.values()):
            self.destroy_subscription(sub)
        self._stop.set()
        self._writer.join()
        code = 0
        error = getattr(self, 'write_error', None)
        try:
            self.bag.close()
        except BagError as exc:
            error = error or exc
        logger = self.get_logger()
        if error is not None:
            logger.error(f'{error}; recording stopped, the bag holds what was written before '
                         'the error')
            code = 1
        counts = self.bag.counts()
        files = len(self.bag.files)
        logger.info(f'wrote {sum(counts.values())} messages on {len(counts)} topics to '
                    f'{self.bag.path}' + (f' ({files} files)' if files > 1 else ''))
        for topic, n in sorted(counts.items()):
            logger.info(f'  {topic}: {n}')
        return code


def main(args=None) -> int:
    return node_main(BagRecorder, NODE_NAME, usage_text(NODE_NAME, SUMMARY, PARAMETERS, examples=[
        f'{NODE_NAME} --ros-args -p output:=out/run1',
        f"{NODE_NAME} --ros-args -p output:=out/run2 -p topics:=/pam/pressures,/pam/estimate",
        f'{NODE_NAME} --ros-args -p output:=out/run3 -p max_bag_size:=4000000',
    ]), args)


if __name__ == '__main__':
    sys.exit(main())
