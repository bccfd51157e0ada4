"""Unit tests of pam_common.diagnostics (no running ROS: a fake node stands in)."""

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from pam_common.diagnostics import (
    ERROR,
    OK,
    WARN,
    DiagnosticsPublisher,
    format_value,
    is_status_of,
    level_from,
    make_status,
    status_node,
    status_values,
)
from pam_common.node_params import HARDWARE_ID_PARAM


@pytest.mark.parametrize('value, text', [
    ('free', 'free'), (True, 'true'), (False, 'false'), (42, '42'), (-1, '-1'),
    (1000.0, '1000'), (999.8123456, '999.812'), (0.000123456789, '0.000123457'),
    (math.nan, 'n/a'), (math.inf, 'n/a'), (-math.inf, 'n/a'), ([1.0, math.nan], '1, n/a'),
    ([5.5, 10.0], '5.5, 10'), ((1, 'a'), '1, a'),
    (np.float64(2.5), '2.5'), (np.int64(7), '7'), (np.array([1.0, 2.0]), '1, 2'),
])
def test_format_value(value, text):
    assert format_value(value) == text


def test_level_from_names_numbers_and_constants():
    assert level_from(OK) == DiagnosticStatus.OK
    assert level_from('warn') == DiagnosticStatus.WARN
    assert level_from('WARNING') == DiagnosticStatus.WARN
    assert level_from(2) == DiagnosticStatus.ERROR
    assert level_from('stale') == DiagnosticStatus.STALE
    for bad in ('fine', 7, -1, 1.0, None, True):
        with pytest.raises(ValueError):
            level_from(bad)


def test_make_status_keeps_order_and_formats():
    status = make_status('n: task', 'hw', 'WARN', 'careful',
                         {'b': 1.5, 'a': True, 'rate (Hz)': 999.95})
    assert status.name == 'n: task' and status.hardware_id == 'hw'
    assert status.level == WARN and status.message == 'careful'
    assert [kv.key for kv in status.values] == ['b', 'a', 'rate (Hz)']
    assert status_values(status) == {'b': '1.5', 'a': 'true', 'rate (Hz)': '999.95'}


class _FakeClock:
    def now(self):
        class _Now:
            def to_msg(self_inner):
                from builtin_interfaces.msg import Time
                return Time(sec=12, nanosec=34)
        return _Now()


class _FakeNode:
    def __init__(self):
        self.published = []
        self.timers = []
        self.topic = None

    def create_publisher(self, msg_type, topic, qos):
        self.topic = (msg_type, topic, qos)
        node = self

        class _Pub:
            def publish(self, msg):
                node.published.append(msg)
        return _Pub()

    def create_timer(self, period, callback):
        self.timers.append((period, callback))
        return object()

    def get_clock(self):
        return _FakeClock()

    def get_fully_qualified_name(self):
        return '/ns/x'

    def get_namespace(self):
        return '/ns'


def test_publisher_builds_one_status_per_period():
    node = _FakeNode()
    calls = []

    def report():
        calls.append(1)
        return OK, 'fine', {'samples': len(calls)}

    pub = DiagnosticsPublisher(node, 'y', 'hw-1', report, period=0.5)
    assert node.topic[0] is DiagnosticArray and node.topic[1] == '/diagnostics'
    period, tick = node.timers[0]
    assert period == 0.5
    tick()
    tick()
    assert len(node.published) == 2
    array = node.published[-1]
    assert array.header.stamp.sec == 12
    assert len(array.status) == 1
    assert array.status[0].name == '/ns/x: y' and array.status[0].hardware_id == 'hw-1'
    assert status_values(array.status[0]) == {'samples': '2'}
    assert pub.build().level == OK


def test_the_name_carries_the_node_and_hardware_id_defaults_to_the_namespace():
    """'/ns/x: rig' (the fully qualified node name), hardware_id '' -> the namespace: two
    stacks in two namespaces are told apart; the parameter row every node shares says so."""
    status = DiagnosticsPublisher(_FakeNode(), 'rig', '', lambda: (OK, 'ok', {})).build()
    assert (status.name, status.hardware_id) == ('/ns/x: rig', '/ns')
    assert (HARDWARE_ID_PARAM.name, HARDWARE_ID_PARAM.default) == ('hardware_id', '')
    assert HARDWARE_ID_PARAM.type_name == 'string'


def test_statuses_are_found_by_node():
    assert status_node('/joint2/sim_node: simulated rig') == '/joint2/sim_node'
    assert is_status_of('/joint2/sim_node: simulated rig', 'sim_node')
    assert is_status_of('/joint2/sim_node: simulated rig', '/joint2/sim_node')
    assert not is_status_of('/joint2/sim_node: simulated rig', '/pam/sim_node')
    assert not is_status_of('/pam/sim_node_2: simulated rig', 'sim_node')
    assert not is_status_of('/pam/sim_node_2: simulated rig', '/pam/sim_node')


def test_failing_callback_gives_error_status():
    node = _FakeNode()

    def broken():
        raise RuntimeError('boom')

    pub = DiagnosticsPublisher(node, 'x', 'hw', broken)
    node.timers[0][1]()
    status = node.published[0].status[0]
    assert status.level == ERROR and 'boom' in status.message
    assert pub.build().level == ERROR


def test_publisher_rejects_bad_period():
    with pytest.raises(ValueError):
        DiagnosticsPublisher(_FakeNode(), 'x', 'hw', lambda: (OK, '', {}), period=0.0)


def test_checks_are_merged_into_the_status():
    """add_check: values appended; a problem appended to the message and the level raised to
    the check's level only if worse; no problem: the callback's status as it is."""
    level = [OK]
    pub = DiagnosticsPublisher(_FakeNode(), 'x', 'hw',
                               lambda: (level[0], 'running', {'a': 1}))
    problem = ['']
    pub.add_check(lambda: (WARN, problem[0], {'b': 2}))
    status = pub.build()
    assert (status.level, status.message, status_values(status)) == (
        OK, 'running', {'a': '1', 'b': '2'})
    problem[0] = '3 values substituted'
    status = pub.build()
    assert (status.level, status.message) == (WARN, 'running; 3 values substituted')
    level[0] = ERROR
    assert pub.build().level == ERROR


def test_the_ros_free_levels_are_diagnostic_msgs_levels():
    """pam_common.levels (what the ROS-free cores decide) are DiagnosticStatus's bytes."""
    from pam_common import levels
    assert (levels.OK, levels.WARN, levels.ERROR, levels.STALE) == (
        DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR,
        DiagnosticStatus.STALE)
    assert (OK, WARN, ERROR) == (levels.OK, levels.WARN, levels.ERROR)
    assert max(levels.OK, levels.WARN, levels.ERROR) == levels.ERROR
