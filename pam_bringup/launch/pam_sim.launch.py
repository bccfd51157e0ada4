"""The PAM stack with a full ROS 2 install: `ros2 launch pam_bringup pam_sim.launch.py`.

Starts, in namespace /pam, the nodes of pam_bringup.stack (the node list pam-bringup starts too):
the rig (sim_node, or driver_node with rig:=driver), ukf_node, reference_node and pi_node, all
with one params file (default: this package's config/bringup.yaml, one section per node keyed
/pam/<node>). Same stack as `pam-bringup`, which needs no launch package. Examples:

    ros2 launch pam_bringup pam_sim.launch.py
    ros2 launch pam_bringup pam_sim.launch.py params_file:=/path/my.yaml use_controller:=false
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from pam_bringup.stack import (
    CONTROLLER,
    DEFAULT_NAMESPACE,
    REFERENCE,
    RIGS,
    every_node,
    stack_nodes,
)


def stack_actions(context):
    """A Node action per node of pam_bringup.stack.stack_nodes for this launch's rig,
    use_reference and use_controller."""
    nodes = stack_nodes(LaunchConfiguration('rig').perform(context),
                        reference=IfCondition(LaunchConfiguration('use_reference'))
                        .evaluate(context),
                        controller=IfCondition(LaunchConfiguration('use_controller'))
                        .evaluate(context))
    return [Node(package=node.package, executable=node.name, name=node.name,
                 namespace=LaunchConfiguration('namespace'),
                 parameters=[LaunchConfiguration('params_file')], output='screen',
                 emulate_tty=True)
            for node in nodes]


def generate_launch_description():
    sections = ', '.join(f'{DEFAULT_NAMESPACE}/{node.name}' for node in every_node())
    rigs = '; '.join(f"'{rig}': {node.name} ({node.package})" for rig, node in RIGS.items())
    arguments = [
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution(
                [FindPackageShare('pam_bringup'), 'config', 'bringup.yaml']),
            description=f'ROS 2 params file with a section per node ({sections}).'),
        DeclareLaunchArgument(
            'rig', default_value='sim', choices=sorted(RIGS),
            description=f'The rig: {rigs}.'),
        DeclareLaunchArgument(
            'namespace', default_value=DEFAULT_NAMESPACE.lstrip('/'),
            description='Namespace of every node (the params file keys must match it).'),
        DeclareLaunchArgument(
            'use_controller', default_value='true', choices=['true', 'false'],
            description=f'Start the controller ({CONTROLLER.name}).'),
        DeclareLaunchArgument(
            'use_reference', default_value='true', choices=['true', 'false'],
            description=f'Start the reference generator ({REFERENCE.name}).'),
    ]
    return LaunchDescription([*arguments, OpaqueFunction(function=stack_actions)])
