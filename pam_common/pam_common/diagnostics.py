"""A tiny stand-in for diagnostic_updater (not available on PyPI), reusable by every PAM node.

    from pam_common.diagnostics import DiagnosticsPublisher, OK, WARN

    def report():
        return OK, 'running', {'samples published': 1234, 'achieved rate (Hz)': 999.8}

    PARAMETERS = (..., HARDWARE_ID_PARAM)          # pam_common.node_params: in every node's table
    DiagnosticsPublisher(node, 'UKF estimator', values['hardware_id'], report)

publishes on the absolute topic /diagnostics (diagnostic_msgs/DiagnosticArray, reliable, keep
last 10, like diagnostic_updater) every `period` seconds one DiagnosticStatus built from what the
callback returns: (level, message, values). Its name is the node's fully qualified name and the
title, '/pam/ukf_node: UKF estimator', so two stacks in two namespaces on one domain are told
apart; its hardware_id is the node's hardware_id parameter (the row
pam_common.node_params.HARDWARE_ID_PARAM), by default '' which stands for the node's namespace
('/pam'). level is OK/WARN/ERROR/STALE (the byte constants of DiagnosticStatus) or their
names; values is a mapping of key -> value, formatted by format_value. A callback that raises
yields an ERROR status naming the exception instead of killing the node.

The module-level helpers (format_value, level_from, make_status) need no running ROS.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from .levels import ERROR, LEVEL_NAMES, OK, STALE, WARN  # noqa: F401 - the levels of this API
from .links import process_links
from .topics import DIAGNOSTICS

# the levels are pam_common.levels' (ROS-free, the same bytes as DiagnosticStatus's)
_LEVELS_BY_NAME = {name: level for level, name in LEVEL_NAMES.items()}
_LEVELS_BY_NAME['WARNING'] = WARN

DIAGNOSTICS_TOPIC = DIAGNOSTICS
NOT_AVAILABLE = 'n/a'     # the text of a non-finite value (format_value)


def status_name(node_name: str, title: str) -> str:
    """The name of a node's status: '/pam/sim_node: simulated rig' of ('/pam/sim_node',
    'simulated rig'); node_name is the fully qualified name."""
    return f'{node_name}: {title}'


def status_node(name: str) -> str:
    """The node of a status name: '/pam/sim_node' of '/pam/sim_node: simulated rig'."""
    return name.split(': ', 1)[0]


def is_status_of(name: str, node: str) -> bool:
    """Whether the status called `name` is the node's: `node` is a fully qualified name
    ('/pam/sim_node': that node only) or a bare node name ('sim_node': in any namespace)."""
    fqn = status_node(name)
    return fqn == node if node.startswith('/') else fqn.rsplit('/', 1)[-1] == node


def level_from(level) -> bytes:
    """A DiagnosticStatus level (bytes of length 1) from a level constant, an int or a name."""
    if isinstance(level, (bytes, bytearray)) and len(level) == 1:
        value = level[0]
    elif isinstance(level, str):
        try:
            return _LEVELS_BY_NAME[level.strip().upper()]
        except KeyError:
            raise ValueError(f'unknown diagnostic level {level!r}; use OK, WARN, ERROR or '
                             f'STALE') from None
    elif isinstance(level, int) and not isinstance(level, bool):
        value = level
    else:
        raise ValueError(f'unknown diagnostic level {level!r}')
    result = bytes([value]) if 0 <= value <= 255 else None
    if result not in LEVEL_NAMES:
        raise ValueError(f'unknown diagnostic level {level!r}; use OK, WARN, ERROR or STALE')
    return result


def format_value(value, digits: int = 6) -> str:
    """A value as the string of a KeyValue: bools 'true'/'false', floats with `digits`
    significant digits, sequences as comma-separated items. A non-finite float (a figure not
    available yet: no sample received, no rate window, no watchdog trip) is 'n/a': /diagnostics
    never carries a non-finite number either (the fault campaign counts them)."""
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return NOT_AVAILABLE
        return f'{value:.{digits}g}'
    if isinstance(value, (bytes, bytearray)):
        return value.hex()
    if isinstance(value, (list, tuple)):
        return ', '.join(format_value(v, digits) for v in value)
    try:  # numpy scalars and arrays, without importing numpy here
        return format_value(value.tolist(), digits)
    except AttributeError:
        return str(value)


def make_status(name: str, hardware_id: str, level, message: str,
                values: Mapping[str, object] | None = None) -> DiagnosticStatus:
    """One DiagnosticStatus with formatted key/values, in the mapping's order."""
    status = DiagnosticStatus()
    status.name = name
    status.hardware_id = hardware_id
    status.level = level_from(level)
    status.message = message
    status.values = [KeyValue(key=str(key), value=format_value(value))
                     for key, value in (values or {}).items()]
    return status


def status_values(status: DiagnosticStatus) -> dict[str, str]:
    """The key/values of a DiagnosticStatus as a dict (for tests and tools)."""
    return {kv.key: kv.value for kv in status.values}


ReportCallback = Callable[[], tuple]


class DiagnosticsPublisher:
    """Publishes one status on /diagnostics every `period` s from `callback()`.

    The status is named status_name(node's fully qualified name, title); hardware_id '' is the
    node's namespace. callback() returns (level, message, values). The timer uses the node's
    clock and executor; call publish_now() to send a status outside the period (e.g. at
    shutdown). add_check() adds a check shared by nodes (e.g. FiniteGuard.report) to every status.
    """

    def __init__(self, node, title: str, hardware_id: str, callback: ReportCallback,
                 period: float = 1.0, topic: str = DIAGNOSTICS_TOPIC, qos_depth: int = 10):
        if not (math.isfinite(period) and period > 0.0):
            raise ValueError(f'diagnostics period must be > 0 s, got {period!r}')
        self._node = node
        self.name = status_name(node.get_fully_qualified_name(), title)
        self.hardware_id = hardware_id or node.get_namespace()
        self._callback = callback
        self._checks: list[ReportCallback] = []
        self.period = period
        self._publisher = node.create_publisher(DiagnosticArray, topic, qos_depth)
        # a LinkedNode's plain timer: with in-process links on, publish_now holds the process's
        # lock only while it reads the node (build), not while the status is converted and
        # written to DDS (a few ms a second on the 1 kHz path otherwise)
        make_timer = getattr(node, 'create_plain_timer', node.create_timer)
        self._timer = make_timer(period, self.publish_now)

    def add_check(self, check: ReportCallback) -> None:
        """check() -> (level, problem, values), merged into every status: its values appended,
        and when problem is not empty, problem appended to the message and the level raised to
        its level if that is worse."""
        self._checks.append(check)

    def build(self) -> DiagnosticStatus:
        """Call the callback and the checks and build the status (ERROR if one fails)."""
        try:
            level, message, values = self._callback()
            level, values = level_from(level), dict(values or {})
            for check in self._checks:
                check_level, problem, check_values = check()
                values.update(check_values)
                if problem:
                    message = f'{message}; {problem}' if message else problem
                    level = max(level, level_from(check_level))
            return make_status(self.name, self.hardware_id, level, message, values)
        except Exception as exc:  # noqa: BLE001 - a report must never take the node down
            return make_status(self.name, self.hardware_id, ERROR,
                               f'diagnostics callback failed: {type(exc).__name__}: {exc}')

    def publish_now(self) -> None:
        links = process_links()
        if links is None:
            status = self.build()
        else:
            with links.lock:        # the node's state, read as its other callbacks see it
                status = self.build()
        array = DiagnosticArray()
        array.header.stamp = self._node.get_clock().now().to_msg()
        array.status = [status]
        self._publisher.publish(array)

    def destroy(self) -> None:
        self._node.destroy_timer(self._timer)
        self._node.destroy_publisher(self._publisher)
