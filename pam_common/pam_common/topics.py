"""The stack's topic names: the one place they are written (their QoS: pam_common.qos).

Names without a leading '/' are relative: they resolve under the node's namespace
(DEFAULT_NAMESPACE, '/pam', unless remapped with `--ros-args -r __ns:=/other`); '~/' names
under the node's own name. The names are part of the stack's interface (bags, launch files,
other robots' nodes use them): change none of them. No ROS import here: the bag tools that run
without rclpy use these too.

    topic              type                              published by
    pressures          pam_interfaces/Pressures          sim_node, driver_node
    supply_pressure    sensor_msgs/FluidPressure         sim_node (publish_supply_pressure),
                                                         driver_node (a board with the supply
                                                         transducer): P_tank in Pa abs,
                                                         header.stamp = its pressures sample's,
                                                         variance Pa^2 (0: unknown)
    joint_measured     pam_interfaces/JointMeasurement   sim_node, driver_node
    valve_command      pam_interfaces/ValveCommand       pi_node, profile_player
    estimate           pam_interfaces/JointEstimate      ukf_node
    joint_states       sensor_msgs/JointState            sim_node, driver_node (the measured
                                                         joint, for the standard tools)
    estimate/joint_states  sensor_msgs/JointState        ukf_node (the estimate, likewise)
    controller_state   pam_interfaces/ControllerState    pi_node
    reference          pam_interfaces/Reference          reference_node
    ~/applied_command  pam_interfaces/ValveCommand       driver_node
    /diagnostics       diagnostic_msgs/DiagnosticArray   every node
    /clock             rosgraph_msgs/Clock               sim_node (publish_clock), bag_play (clock)
    /rosout            rcl_interfaces/Log                every node (rclpy's log lines; read by
                                                         pam-foxglove and the tests)
"""

from __future__ import annotations

DEFAULT_NAMESPACE = '/pam'

PRESSURES = 'pressures'
SUPPLY_PRESSURE = 'supply_pressure'
JOINT_MEASURED = 'joint_measured'
VALVE_COMMAND = 'valve_command'
ESTIMATE = 'estimate'
JOINT_STATES = 'joint_states'
ESTIMATE_JOINT_STATES = 'estimate/joint_states'
CONTROLLER_STATE = 'controller_state'
REFERENCE = 'reference'
APPLIED_COMMAND = '~/applied_command'
DIAGNOSTICS = '/diagnostics'
CLOCK = '/clock'
ROSOUT = '/rosout'


def absolute(name: str, namespace: str = DEFAULT_NAMESPACE) -> str:
    """A relative topic name under `namespace` ('pressures' -> '/pam/pressures'); an absolute
    name unchanged."""
    if name.startswith('/'):
        return name
    return namespace.rstrip('/') + '/' + name
