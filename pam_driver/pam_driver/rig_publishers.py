"""The publishers both rigs have (sim_node, driver_node), made one way: pressures and
joint_measured through a FiniteGuard that holds the last finite values (a non-finite sample never
leaves the node), and joint_measured as sensor_msgs/JointState for the standard tools
(pam_common.joint_states), all with the sample profile (SAMPLE_QOS); and the builders of their
per-sample messages (pam_common.fast_messages: one step each, not rosidl's constructor)."""

from __future__ import annotations

from dataclasses import dataclass

from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from pam_common.fast_messages import builder
from pam_common.finite_guard import FiniteGuard
from pam_common.joint_states import JointStates
from pam_common.qos import SAMPLE_QOS
from pam_common.topics import JOINT_MEASURED, JOINT_STATES, PRESSURES
from pam_interfaces.msg import JointMeasurement, Pressures

build_header = builder(Header)                  # (stamp, frame_id)
build_pressures = builder(Pressures)            # (header, p1, p2, sample)
build_joint = builder(JointMeasurement)         # (header, angle, angular_velocity, torque)


@dataclass
class RigPublishers:
    guard: FiniteGuard              # of every publisher here (and those the node adds to it)
    pressures: object               # pam_interfaces/Pressures, guarded
    joint: object                   # pam_interfaces/JointMeasurement, guarded
    joint_states: JointStates       # sensor_msgs/JointState (off at joint_states_rate 0)


def rig_publishers(node, frame_id: str, joint_name: str, joint_states_rate: float,
                   sample_rate: float | None) -> RigPublishers:
    """The rig's sample publishers on `node`; `sample_rate` Hz (None: known later, e.g. a DAQ
    board's at the handshake) sets which samples the JointState takes."""
    guard = FiniteGuard(node.get_logger())
    pressures = guard.wrap(node.create_publisher(Pressures, PRESSURES, SAMPLE_QOS), hold=True)
    joint = guard.wrap(node.create_publisher(JointMeasurement, JOINT_MEASURED, SAMPLE_QOS),
                       hold=True)
    states = JointStates(
        guard.wrap(node.create_publisher(JointState, JOINT_STATES, SAMPLE_QOS))
        if joint_states_rate else None, JointState(), joint_name, frame_id, joint_states_rate,
        sample_rate)
    return RigPublishers(guard, pressures, joint, states)
