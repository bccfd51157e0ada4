"""Messages of the 1 kHz path built in one step: every field given, in the message's order.

Why: the constructor that rosidl generates for a Python message class takes keyword arguments,
imports the nested types and builds a default for every field (a default Header, with its Time,
even when a header is given), then sets each field through its property; a composed stack
builds four such messages and their headers per sample, at 1 kHz. builder() makes, once per
class, a function that creates the message without the constructor and stores each given value
in its field directly. Measured on the 2-core development machine, with the header: a Pressures
2.7 -> 0.17 us, a JointEstimate 5.1 -> 0.9 us (its covariance copy included).

    header = builder(Header)                      # header(stamp, frame_id)
    pressures = builder(Pressures)                # pressures(header, p1, p2, sample)
    msg = pressures(header(stamp, 'pam'), p1, p2, 17)

The values go in as given, unchecked (the generated class checks them only when
ROS_PYTHON_CHECK_FIELDS=1 anyway): a float field takes a float, an integer field an int, a bool
field a bool, a fixed-size float array a numpy float64 array of its size, a nested message an
instance of its class. The messages are the generated class's own (equal to, and serialised as,
the constructor's: pam_common/test/test_fast_messages.py). The builder falls back to the
constructor, with the same arguments, where the class does not have the layout this relies on
(one slot '_<field>' per field and '_check_fields', as rosidl_generator_py writes them), or
where ROS_PYTHON_CHECK_FIELDS=1 asks for the checks.
"""

from __future__ import annotations

import keyword
from collections.abc import Callable
from functools import cache

__all__ = ['builder', 'is_direct']

_DIRECT: set[type] = set()      # the classes whose builder stores the fields directly


def _layout_known(msg_type) -> bool:
    fields = tuple(msg_type.get_fields_and_field_types())
    slots = set(getattr(msg_type, '__slots__', ()))
    return (all(name.isidentifier() and not keyword.iskeyword(name) for name in fields)
            and slots == {'_' + name for name in fields} | {'_check_fields'})


@cache
def builder(msg_type) -> Callable:
    """A function (field values, in the order of msg_type.get_fields_and_field_types()) ->
    a new msg_type message with those values."""
    fields = tuple(msg_type.get_fields_and_field_types())
    arguments = ', '.join(fields)
    if _layout_known(msg_type) and not msg_type()._check_fields:
        body = ''.join(f'    msg._{name} = {name}\n' for name in fields)
        source = (f'def build({arguments}):\n    msg = new(cls)\n'
                  f'    msg._check_fields = False\n{body}    return msg\n')
        _DIRECT.add(msg_type)
    else:
        keywords = ', '.join(f'{name}={name}' for name in fields)
        source = f'def build({arguments}):\n    return cls({keywords})\n'
    namespace = {'new': object.__new__, 'cls': msg_type}
    exec(source, namespace)       # source: the class's own field names, checked above
    build = namespace['build']
    build.__name__ = build.__qualname__ = f'build_{msg_type.__name__}'
    build.__doc__ = f'A new {msg_type.__name__}({arguments}).'
    return build


def is_direct(msg_type) -> bool:
    """True if builder(msg_type) stores the fields directly (False: it calls the constructor)."""
    builder(msg_type)
    return msg_type in _DIRECT
