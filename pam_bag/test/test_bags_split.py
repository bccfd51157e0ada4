"""pam_bag.bags is the public face of the bag library's modules (rosbag2's layers: _storage
metadata and files, _types, _qos, _mcap_storage, _writer, _reader, _info, _reindexer): every
name it offered when it was one module is still importable from it, and a bag written by the
library as one module (test/resources/written_before, a split bag of two files) reads the same
as one written now with the same messages, which says `recorder: pam_bag bag_record`."""

import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np

from pam_bag import bags

RESOURCES = Path(__file__).parent / 'resources'
BEFORE = RESOURCES / 'written_before'

#: Every public name of pam_bag.bags when it was one module (1,236 lines).
PUBLIC = [
    'BagContents', 'BagError', 'BagSelection', 'BagWriteError', 'BagWriter', 'DAMAGED',
    'DEFAULT_CHUNK_INTERVAL', 'EXIT_BAD_INPUT', 'METADATA', 'MIN_SPLIT_DURATION',
    'MIN_SPLIT_SIZE', 'RECOVER_TMP', 'ROS_DISTRO', 'Recovery', 'bag_dir', 'bag_files',
    'bag_info', 'channel_hash', 'check_bag', 'check_definitions', 'check_mcap', 'check_split',
    'definition_hash', 'embedded_metadata', 'first_problems', 'format_info', 'interface_dirs',
    'known_type', 'load_bag', 'make_qos', 'make_typestore', 'open_bag', 'qos_from_ints',
    'read_metadata', 'recorded_types', 'recover_bag', 'verify_bag',
]


def write_fixture(path: Path) -> Path:
    """Two topics of standard types (their definitions do not change with the project's), 40
    samples 1 ms apart, a second file after the 20th: the fixture's recipe."""
    store = bags.make_typestore()
    types = store.types
    writer = bags.BagWriter(path, typestore=store, split=True, chunk_interval=3600.0)
    writer.add_topic('/pam/label', 'std_msgs/msg/String', [bags.make_qos()])
    writer.add_topic('/pam/joint_states', 'sensor_msgs/msg/JointState',
                     [bags.make_qos(reliable=False, depth=10)])
    for k in range(40):
        t_ns = 1_700_000_000_000_000_000 + k * 1_000_000
        if k == 20:
            writer.next_file()
        header = types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=1_700_000_000, nanosec=k * 1_000_000),
            frame_id='pam_joint')
        state = types['sensor_msgs/msg/JointState'](
            header=header, name=['seesaw_joint'], position=np.array([0.001 * k]),
            velocity=np.array([0.1]), effort=np.array([-0.5 * k]))
        writer.write('/pam/joint_states', t_ns,
                     bytes(store.serialize_cdr(state, 'sensor_msgs/msg/JointState')))
        if k % 10 == 0:
            label = types['std_msgs/msg/String'](data=f'sample {k}')
            writer.write('/pam/label', t_ns, bytes(store.serialize_cdr(label,
                                                                       'std_msgs/msg/String')))
    writer.close()
    return path


def test_every_public_name_is_still_importable_from_bags():
    missing = [name for name in PUBLIC if not hasattr(bags, name)]
    assert not missing
    assert set(PUBLIC) <= set(bags.__all__)
    for name in bags.__all__:             # and each comes from the layer that defines it
        module = getattr(getattr(bags, name), '__module__', None)
        if module is not None and module.startswith('pam_bag.'):
            assert importlib.import_module(module) is not bags, name


def contents(path: Path) -> dict:
    loaded = bags.load_bag(path)
    info = bags.bag_info(path)
    for key in ('path', 'files', 'size'):
        info.pop(key)
    metadata = bags.read_metadata(path)
    recorder = metadata.pop('custom_data').pop('recorder')
    return dict(topics=loaded.topics, qos=loaded.qos, times=loaded.times,
                topic_index=loaded.topic_index, topic_names=loaded.topic_names,
                data=loaded.data, info=info, metadata=metadata, recorder=recorder,
                types=[(p.name, *rest) for p, *rest in bags.recorded_types(bags.bag_files(path))],
                problems=[c.problems for c in bags.verify_bag(path)])


def test_bags_written_before_and_now_read_the_same(tmp_path):
    before, now = contents(BEFORE), contents(write_fixture(tmp_path / 'written_before'))
    assert before.pop('recorder') == 'pam_driver bag_record'    # the package it moved from
    assert now.pop('recorder') == 'pam_bag bag_record'
    assert now == before
    assert now['problems'] == [[], []] and len(now['times']) == 44


def test_importing_bags_imports_no_rosbags():
    """rosbags (a tenth of a second) is imported once a bag is written or read, not by a node's
    --help: the MCAP storage writer, which subclasses rosbags' own, is imported by BagWriter."""
    code = ('import sys, pam_bag.bags; '
            "print(sorted(m for m in sys.modules if m.startswith('rosbags')))")
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          check=False, timeout=60)
    assert (done.returncode, done.stdout.strip()) == (0, '[]'), done.stderr


def test_the_qos_profiles_are_rosbags_own():
    from rosbags.interfaces import QosDurability, QosHistory, QosReliability, QosTime
    made = bags.make_qos(reliable=False, depth=7, transient_local=True, keep_all=True)
    assert (made.history, made.depth, made.reliability, made.durability) == (
        QosHistory.KEEP_ALL, 7, QosReliability.BEST_EFFORT, QosDurability.TRANSIENT_LOCAL)
    assert made.deadline == QosTime(sec=2147483647, nsec=4294967295)
    ints = bags.qos_from_ints(1, 10, 2, 1, 1, lease=(1, 5))
    assert (ints.history, ints.depth, ints.reliability, ints.durability) == (
        QosHistory.KEEP_LAST, 10, QosReliability.BEST_EFFORT, QosDurability.TRANSIENT_LOCAL)
    assert ints.liveliness_lease_duration == QosTime(1, 5)
    assert bags.qos_from_ints(99, 1, 99, 99, 99).history == QosHistory.UNKNOWN
