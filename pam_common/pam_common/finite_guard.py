"""FiniteGuard: no PAM node publishes a non-finite number, in any field, ever.

    guard = FiniteGuard(node.get_logger())
    command_pub = guard.wrap(node.create_publisher(ValveCommand, 'valve_command', qos),
                             safe={'u1': 5.5, 'u2': 5.5}, whole=True)
    estimate_pub = guard.wrap(node.create_publisher(JointEstimate, 'estimate', qos), hold=True)
    diagnostics.add_check(guard.report)          # pam_common.diagnostics.DiagnosticsPublisher

wrap() returns a publisher whose publish(msg) first checks every float field of msg (float32 and
float64 scalars, fixed arrays and sequences, in nested messages too: the list of fields is
worked out once per message type) and replaces each non-finite value (NaN, +-inf) in place by its
substitute, then publishes. The substitute of a field (a dotted path for a nested field, e.g.
'twist.linear.x'; an array element takes its array's):
    hold=True   the field's value in the last message of that publisher that was all finite
                (before the first one: as below);
    otherwise   safe[field] if given, else 0.0.
whole=True replaces every float field of a message that has any non-finite one (a valve command
goes to the safe command as a whole, not one valve of it). Elements of sequences of nested
messages always take safe/0.0.

Each substitution is counted per topic (values replaced), and the first in every `period`
seconds is logged as a warning (ThrottledLog, with the count left out since). report() is a
DiagnosticsPublisher check: the counts per topic, and WARN while substitutions happened since
the previous report (the last diagnostics period).

Cost: about 1 us per message with a dozen float fields and a 16-element array (math.isfinite on
each value); a message type without float fields (rosgraph_msgs/Clock, diagnostics) is not
wrapped at all. Thread-safe (a sampling thread and the executor may both publish).
"""

from __future__ import annotations

import importlib
import math
import threading
from collections.abc import Mapping
from functools import cache
from operator import attrgetter
from typing import NamedTuple

from rosidl_parser.definition import (
    FLOATING_POINT_TYPES,
    AbstractNestedType,
    BasicType,
    NamespacedType,
)

from .diagnostics import OK, WARN
from .throttled_log import ThrottledLog

isfinite = math.isfinite


class FloatFields(NamedTuple):
    """Where the float values of one message type are (None: it has none)."""

    scalars: tuple            # names of float scalar fields
    get_scalars: object       # msg -> tuple of their values
    arrays: tuple             # names of float array / sequence fields
    nested: tuple             # (name, FloatFields) of nested message fields
    nested_seqs: tuple        # (name, FloatFields) of array / sequence of message fields


def _message_class(t: NamespacedType):
    return getattr(importlib.import_module('.'.join(t.namespaces)), t.name)


def _is_float(t) -> bool:
    return isinstance(t, BasicType) and t.typename in FLOATING_POINT_TYPES


@cache
def float_fields(msg_type) -> FloatFields | None:
    """The float fields of a ROS message class, once per class; None if it has none."""
    scalars, arrays, nested, nested_seqs = [], [], [], []
    for name, slot in zip(msg_type.get_fields_and_field_types(), msg_type.SLOT_TYPES,
                          strict=True):
        if _is_float(slot):
            scalars.append(name)
        elif isinstance(slot, AbstractNestedType) and _is_float(slot.value_type):
            arrays.append(name)
        elif isinstance(slot, NamespacedType):
            inner = float_fields(_message_class(slot))
            if inner is not None:
                nested.append((name, inner))
        elif (isinstance(slot, AbstractNestedType)
              and isinstance(slot.value_type, NamespacedType)):
            inner = float_fields(_message_class(slot.value_type))
            if inner is not None:
                nested_seqs.append((name, inner))
    if not (scalars or arrays or nested or nested_seqs):
        return None
    if len(scalars) == 1:
        only = attrgetter(scalars[0])
        get_scalars = lambda msg: (only(msg),)   # noqa: E731
    else:
        get_scalars = attrgetter(*scalars) if scalars else (lambda msg: ())
    return FloatFields(tuple(scalars), get_scalars, tuple(arrays), tuple(nested),
                       tuple(nested_seqs))


def _finite(values) -> bool:
    """True if every value is finite: their sum first (fast; a sum can also overflow with
    finite values), each one if the sum is not finite."""
    return isfinite(sum(values)) or all(map(isfinite, values))


def all_finite(msg, fields: FloatFields) -> bool:
    """True if every float value of msg is finite."""
    if not _finite(fields.get_scalars(msg)):
        return False
    for name in fields.arrays:
        values = getattr(msg, name)      # numpy array (fixed size) or array.array (sequence)
        if not _finite(values.tolist()):
            return False
    for name, inner in fields.nested:
        if not all_finite(getattr(msg, name), inner):
            return False
    for name, inner in fields.nested_seqs:
        if not all(all_finite(item, inner) for item in getattr(msg, name)):
            return False
    return True


def _held(last, path: str, index: int | None):
    """The value at path (and index) of the last all-finite message, if finite; else None."""
    if last is None:
        return None
    try:
        value = attrgetter(path)(last)
        value = value[index] if index is not None else value
    except (AttributeError, IndexError):
        return None
    return float(value) if isfinite(value) else None


class _Substitutes:
    """The substitute of each float field of one publisher's messages."""

    def __init__(self, safe: Mapping[str, float], hold: bool, whole: bool):
        for field, value in safe.items():
            if not isfinite(value):
                raise ValueError(f'the safe value of {field} must be finite, got {value!r}')
        self.safe = {field: float(value) for field, value in safe.items()}
        self.hold = hold
        self.whole = whole
        self.last = None            # the last all-finite message (hold)

    def value(self, path: str, index: int | None = None, holdable: bool = True) -> float:
        if self.hold and holdable:
            held = _held(self.last, path, index)
            if held is not None:
                return held
        return self.safe.get(path, 0.0)

    def repair(self, msg, fields: FloatFields, prefix: str = '', holdable: bool = True) -> int:
        """Replace the non-finite (every, if whole) float values of msg; how many changed."""
        changed = 0
        for name in fields.scalars:
            value = getattr(msg, name)
            if self.whole or not isfinite(value):
                new = self.value(prefix + name, None, holdable)
                changed += int(new != value)
                setattr(msg, name, new)
        for name in fields.arrays:
            values = getattr(msg, name).tolist()
            bad = [i for i, v in enumerate(values) if self.whole or not isfinite(v)]
            for i in bad:
                new = self.value(prefix + name, i, holdable)
                changed += int(new != values[i])
                values[i] = new
            if bad:
                setattr(msg, name, values)
        for name, inner in fields.nested:
            changed += self.repair(getattr(msg, name), inner, f'{prefix}{name}.', holdable)
        for name, inner in fields.nested_seqs:
            for item in getattr(msg, name):
                changed += self.repair(item, inner, f'{prefix}{name}.', False)
        return changed


class GuardedPublisher:
    """A publisher whose publish() substitutes non-finite float values first (FiniteGuard.wrap);
    every other attribute is the wrapped publisher's."""

    def __init__(self, guard: FiniteGuard, publisher, fields: FloatFields,
                 substitutes: _Substitutes, subscribed_only: bool = False):
        self._guard = guard
        self._publisher = publisher
        self._fields = fields
        self._substitutes = substitutes
        self._subscribed_only = subscribed_only
        self.topic = publisher.topic_name

    def wanted(self) -> bool:
        """False for a subscribed_only publisher that no subscription matches now: its message
        need not even be built."""
        return not self._subscribed_only or self._publisher.get_subscription_count() > 0

    def publish(self, msg) -> None:
        if self._subscribed_only and not self._publisher.get_subscription_count():
            return
        if all_finite(msg, self._fields):
            self._substitutes.last = msg
        else:
            self._guard._substituted(self.topic, msg,
                                     self._substitutes.repair(msg, self._fields))
        self._publisher.publish(msg)

    def __getattr__(self, name):
        return getattr(self._publisher, name)


class FiniteGuard:
    """Wraps a node's publishers so that none publishes a non-finite float; counts the
    substitutions per topic for /diagnostics (report)."""

    def __init__(self, logger, period: float = 1.0):
        self._warn = ThrottledLog(logger, period)
        self._lock = threading.Lock()
        self.counts: dict[str, int] = {}          # topic -> values substituted so far
        self._reported: dict[str, int] = {}

    def wrap(self, publisher, safe: Mapping[str, float] | None = None, hold: bool = False,
             whole: bool = False, subscribed_only: bool = False):
        """The publisher, guarded (see the module docstring); as is if its message type has no
        float field. subscribed_only: publish only while a subscription (in any process, on any
        host) matches, for the optional 1 kHz streams nothing in the loop reads (JointState,
        controller_state): about 10 us per message saved when nobody listens."""
        fields = float_fields(publisher.msg_type)
        if fields is None:
            return publisher
        with self._lock:
            self.counts.setdefault(publisher.topic_name, 0)
        return GuardedPublisher(self, publisher, fields,
                                _Substitutes(safe or {}, hold, whole), subscribed_only)

    def _substituted(self, topic: str, msg, changed: int) -> None:
        with self._lock:
            self.counts[topic] += max(changed, 1)
            total = self.counts[topic]
        self._warn(f'non-finite value(s) in a message on {topic}: substituted (no node '
                   f'publishes a non-finite number); {total} so far on that topic')

    def report(self) -> tuple:
        """(level, problem, values) for DiagnosticsPublisher.add_check: WARN while values were
        substituted since the previous report."""
        with self._lock:
            counts = dict(self.counts)
        new = {topic: n - self._reported.get(topic, 0) for topic, n in counts.items()}
        self._reported = counts
        values = {f'non-finite values substituted on {topic}': n for topic, n in counts.items()}
        recent = [f'{n} on {topic}' for topic, n in new.items() if n]
        if recent:
            return WARN, ('non-finite values substituted in the last period: '
                          + ', '.join(recent)), values
        return OK, '', values
