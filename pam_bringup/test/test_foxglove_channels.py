"""pam-foxglove's ROS-free part (pam_bringup.foxglove_channels): which topics it serves, their
schemas (the text a bag of ours embeds), the URL it logs and its command-line shorthands."""

from __future__ import annotations

import socket

import pytest
from mcap.reader import make_reader

from pam_bag.bags import BagWriter
from pam_bringup.foxglove_channels import (
    DRIVER_APPLIED_COMMAND,
    TOPICS,
    ServedTopic,
    check_host,
    expand_shorthands,
    ros2msg_schemas,
    select_topics,
    url,
)
from pam_common import topics
from pam_common.node_params import ConfigError


def test_every_topic_of_the_stack_is_served_but_the_clock():
    names = {getattr(topics, n) for n in dir(topics) if n.isupper()} - {
        topics.DEFAULT_NAMESPACE, topics.CLOCK, topics.APPLIED_COMMAND}
    assert {name for name, _ in TOPICS} == names | {DRIVER_APPLIED_COMMAND}
    assert DRIVER_APPLIED_COMMAND == 'driver_node/applied_command'


def test_the_schemas_are_the_definitions_a_bag_embeds(tmp_path):
    """The ros2msg text of each type equals the schema record BagWriter writes for it."""
    writer = BagWriter(tmp_path / 'bag', compression='none')
    for k, (_, msgtype) in enumerate(TOPICS):
        writer.add_topic(f'/t{k}', msgtype)
    writer.close()
    with open(writer.mcap_path, 'rb') as f:
        summary = make_reader(f).get_summary()
    in_bag = {s.name: s.data for s in summary.schemas.values()}
    assert {s.encoding for s in summary.schemas.values()} == {'ros2msg'}
    schemas = ros2msg_schemas([msgtype for _, msgtype in TOPICS])
    assert schemas == in_bag
    assert b'\nMSG: std_msgs/Header\n' in schemas['pam_interfaces/msg/Pressures']


def test_topics_are_selected_by_relative_or_absolute_name():
    assert len(select_topics('', '/pam')) == len(TOPICS)
    assert select_topics(' /joint2/estimate, pressures,/diagnostics', '/joint2') == [
        ServedTopic('/joint2/pressures', 'pam_interfaces/msg/Pressures'),
        ServedTopic('/joint2/estimate', 'pam_interfaces/msg/JointEstimate'),
        ServedTopic('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray')]
    with pytest.raises(ConfigError, match=r"unknown topic '/pam/pressure'; .*/pam/pressures"):
        select_topics('pressure', '/pam')
    with pytest.raises(ConfigError, match="unknown topic '/joint2/pressures'"):
        select_topics('/joint2/pressures', '/pam')


def test_hosts_and_urls():
    assert check_host(' 127.0.0.1 ') == '127.0.0.1'
    with pytest.raises(ConfigError, match="parameter 'host': empty"):
        check_host(' ')
    with pytest.raises(ConfigError, match="parameter 'host': cannot resolve"):
        check_host('no-such-host.invalid')
    assert url('127.0.0.1', 8765) == 'ws://127.0.0.1:8765'
    assert url('0.0.0.0', 8766) == f'ws://{socket.gethostname()}:8766'
    assert url('::1', 8765) == 'ws://[::1]:8765'


def test_shorthands_become_ros_arguments():
    assert expand_shorthands(['pam-foxglove']) == ['pam-foxglove']
    assert expand_shorthands(['p', '--host', '0.0.0.0', '--port=8766', '--namespace', 'joint2',
                              '--topics', "a,b'c"]) == [
        'p', '--ros-args', '-p', "host:='0.0.0.0'", '-p', 'port:=8766', '-r', '__ns:=/joint2',
        '-p', "topics:='a,b''c'"]
    # after --ros-args nothing is a shorthand; what is not one stays for the argument check
    assert expand_shorthands(['p', '--port', '1', '-x', '--ros-args', '-p', 'port:=2']) == [
        'p', '-x', '--ros-args', '-p', 'port:=2', '--ros-args', '-p', 'port:=1']
    with pytest.raises(ConfigError, match='option --port needs a value'):
        expand_shorthands(['p', '--port', '--ros-args', '-p', 'a:=1'])
