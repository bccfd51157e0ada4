"""The PAM stack with a full ROS 2 install: `ros2 launch pam_bringup pam_sim.launch.py`.

Starts, in namespace /pam, the rig (sim_node, or driver_node with rig:=driver), ukf_node,
reference_node and pi_node, all with one params file (default: this package's
config/bringup.yaml, one section per node keyed /pam/<node>). Same stack as `pam-bringup`, which
needs no launch package. Examples:

    ros2 launch pam_bringup pam_sim.launch.py
    ros2 launch pam_bringup pam_sim.launch.py params_file:=/path/my.yaml use_controller:=false
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    params_file = LaunchConfiguration('params_file')
    namespace = LaunchConfiguration('namespace')
    rig = LaunchConfiguration('rig')

    arguments = [
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution(
                [FindPackageShare('pam_bringup'), 'config', 'bringup.yaml']),
            description='ROS 2 params file with a section per node (/pam/sim_node, '
                        '/pam/ukf_node, /pam/pi_node, /pam/reference_node).'),
        DeclareLaunchArgument(
            'rig', default_value='sim', choices=['sim', 'driver'],
            description="'sim': the simulated rig sim_node; 'driver': driver_node (pam_driver)."),
        DeclareLaunchArgument(
            'namespace', default_value='pam',
            description='Namespace of every node (the params file keys must match it).'),
        DeclareLaunchArgument(
            'use_controller', default_value='true', choices=['true', 'false'],
            description='Start pi_node.'),
        DeclareLaunchArgument(
            'use_reference', default_value='true', choices=['true', 'false'],
            description='Start reference_node.'),
    ]

    def node(package, executable, condition=None):
        return Node(package=package, executable=executable, name=executable,
                    namespace=namespace, parameters=[params_file], output='screen',
                    emulate_tty=True, condition=condition)

    nodes = [
        # rig:=sim -> sim_node, rig:=driver -> driver_node, both of pam_driver
        Node(package='pam_driver', executable=[rig, '_node'], name=[rig, '_node'],
             namespace=namespace, parameters=[params_file], output='screen', emulate_tty=True),
        node('pam_estimator', 'ukf_node'),
        node('pam_controller', 'reference_node',
             condition=IfCondition(LaunchConfiguration('use_reference'))),
        node('pam_controller', 'pi_node',
             condition=IfCondition(LaunchConfiguration('use_controller'))),
    ]
    return LaunchDescription(arguments + nodes)
