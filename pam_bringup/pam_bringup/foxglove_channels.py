"""What pam-foxglove serves and how, without ROS: the topics, their Foxglove channel schemas,
the URL to open, and the command-line shorthands.

Every served topic is one channel of the Foxglove WebSocket protocol with message encoding
`cdr` and a `ros2msg` schema: the type's definition with the definitions it uses appended, each
after a line of 80 '=' and `MSG: <type>`, the text a rosbag2 MCAP bag embeds (pam_bag's typestore,
rosbags' generate_msgdef, as BagWriter writes it). The serialized messages are forwarded as
received, so Foxglove decodes them as it decodes a bag, and no message is converted here.
"""

from __future__ import annotations

import socket
from collections.abc import Sequence
from dataclasses import dataclass

from pam_common.node_params import ConfigError
from pam_common.topics import (
    APPLIED_COMMAND,
    CONTROLLER_STATE,
    DIAGNOSTICS,
    ESTIMATE,
    ESTIMATE_JOINT_STATES,
    JOINT_MEASURED,
    JOINT_STATES,
    PRESSURES,
    REFERENCE,
    ROSOUT,
    SUPPLY_PRESSURE,
    VALVE_COMMAND,
    absolute,
)

from .stack import RIGS

DEFAULT_HOST = '127.0.0.1'
DEFAULT_PORT = 8765
SCHEMA_ENCODING = 'ros2msg'
MESSAGE_ENCODING = 'cdr'
ALL_INTERFACES = ('0.0.0.0', '::')    # hosts that listen on every interface of the machine

#: driver_node's ~/applied_command, seen from another node of its namespace.
DRIVER_APPLIED_COMMAND = APPLIED_COMMAND.replace('~', RIGS['driver'].name, 1)

#: The topics served (names relative to the stack's namespace, or absolute), with their types:
#: the stack's topics (pam_common.topics), the global /diagnostics and /rosout (the nodes' log
#: lines, for Foxglove's Log panel).
TOPICS: tuple[tuple[str, str], ...] = (
    (PRESSURES, 'pam_interfaces/msg/Pressures'),
    (JOINT_MEASURED, 'pam_interfaces/msg/JointMeasurement'),
    (SUPPLY_PRESSURE, 'sensor_msgs/msg/FluidPressure'),
    (JOINT_STATES, 'sensor_msgs/msg/JointState'),
    (ESTIMATE, 'pam_interfaces/msg/JointEstimate'),
    (ESTIMATE_JOINT_STATES, 'sensor_msgs/msg/JointState'),
    (REFERENCE, 'pam_interfaces/msg/Reference'),
    (CONTROLLER_STATE, 'pam_interfaces/msg/ControllerState'),
    (VALVE_COMMAND, 'pam_interfaces/msg/ValveCommand'),
    (DRIVER_APPLIED_COMMAND, 'pam_interfaces/msg/ValveCommand'),
    (DIAGNOSTICS, 'diagnostic_msgs/msg/DiagnosticArray'),
    (ROSOUT, 'rcl_interfaces/msg/Log'),
)


@dataclass(frozen=True)
class ServedTopic:
    """One served topic: its absolute name and its type ('pkg/msg/Type')."""

    name: str
    msgtype: str


def select_topics(text: str, namespace: str) -> list[ServedTopic]:
    """The topics of the `topics` parameter: '' for all of TOPICS, else a comma-separated list
    of their names, relative to `namespace` ('pressures, estimate') or absolute
    ('/pam/pressures', '/diagnostics'), in the order of TOPICS. A name TOPICS does not hold is
    a ConfigError naming the ones it does."""
    known = {absolute(name, namespace): msgtype for name, msgtype in TOPICS}
    wanted = [absolute(name.strip(), namespace) for name in text.split(',') if name.strip()]
    unknown = [name for name in wanted if name not in known]
    if unknown:
        raise ConfigError(f"parameter 'topics': unknown topic {unknown[0]!r}; pam-foxglove "
                          f"serves: {', '.join(known)}")
    return [ServedTopic(name, msgtype) for name, msgtype in known.items()
            if not wanted or name in wanted]


def check_host(host: str) -> str:
    """The `host` parameter, stripped; a ConfigError if it is empty or not an address or name
    this machine can resolve."""
    host = host.strip()
    if not host:
        raise ConfigError("parameter 'host': empty; use 127.0.0.1 (this machine only) or "
                          '0.0.0.0 (every interface)')
    try:
        socket.getaddrinfo(host, None)
    except (OSError, UnicodeError) as exc:
        raise ConfigError(f"parameter 'host': cannot resolve {host!r}: {exc}") from None
    return host


def url(host: str, port: int) -> str:
    """The URL a Foxglove client opens: ws://host:port; for a server on every interface, with
    this machine's name (what another machine opens)."""
    if host in ALL_INTERFACES:
        host = socket.gethostname()
    elif ':' in host:           # an IPv6 address
        host = f'[{host}]'
    return f'ws://{host}:{port}'


def ros2msg_schemas(msgtypes: Sequence[str]) -> dict[str, bytes]:
    """The ros2msg schema text (UTF-8) of each type, as a rosbag2 MCAP bag embeds it."""
    from pam_bag.bags import make_typestore
    store = make_typestore()
    return {msgtype: store.generate_msgdef(msgtype, ros_version=2)[0].encode()
            for msgtype in dict.fromkeys(msgtypes)}


# ---------------------------------------------------------------------------- command line
#: Shorthand option -> the ROS argument it stands for.
SHORTHANDS = {'--host': 'host', '--port': 'port', '--topics': 'topics', '--namespace': '__ns'}
SHORTHAND_HELP = [
    'Options (shorthands for the ROS arguments; before any --ros-args):',
    "  --host HOST       -p host:=HOST     0.0.0.0 serves every interface, so that another "
    'machine',
    '                                      can connect (no authentication: trusted networks only)',
    '  --port PORT       -p port:=PORT',
    '  --topics LIST     -p topics:=LIST',
    "  --namespace NS    -r __ns:=NS       the stack's namespace (default /pam)",
]


def _quoted(value: str) -> str:
    """A YAML single-quoted string: -p values are YAML, and a host such as 1 or a list of
    topics must stay a string."""
    return "'" + value.replace("'", "''") + "'"


def expand_shorthands(argv: Sequence[str]) -> list[str]:
    """argv with the shorthand options before the first --ros-args turned into ROS arguments
    appended at the end (`--port 8766` -> `--ros-args -p port:=8766`; `--opt=value` too);
    anything else stays where it is (an unknown option is then reported by the node's
    argument check). A shorthand without its value is a ConfigError."""
    argv = list(argv)
    end = argv.index('--ros-args') if '--ros-args' in argv else len(argv)
    kept, ros, i = argv[:1], [], 1
    while i < end:
        option, has_value, value = argv[i].partition('=')
        if option not in SHORTHANDS:
            kept.append(argv[i])
            i += 1
            continue
        if not has_value:
            if i + 1 >= end:
                raise ConfigError(f'option {option} needs a value')
            value, i = argv[i + 1], i + 1
        i += 1
        name = SHORTHANDS[option]
        if name == '__ns':
            ros += ['-r', f"__ns:={value if value.startswith('/') else '/' + value}"]
        elif name == 'port':
            ros += ['-p', f'port:={value}']
        else:
            ros += ['-p', f'{name}:={_quoted(value)}']
    return kept + argv[end:] + (['--ros-args', *ros] if ros else [])
