"""The PAM stack with a full ROS 2 install: `ros2 launch pam_bringup pam_sim.launch.py`.

Starts, in namespace /pam, the nodes of pam_bringup.stack (the node list pam-bringup starts too):
the rig (sim_node, or driver_node with rig:=driver), ukf_node, reference_node and pi_node, all
with one params file (default: this package's config/bringup.yaml, one section per node keyed
/pam/<node>). With namespace:=joint2 the nodes get a copy of the file whose /pam sections are
re-keyed to /joint2 (pam_bringup.params_namespace.stack_params, as pam-bringup --namespace; the
copy is in a directory removed when the launch exits; a section of the file for /joint2 itself
wins). As pam-bringup does by default, the nodes are composed in one process, pam_container
(composed:=false: a process per node; docs/composition.md). Same stack as `pam-bringup`, which
needs no launch package. Examples:

    ros2 launch pam_bringup pam_sim.launch.py
    ros2 launch pam_bringup pam_sim.launch.py composed:=false
    ros2 launch pam_bringup pam_sim.launch.py params_file:=/path/my.yaml use_controller:=false
    ros2 launch pam_bringup pam_sim.launch.py namespace:=joint2
"""

import launch.logging
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare
from launch_ros.utilities import make_namespace_absolute, prefix_namespace

from pam_bringup.params_namespace import run_directory, stack_params
from pam_bringup.stack import (
    CONTAINER,
    CONTROLLER,
    DEFAULT_NAMESPACE,
    REFERENCE,
    RIGS,
    container_options,
    every_node,
    stack_nodes,
)


def stack_actions(context):
    """The nodes of pam_bringup.stack.stack_nodes for this launch's rig, use_reference and
    use_controller, in its namespace (relative: under an including launch file's
    PushRosNamespace, as Node itself resolves it), with the params file stack_params gives for
    that namespace: one Node action, pam_container, composing them (composed:=true), or a Node
    action per node."""
    rig = LaunchConfiguration('rig').perform(context)
    reference = IfCondition(LaunchConfiguration('use_reference')).evaluate(context)
    controller = IfCondition(LaunchConfiguration('use_controller')).evaluate(context)
    nodes = stack_nodes(rig, reference=reference, controller=controller)
    namespace = make_namespace_absolute(prefix_namespace(
        context.launch_configurations.get('ros_namespace'),
        LaunchConfiguration('namespace').perform(context)))
    params = stack_params(LaunchConfiguration('params_file').perform(context), namespace,
                          [node.name for node in nodes], run_directory('pam_sim_launch_'))
    logger = launch.logging.get_logger('pam_sim.launch')
    if params.moved:
        logger.info(params.describe())
    for warning in params.warnings:
        logger.warning(warning)
    if IfCondition(LaunchConfiguration('composed')).evaluate(context):
        # no name=: a node-name remap would rename every node of the container
        return [Node(package=CONTAINER.package, executable=CONTAINER.name,
                     namespace=namespace, parameters=[str(params.file)],
                     arguments=container_options(rig, reference=reference,
                                                 controller=controller),
                     output='screen', emulate_tty=True)]
    return [Node(package=node.package, executable=node.name, name=node.name,
                 namespace=namespace, parameters=[str(params.file)], output='screen',
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
            description=f'Namespace of every node; the params file\'s {DEFAULT_NAMESPACE} '
                        'sections apply to it (a section for the namespace itself wins).'),
        DeclareLaunchArgument(
            'composed', default_value='true', choices=['true', 'false'],
            description=f'true: the nodes composed in one process ({CONTAINER.name}), as '
                        'pam-bringup does by default; false: a process per node.'),
        DeclareLaunchArgument(
            'use_controller', default_value='true', choices=['true', 'false'],
            description=f'Start the controller ({CONTROLLER.name}).'),
        DeclareLaunchArgument(
            'use_reference', default_value='true', choices=['true', 'false'],
            description=f'Start the reference generator ({REFERENCE.name}).'),
    ]
    return LaunchDescription([*arguments, OpaqueFunction(function=stack_actions)])
