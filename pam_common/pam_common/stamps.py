"""Message stamps (builtin_interfaces/Time) to and from integer nanoseconds: the one place the
stack converts them (every node, tool and test uses these)."""

from __future__ import annotations

from builtin_interfaces.msg import Time

NS_PER_S = 1_000_000_000


def stamp_ns(stamp) -> int:
    """A builtin_interfaces/Time (or anything with sec, nanosec) in ns since the epoch."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def ns_stamp(ns: int) -> Time:
    """ns since the epoch (>= 0) as a builtin_interfaces/Time."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return Time(sec=sec, nanosec=nanosec)
