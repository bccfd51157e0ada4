"""Message stamps (builtin_interfaces/Time) to and from integer nanoseconds: the one place the
stack converts them (every node, tool and test uses these; pam_common/test/test_layout.py fails
on a conversion written anywhere else).

stamp_ns reads anything with `sec` and `nanosec` (an rclpy message, a rosbags message); only
ns_stamp imports ROS (builtin_interfaces), so tools that read bags without rclpy can use the rest.
"""

from __future__ import annotations

NS_PER_S = 1_000_000_000


def stamp_ns(stamp) -> int:
    """A builtin_interfaces/Time (or anything with sec, nanosec) in ns since the epoch."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def stamps_ns(sec, nanosec):
    """stamp_ns over arrays: numpy integer arrays of the sec and nanosec fields of many stamps
    (e.g. a bag's columns) as an int64 array of ns since the epoch (no numpy import here: the
    arrays carry it)."""
    return sec.astype('int64') * NS_PER_S + nanosec.astype('int64')


def ns_pair(ns) -> tuple[int, int]:
    """ns (an int, or a float: truncated to whole ns) as (sec, nanosec), 0 <= nanosec < 1e9:
    the fields of a builtin_interfaces/Time or Duration."""
    return divmod(int(ns), NS_PER_S)


def ns_stamp(ns):
    """ns since the epoch (>= 0) as a builtin_interfaces/Time."""
    from builtin_interfaces.msg import Time

    from .fast_messages import builder
    return builder(Time)(*ns_pair(ns))
