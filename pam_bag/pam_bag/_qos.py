"""QoS profiles in the form metadata.yaml's offered_qos_profiles holds (rosbags' Qos), built
from keywords or from rmw's integer policies. rosbags is imported when a profile is first built,
so that importing pam_bag.bags (a node's --help) stays quick.

Imported through pam_bag.bags, the library's public face."""

from __future__ import annotations


def make_qos(reliable: bool = True, depth: int = 100, transient_local: bool = False,
             keep_all: bool = False):
    """A rosbags Qos (the form of metadata.yaml's offered_qos_profiles)."""
    from rosbags import interfaces as q
    infinite = q.QosTime(sec=2147483647, nsec=4294967295)
    return q.Qos(
        history=q.QosHistory.KEEP_ALL if keep_all else q.QosHistory.KEEP_LAST, depth=depth,
        reliability=q.QosReliability.RELIABLE if reliable else q.QosReliability.BEST_EFFORT,
        durability=(q.QosDurability.TRANSIENT_LOCAL if transient_local
                    else q.QosDurability.VOLATILE),
        deadline=infinite, lifespan=infinite, liveliness=q.QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=infinite, avoid_ros_namespace_conventions=False)


def qos_from_ints(history: int, depth: int, reliability: int, durability: int, liveliness: int,
                  deadline=(0, 0), lifespan=(0, 0), lease=(0, 0)):
    """A rosbags Qos from the integer enums of rmw (rclpy's QoSProfile policies use the same)."""
    from rosbags import interfaces as q

    def enum(cls, value):
        try:
            return cls(int(value))
        except ValueError:
            return cls.UNKNOWN
    return q.Qos(history=enum(q.QosHistory, history), depth=int(depth),
                 reliability=enum(q.QosReliability, reliability),
                 durability=enum(q.QosDurability, durability), deadline=q.QosTime(*deadline),
                 lifespan=q.QosTime(*lifespan), liveliness=enum(q.QosLiveliness, liveliness),
                 liveliness_lease_duration=q.QosTime(*lease),
                 avoid_ros_namespace_conventions=False)
