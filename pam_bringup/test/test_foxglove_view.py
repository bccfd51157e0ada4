"""pam-foxglove as a Foxglove client sees it: real processes on the module's ROS domain, a real
WebSocket client (the `websockets` package) speaking the Foxglove WebSocket protocol: its
subprotocol foxglove.sdk.v1, foxglove.websocket.v1 under the name foxglove-sdk accepts.

pam-foxglove starts first, the client connects, reads serverInfo and the advertised channels
(one per topic, cdr with a ros2msg schema) and subscribes to every channel; only then does the
stack start (pam-bringup: sim_node, ukf_node, pi_node, reference_node), so every topic appears
after the server made its channels. The probe publishes the topics no node of that stack
does by default: driver_node's ~/applied_command (a hardware rig's), supply_pressure (a rig with a
supply transducer's) and /rosout lines. Each channel must
deliver a binary messageData frame whose payload decodes with the advertised schema text alone
(mcap_ros2, as a bag reader decodes) into values that make sense. Then Ctrl-C stops it cleanly.
Bad input: a port in use is one ERROR line and exit code 1; a bad port or topic one line and 2.
"""

from __future__ import annotations

import asyncio
import json
import math
import socket
import struct
import subprocess
import time

import pytest
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
from rcl_interfaces.msg import Log
from sensor_msgs.msg import FluidPressure

from pam_bringup.foxglove_channels import TOPICS
from pam_common.testing import (
    STARTUP_TIMEOUT,
    child_env,
    executable,
    log_lines,
    wait_for_log,
    wait_until,
)
from pam_interfaces.msg import ValveCommand

SUBPROTOCOL = 'foxglove.sdk.v1'   # foxglove-sdk refuses foxglove.websocket.v1 (HTTP 400)
MESSAGE_DATA = 0x01            # opcode of a binary messageData frame
HEADER = struct.Struct('<BIQ')  # opcode, subscription id, timestamp (ns)
#: s: pam-bringup's four Python processes starting on a loaded 2-core machine, then DDS
#: discovery (up to ~3 s per pair) and the 1 s diagnostics period
TIMEOUT = 2.0 * STARTUP_TIMEOUT
ABS_PRESSURE = (1.0, 1e6)      # Pa: absolute pressures of the muscles, open bounds
ANGLE_LIMIT = 0.5              # rad: beyond the joint's +-25 deg (0.436 rad)
VOLTAGE = (0.0, 10.0)          # V: the valve range
LOG_TEXT = 'hello from test_foxglove_view'


def free_port() -> int:
    """A TCP port of 127.0.0.1 free a moment ago (bound to 0, then closed)."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def finite(*values) -> bool:
    return all(math.isfinite(v) for v in values)


def pressures(m) -> bool:
    return all(ABS_PRESSURE[0] < p < ABS_PRESSURE[1] for p in (m.p1, m.p2))


def joint(m) -> bool:
    return finite(m.angle, m.angular_velocity, m.torque) and abs(m.angle) < ANGLE_LIMIT


def voltages(m) -> bool:
    return all(VOLTAGE[0] <= u <= VOLTAGE[1] for u in (m.u1, m.u2))


#: Type -> whether a decoded message's values make sense.
SENSIBLE = {
    'pam_interfaces/msg/Pressures': pressures,
    'pam_interfaces/msg/JointMeasurement': joint,
    'sensor_msgs/msg/FluidPressure': lambda m: m.fluid_pressure == 7.1e5,
    'pam_interfaces/msg/JointEstimate': lambda m: pressures(m) and joint(m),
    'sensor_msgs/msg/JointState': lambda m: (
        len(m.name) == len(m.position) == len(m.velocity) == len(m.effort) == 1 and m.name[0]
        and finite(*m.position, *m.velocity, *m.effort) and abs(m.position[0]) < ANGLE_LIMIT),
    'pam_interfaces/msg/Reference': lambda m: m.mode in (0, 1) and finite(m.value),
    'pam_interfaces/msg/ControllerState': lambda m: voltages(m) and finite(
        m.reference, m.feedback, m.error, m.p_term, m.i_term),
    'pam_interfaces/msg/ValveCommand': voltages,
    'diagnostic_msgs/msg/DiagnosticArray': lambda m: m.status and all(
        s.name.startswith('/') for s in m.status),
    'rcl_interfaces/msg/Log': lambda m: m.msg and m.name,
}


class FoxgloveClient:
    """The client side of foxglove.websocket.v1, over a websockets connection."""

    def __init__(self, ws):
        self.ws = ws
        self.server_info: dict = {}
        self.channels: dict[int, dict] = {}      # channel id -> the advertised channel
        self.decoders: dict[int, object] = {}    # channel id -> decode(payload)
        self.by_subscription: dict[int, dict] = {}

    async def read_advertisements(self, count: int, timeout: float) -> None:
        """Read text ops until serverInfo and `count` channels came."""
        end = time.monotonic() + timeout
        while not self.server_info or len(self.channels) < count:
            frame = await asyncio.wait_for(self.ws.recv(), max(0.1, end - time.monotonic()))
            assert isinstance(frame, str), 'a binary frame before any subscription'
            op = json.loads(frame)
            if op['op'] == 'serverInfo':
                self.server_info = op
            elif op['op'] == 'advertise':
                for channel in op['channels']:
                    self.channels[channel['id']] = channel

    def make_decoders(self) -> None:
        """A decoder per channel from its advertised schema text alone (mcap_ros2)."""
        factory = DecoderFactory()
        for cid, channel in self.channels.items():
            schema = Schema(id=cid, name=channel['schemaName'],
                            encoding=channel['schemaEncoding'], data=channel['schema'].encode())
            self.decoders[cid] = factory.decoder_for(channel['encoding'], schema)
            assert self.decoders[cid] is not None, channel

    async def subscribe_all(self) -> None:
        subscriptions = [{'id': k, 'channelId': cid} for k, cid in enumerate(self.channels)]
        self.by_subscription = {s['id']: self.channels[s['channelId']] for s in subscriptions}
        await self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subscriptions}))

    def decode(self, frame: bytes):
        """(channel, timestamp ns, decoded message) of a messageData frame."""
        opcode, subscription, stamp = HEADER.unpack_from(frame)
        assert opcode == MESSAGE_DATA, f'binary opcode {opcode}'
        channel = self.by_subscription[subscription]
        return channel, stamp, self.decoders[channel['id']](frame[HEADER.size:])


async def watch(url: str, start_stack, publish, timeout: float) -> dict:
    """Connect, check the advertisements, subscribe to every channel, start the stack
    (`start_stack()`), then read frames (calling `publish()` every 0.1 s) until every channel
    delivered a sensible message and pam-foxglove's own status came on /diagnostics. Returns
    topic -> (the first message, its timestamp); fails naming the channels still silent."""
    import websockets
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        client = FoxgloveClient(ws)
        await client.read_advertisements(len(TOPICS), 30.0)
        assert client.server_info['name'].startswith('pam-foxglove /pam')
        advertised = {c['topic']: c for c in client.channels.values()}
        expected = {(name if name.startswith('/') else '/pam/' + name): msgtype
                    for name, msgtype in TOPICS}
        assert {t: c['schemaName'] for t, c in advertised.items()} == expected
        assert {(c['encoding'], c['schemaEncoding']) for c in advertised.values()} == {
            ('cdr', 'ros2msg')}
        client.make_decoders()
        await client.subscribe_all()
        start_stack()
        first: dict = {}
        own_status = False
        problems: dict = {}
        last_publish = time.monotonic()
        end = last_publish + timeout
        while time.monotonic() < end and (len(first) < len(expected) or not own_status):
            if time.monotonic() - last_publish > 0.1:
                publish()
                last_publish = time.monotonic()
            try:
                frame = await asyncio.wait_for(ws.recv(), 0.1)
            except asyncio.TimeoutError:
                continue
            if isinstance(frame, str):
                continue                      # e.g. a status op
            channel, stamp, msg = client.decode(frame)
            topic, msgtype = channel['topic'], channel['schemaName']
            if not SENSIBLE[msgtype](msg):
                problems[topic] = repr(msg)
                continue
            first.setdefault(topic, (msg, stamp))
            if topic == '/diagnostics':
                own_status |= any(s.name == '/pam/foxglove_view: Foxglove live view'
                                  for s in msg.status)
        silent = sorted(set(expected) - set(first))
        assert not silent, f'no sensible message on {silent}; problems: {problems}'
        assert own_status, "pam-foxglove's own status never came on /diagnostics"
        return first


def test_a_client_receives_every_channel_decodable(node_process, probe, ros_domain):
    port = free_port()
    view = node_process('pam-foxglove', 'pam_bringup', '--port', str(port), raw=True)
    url = f'ws://127.0.0.1:{port}'
    wait_for_log(view, 'INFO', 'pam.foxglove_view', url, timeout=STARTUP_TIMEOUT)
    applied = probe.publisher(ValveCommand, '/pam/driver_node/applied_command')
    rosout = probe.publisher(Log, '/rosout')
    supply = probe.publisher(FluidPressure, '/pam/supply_pressure')

    def start_stack():
        node_process('pam-bringup', 'pam_bringup', '--domain-id', str(ros_domain), raw=True)

    def publish():
        applied.publish(ValveCommand(u1=5.0, u2=5.0))
        rosout.publish(Log(level=Log.INFO, name='test_probe', msg=LOG_TEXT))
        supply.publish(FluidPressure(fluid_pressure=7.1e5))

    started = time.time_ns()
    first = asyncio.run(watch(url, start_stack, publish, TIMEOUT))
    for topic, (_, stamp) in first.items():     # receive times, ns since the epoch
        assert started <= stamp <= time.time_ns(), topic
    assert first['/rosout'][0].msg        # a node's line or the probe's
    # foxglove-sdk's own lines come through the node's rclpy logger
    assert any('foxglove-sdk: Registered client 127.0.0.1:' in line
               for line in log_lines(view.stderr, 'INFO', 'pam.foxglove_view')), view.stderr
    assert view.stop() == 0, view.stderr
    assert 'Traceback' not in view.stderr, view.stderr


def run_view(ros_domain, *args) -> subprocess.CompletedProcess:
    return subprocess.run([executable('pam-foxglove', 'pam_bringup'), *args],
                          env=child_env(ros_domain), capture_output=True, text=True,
                          timeout=STARTUP_TIMEOUT)


def test_a_port_in_use_is_one_line_and_exit_code_1(ros_domain):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        run = run_view(ros_domain, '--port', str(port))
    assert run.returncode == 1, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('[ERROR] '), run.stderr
    assert f'cannot serve on 127.0.0.1:{port}' in lines[0] and 'in use' in lines[0], lines
    assert run.stdout == ''


@pytest.mark.parametrize(('args', 'text'), [
    (['--port', '70000'], "parameter 'port': 70000 is out of range [0, 65535]"),
    (['--ros-args', '-p', 'port:=x'], "parameter 'port': expected integer"),
    (['--topics', 'pressures,nonsense'], "parameter 'topics': unknown topic '/pam/nonsense'"),
    (['--host', 'no-such-host.invalid'], "parameter 'host': cannot resolve"),
    (['--port'], 'option --port needs a value'),
    (['--verbose'], "unknown argument '--verbose'"),
])
def test_bad_arguments_are_one_line_and_exit_code_2(ros_domain, args, text):
    run = run_view(ros_domain, *args)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and text in lines[0], run.stderr


def test_a_free_port_chosen_by_the_system_is_logged(node_process):
    """port:=0: the server listens where the system says, and the URL logged is that port;
    the shorthands put the node in another namespace and select its topics."""
    view = node_process('pam-foxglove', 'pam_bringup', '--namespace', 'joint2', '--topics',
                        'pressures', '--ros-args', '-p', 'port:=0', raw=True)
    lines = wait_for_log(view, 'INFO', 'joint2.foxglove_view', 'ws://127.0.0.1:',
                         STARTUP_TIMEOUT)
    line = next(line for line in lines if 'ws://127.0.0.1:' in line)
    port = int(line.split('ws://127.0.0.1:')[1].split(':')[0])
    assert port > 0
    socket.create_connection(('127.0.0.1', port), 5.0).close()
    assert 'serving 1 topic of /joint2' in line, lines
    assert view.stop() == 0, view.stderr


def view_subscriptions(probe) -> set[str]:
    """The topics foxglove_view subscribes to now, from the ROS graph."""
    try:
        return {name for name, _ in probe.node.get_subscriber_names_and_types_by_node(
            'foxglove_view', '/pam')}
    except Exception:  # noqa: BLE001 - the node not (yet) in this process's graph
        return set()


async def subscribe_one(url: str, topic: str, probe) -> tuple[set, set]:
    """Connect, subscribe to the channel of `topic` alone: the topics foxglove_view subscribes
    to then (once it did), and after the client unsubscribed (once it did)."""
    import websockets
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        client = FoxgloveClient(ws)
        await client.read_advertisements(len(TOPICS), 30.0)
        cid = next(c['id'] for c in client.channels.values() if c['topic'] == topic)
        await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [{'id': 7,
                                                                       'channelId': cid}]}))
        assert wait_until(lambda: topic in view_subscriptions(probe), TIMEOUT)
        watched = view_subscriptions(probe)
        await ws.send(json.dumps({'op': 'unsubscribe', 'subscriptionIds': [7]}))
        assert wait_until(lambda: topic not in view_subscriptions(probe), TIMEOUT)
        return watched, view_subscriptions(probe)


def test_topics_are_subscribed_only_while_a_client_watches_them(node_process, probe):
    """No client: pam-foxglove subscribes nothing (no 1 kHz stream received for nobody); a
    client watching one channel: that topic alone; unsubscribed: nothing again."""
    port = free_port()
    view = node_process('pam-foxglove', 'pam_bringup', '--port', str(port), raw=True)
    url = f'ws://127.0.0.1:{port}'
    wait_for_log(view, 'INFO', 'pam.foxglove_view', url, timeout=STARTUP_TIMEOUT)
    def view_publishes() -> bool:
        try:
            return bool(probe.node.get_publisher_names_and_types_by_node('foxglove_view', '/pam'))
        except Exception:  # noqa: BLE001 - the node not (yet) in this process's graph
            return False
    assert wait_until(view_publishes, TIMEOUT), 'foxglove_view not in the graph'
    assert view_subscriptions(probe) == set()
    watched, after = asyncio.run(subscribe_one(url, '/pam/pressures', probe))
    assert watched == {'/pam/pressures'} and after == set()
    assert view.stop() == 0, view.stderr
