"""fast_messages.builder: the 1 kHz path's messages, built in one step, are the constructor's
messages: equal field by field, serialised as theirs, and usable as any message after (a field
set through its property, a FiniteGuard repair); with ROS_PYTHON_CHECK_FIELDS=1 the builder is
the checking constructor.

Serialised messages are compared once read back, not byte for byte: the CDR serialiser leaves
the alignment padding (e.g. after a frame_id, before a float64) uninitialised, so two
serialisations of one message can differ there."""

import math
import os
import subprocess
import sys

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header

from pam_common.fast_messages import builder, is_direct
from pam_common.finite_guard import _Substitutes, all_finite, float_fields
from pam_interfaces.msg import JointEstimate, JointMeasurement, Pressures, ValveCommand


def header(sec=12, nanosec=345_678_901, frame_id='pam_joint'):
    return builder(Header)(builder(Time)(sec, nanosec), frame_id)


def stack_messages():
    """(type, values in field order) of every message the 1 kHz path builds this way."""
    covariance = np.arange(16, dtype=np.float64) * 0.25
    return [
        (Time, {'sec': 1_795_822_703, 'nanosec': 999_999_999}),
        (Header, {'stamp': Time(sec=3, nanosec=4), 'frame_id': 'pam_joint'}),
        (Pressures, {'header': Header(stamp=Time(sec=5, nanosec=6), frame_id='f'),
                     'p1': 412_345.5, 'p2': 287_001.25, 'sample': 64_001}),
        (JointMeasurement, {'header': Header(frame_id='f'), 'angle': -0.3125,
                            'angular_velocity': 1.5, 'torque': -7.75}),
        (ValveCommand, {'header': Header(stamp=Time(sec=7), frame_id='f'), 'u1': 6.5,
                        'u2': 4.0}),
        (JointEstimate, {'header': Header(stamp=Time(sec=9, nanosec=10), frame_id='f'),
                         'angle': 0.2, 'angular_velocity': -0.1, 'torque': 3.5, 'p1': 4.1e5,
                         'p2': 2.9e5, 'force1': 512.0, 'force2': 498.5,
                         'covariance': covariance, 'torque_variance': 0.0625, 'subsystem': 3,
                         'nis': 1.75, 'rejected_samples': 2, 'update_skipped': True,
                         'sample': 77}),
    ]


@pytest.mark.parametrize('msg_type, values', stack_messages(),
                         ids=lambda v: v.__name__ if isinstance(v, type) else '')
def test_a_built_message_is_the_constructors(msg_type, values):
    assert is_direct(msg_type)      # the generated layout is the one the builder relies on
    built = builder(msg_type)(**values)
    made = msg_type(**values)
    assert type(built) is msg_type
    assert built == made
    assert deserialize_message(serialize_message(built), msg_type) == made
    assert len(serialize_message(built)) == len(serialize_message(made))
    positional = builder(msg_type)(*values.values())     # the fields' order
    assert positional == made
    assert repr(built) == repr(made)


def test_a_built_message_takes_later_changes_as_any_message():
    msg = builder(ValveCommand)(header(), 6.5, 4.0)
    msg.u1 = 2.0                                     # through the property
    msg.header.frame_id = 'other'
    assert (msg.u1, msg.header.frame_id) == (2.0, 'other')
    assert deserialize_message(serialize_message(msg), ValveCommand) == ValveCommand(
        header=header(frame_id='other'), u1=2.0, u2=4.0)


def test_the_finite_guard_checks_and_repairs_a_built_message():
    covariance = np.ones(16)
    covariance[5] = math.nan
    est = builder(JointEstimate)(header(), 0.1, 0.0, math.inf, 4e5, 3e5, 1.0, 2.0, covariance,
                                 0.5, 1, 0.3, 0, False, 9)
    fields = float_fields(JointEstimate)
    assert not all_finite(est, fields)
    assert _Substitutes({}, hold=False, whole=False).repair(est, fields) == 2
    assert all_finite(est, fields)
    assert est.torque == 0.0 and est.covariance[5] == 0.0 and est.covariance[4] == 1.0
    assert deserialize_message(serialize_message(est), JointEstimate) == est


def test_each_call_builds_a_new_message():
    build = builder(Pressures)
    first, second = build(header(), 1.0, 2.0, 1), build(header(), 1.0, 2.0, 1)
    assert first == second and first is not second


def test_with_field_checks_asked_for_the_builder_is_the_checking_constructor():
    code = ('from pam_common.fast_messages import builder, is_direct\n'
            'from pam_interfaces.msg import ValveCommand\n'
            'from std_msgs.msg import Header\n'
            'assert not is_direct(ValveCommand)\n'
            'assert builder(ValveCommand)(Header(), 1.0, 2.0).u2 == 2.0\n'
            'try:\n'
            '    builder(ValveCommand)(Header(), "1", 2.0)\n'
            'except AssertionError:\n'
            '    print("checked")\n')
    env = dict(os.environ, ROS_PYTHON_CHECK_FIELDS='1')
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'checked'
