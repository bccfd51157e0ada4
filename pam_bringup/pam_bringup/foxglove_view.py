"""pam-foxglove: the stack's topics live in Foxglove, without any ROS tool.

An rclpy node (foxglove_view, in the stack's namespace, /pam by default) subscribes to the
stack's topics (pam_bringup.foxglove_channels.TOPICS: those of pam_common.topics, /diagnostics
and /rosout) and serves them over the Foxglove WebSocket protocol with foxglove-sdk (PyPI): one
channel per topic, created at start, so a topic whose publisher appears later is served from
then on. A channel's messages are the serialized messages as received (raw subscription: no
conversion here), encoding cdr with a ros2msg schema, stamped with their receive time (ns since
the epoch, the system clock); Foxglove decodes them as it decodes a bag.

Open Foxglove -> Open connection -> Foxglove WebSocket -> the URL logged at start
(ws://127.0.0.1:8765 by default). See docs/live_view.md. Run `pam-foxglove --help`.

Exit codes (docs/stopping.md): 0 after Ctrl-C/SIGTERM; 1 when the server cannot listen (the
port in use: one ERROR line); 2 for bad arguments or parameters (one line).
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Log
from rclpy.logging import LoggingSeverity
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import FluidPressure, JointState

from pam_common.diagnostics import OK, WARN, DiagnosticsPublisher
from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    ConfigError,
    NodeConfig,
    ParamSpec,
    check_all,
    usage_text,
)
from pam_common.node_skeleton import node_main, parameter_values
from pam_common.qos import VIEW_QOS
from pam_common.topics import DEFAULT_NAMESPACE
from pam_interfaces.msg import (
    ControllerState,
    JointEstimate,
    JointMeasurement,
    Pressures,
    Reference,
    ValveCommand,
)

from .foxglove_channels import (
    DEFAULT_HOST,
    DEFAULT_PORT,
    MESSAGE_ENCODING,
    SCHEMA_ENCODING,
    SHORTHAND_HELP,
    check_host,
    expand_shorthands,
    ros2msg_schemas,
    select_topics,
    url,
)

NODE_NAME = 'foxglove_view'
PROG = 'pam-foxglove'
PARAMETERS = (
    ParamSpec('host', DEFAULT_HOST, 'string', '',
              'Address to listen on: 127.0.0.1 serves this machine only; 0.0.0.0 every '
              'interface, so that Foxglove on another machine can connect (the protocol has no '
              'authentication: trusted networks only).'),
    ParamSpec('port', DEFAULT_PORT, 'integer', '',
              'TCP port to listen on; 0: a free port chosen by the system (logged).',
              range=(0, 65535)),
    ParamSpec('topics', '', 'string', '',
              "Comma-separated topics to serve, relative to the namespace or absolute (e.g. "
              "'pressures,estimate,/diagnostics'); '': all of them (pressures, joint_measured, "
              'joint_states, estimate, estimate/joint_states, reference, controller_state, '
              'valve_command, driver_node/applied_command, /diagnostics, /rosout).'),
    HARDWARE_ID_PARAM,
)
SUMMARY = [
    "Serves the stack's topics live over the Foxglove WebSocket protocol (foxglove-sdk), without",
    'any ROS tool: in Foxglove, Open connection -> Foxglove WebSocket -> ws://localhost:8765.',
    'One channel per topic; the messages are forwarded as received (cdr, ros2msg schema: decoded',
    "as from a bag), stamped with their receive time. A topic is subscribed only while a client",
    "watches its channel. Default namespace '/pam'. Stop with Ctrl-C.",
    'See docs/live_view.md.',
    '',
    *SHORTHAND_HELP,
]
#: The message classes of the served types (TOPICS names them as 'pkg/msg/Type').
MESSAGE_CLASSES = (Pressures, JointMeasurement, FluidPressure, JointState, JointEstimate, Reference,
                   ControllerState, ValveCommand, DiagnosticArray, Log)


#: foxglove-sdk's Python loggers (its Rust code logs through them) and the lowest level forwarded
#: (DEBUG for foxglove when the node's logger is at DEBUG).
SDK_LOGGERS = {'foxglove': logging.INFO, 'tungstenite': logging.WARNING}


class _SdkLog(logging.Handler):
    """foxglove-sdk's log records on the node's rclpy logger ('foxglove-sdk: ...'), so they
    reach /rosout with the node's own lines: clients registered and gone, failures."""

    def __init__(self, logger):
        super().__init__()
        self._logger = logger

    def emit(self, record: logging.LogRecord) -> None:
        text = f'foxglove-sdk: {record.getMessage()}'
        if record.levelno >= logging.ERROR:
            self._logger.error(text)
        elif record.levelno >= logging.WARNING:
            self._logger.warning(text)
        elif record.levelno >= logging.INFO:
            self._logger.info(text)
        else:
            self._logger.debug(text)

    def install(self, debug: bool) -> None:
        for name, level in SDK_LOGGERS.items():
            sdk = logging.getLogger(name)
            sdk.addHandler(self)
            sdk.setLevel(logging.DEBUG if debug and name == 'foxglove' else level)
            sdk.propagate = False       # not also Python's last-resort print to stderr


def type_name(cls) -> str:
    """'pkg/msg/Type' of a rosidl message class."""
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


class _Subscribers:
    """foxglove-sdk's ServerListener: which client subscribed to which channel (its callbacks
    run on the server's threads)."""

    def __init__(self, logger):
        self._lock = threading.Lock()
        self._pairs: set[tuple[int, int]] = set()
        self._logger = logger

    def on_subscribe(self, client, channel) -> None:
        with self._lock:
            self._pairs.add((client.id, channel.id))
        self._logger.debug(f'client {client.id} subscribed to {channel.topic}')

    def on_unsubscribe(self, client, channel) -> None:
        with self._lock:
            self._pairs.discard((client.id, channel.id))
        self._logger.debug(f'client {client.id} unsubscribed from {channel.topic}')

    def clients(self) -> int:
        """Clients subscribed to at least one channel."""
        with self._lock:
            return len({client for client, _ in self._pairs})

    def channels(self) -> set[int]:
        """The channels at least one client subscribes to."""
        with self._lock:
            return {channel for _, channel in self._pairs}


#: s between two matches of the ROS subscriptions to the clients' (a timer of the executor: the
#: server's callbacks run on its own threads, where no ROS entity may be made)
MATCH_PERIOD = 0.1


@dataclass(frozen=True)
class ViewConfig(NodeConfig):
    """The live view's checked parameters (the table above)."""

    host: str
    port: int
    topics: str
    hardware_id: str


def build_config(values: dict) -> ViewConfig:
    """Check the values against the table (and the host); ConfigError names the parameter."""
    check_all(PARAMETERS, values)
    values['host'] = check_host(values['host'])    # stripped, resolvable
    return ViewConfig.from_values(values)


class FoxgloveView(Node):
    """Subscribes the selected topics raw, each while a client subscribes to its channel, and
    logs each message on its Foxglove channel."""

    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.config = config = parameter_values(self, PARAMETERS, check=build_config)
        host = config.host
        served = select_topics(config.topics, self.get_namespace())
        self.server = None
        self.counts: dict[str, int] = {}
        logger = self.get_logger()
        _SdkLog(logger).install(debug=logger.is_enabled_for(LoggingSeverity.DEBUG))
        import foxglove
        self._sdk_context = foxglove.Context()
        self._subscribers = _Subscribers(self.get_logger())
        try:
            self.server = foxglove.start_server(
                name=f'{PROG} {self.get_namespace()}', host=host, port=config.port,
                context=self._sdk_context, server_listener=self._subscribers)
        except RuntimeError as exc:
            problem = str(exc).removeprefix('FoxgloveError: ')
            self.get_logger().error(f'cannot serve on {host}:{config.port}: {problem}')
            # a finished node (pam_common.executors.run_nodes): it ends at once, finish() gives
            # the exit code; a node that serves has no `finished` (an ordinary node)
            self.finished = Future()
            self.finished.set_result(1)
            return
        self.url = url(host, self.server.port)
        classes = {type_name(cls): cls for cls in MESSAGE_CLASSES}
        schemas = ros2msg_schemas([topic.msgtype for topic in served])
        self._channels = {}           # channel id -> (topic name, message class, channel)
        self._ros_subscriptions = {}  # channel id -> the ROS subscription, while wanted
        for topic in served:
            channel = foxglove.Channel(
                topic.name, message_encoding=MESSAGE_ENCODING, context=self._sdk_context,
                schema=foxglove.Schema(name=topic.msgtype, encoding=SCHEMA_ENCODING,
                                       data=schemas[topic.msgtype]))
            self.counts[topic.name] = 0
            self._channels[channel.id()] = (topic.name, classes[topic.msgtype], channel)
            self.get_logger().debug(f'serving {topic.name} ({topic.msgtype}) as channel '
                                    f'{channel.id()}')
        # a topic is subscribed only while a client subscribes to its channel: nothing is
        # received (about 7000 messages/s at 1 kHz) while nobody watches
        self.create_timer(MATCH_PERIOD, self._match_clients)
        DiagnosticsPublisher(self, 'Foxglove live view', config.hardware_id, self._report)
        self.get_logger().info(
            f"serving {len(served)} topic{'' if len(served) == 1 else 's'} of "
            f'{self.get_namespace()} on {self.url}: in Foxglove, Open connection -> Foxglove '
            f'WebSocket -> {self.url}')

    def _match_clients(self) -> None:
        """Subscribe the topics of the channels some client subscribes to; drop the others."""
        wanted = self._subscribers.channels() & set(self._channels)
        for cid in wanted - set(self._ros_subscriptions):
            name, cls, channel = self._channels[cid]
            self._ros_subscriptions[cid] = self.create_subscription(
                cls, name, self._forwarder(name, channel), VIEW_QOS, raw=True)
            self.get_logger().debug(f'subscribed {name}: a client watches it')
        for cid in set(self._ros_subscriptions) - wanted:
            self.destroy_subscription(self._ros_subscriptions.pop(cid))
            self.get_logger().debug(f'unsubscribed {self._channels[cid][0]}: no client '
                                    'watches it')

    def _forwarder(self, name: str, channel):
        """The raw callback of topic `name`: the message to its channel, stamped now."""
        counts = self.counts

        def forward(data: bytes, log=channel.log, clock=time.time_ns) -> None:
            log(data, log_time=clock())
            counts[name] += 1
        return forward

    def _report(self):
        """/diagnostics: the URL, the topics served, the messages forwarded, the clients
        subscribed; WARN while no message arrived."""
        received = sum(self.counts.values())
        clients = self._subscribers.clients()
        values = {'url': self.url, 'topics served': len(self.counts),
                  'topics subscribed (watched by a client)': len(self._ros_subscriptions),
                  'topics with messages': sum(1 for n in self.counts.values() if n),
                  'messages forwarded': received, 'clients subscribed': clients}
        if not clients:
            return OK, f'serving on {self.url}: no client watching', values
        if not received:
            return WARN, "no message received yet: is the stack up in this namespace?", values
        return OK, f'serving on {self.url}', values

    def finish(self) -> int:
        """The exit code when the server could not start (run_nodes calls it only then)."""
        return self.finished.result()

    def stop_server(self) -> None:
        if self.server is not None:
            self.server.stop()
            self.server = None


def main(args=None) -> int:
    argv = list(sys.argv if args is None else args)
    try:
        argv = expand_shorthands(argv)
    except ConfigError as exc:
        print(f'[{PROG}] error: {exc} (see {PROG} --help)', file=sys.stderr)
        return 2
    usage = usage_text(PROG, SUMMARY, PARAMETERS, examples=[
        PROG,
        f'{PROG} --host 0.0.0.0 --port 8766',
        f'{PROG} --namespace /joint2 --topics pressures,estimate,/diagnostics',
        f"{PROG} --ros-args -r __ns:=/joint2 -p port:=8766",
    ]).replace('[-h]', '[-h] [--host HOST] [--port PORT] [--topics LIST] [--namespace NS]', 1)
    return node_main(FoxgloveView, PROG, usage, argv, stop=FoxgloveView.stop_server)


if __name__ == '__main__':
    sys.exit(main())
