"""pam_driver.bags without ROS: type hashes, round trip, readers, bad input, write errors."""

import json

import pytest

from pam_driver import bags

PRESSURES = 'pam_interfaces/msg/Pressures'


@pytest.fixture(scope='module')
def store():
    return bags.make_typestore()


def pressures(store, i):
    t = store.types
    msg = t[PRESSURES](header=t['std_msgs/msg/Header'](
        stamp=t['builtin_interfaces/msg/Time'](sec=i // 1000, nanosec=(i % 1000) * 1_000_000),
        frame_id='pam'), p1=1e5 + i, p2=2e5)
    return bytes(store.serialize_cdr(msg, PRESSURES))


def write_bag(store, path, n=3000, period_ns=10**6, **kw):
    """n Pressures messages (p1 = 1e5 + index) received every period_ns from 1e18 ns on; also
    used by test_bags_nodes."""
    w = bags.BagWriter(path, typestore=store, **kw)
    w.add_topic('/pam/pressures', PRESSURES, [bags.make_qos()])
    for i in range(n):
        w.write('/pam/pressures', 10**18 + i * period_ns, pressures(store, i))
    w.close()
    return w


def test_type_hashes_match_rosidl(store):
    for d in bags.interface_dirs()[:1]:
        for f in d.glob('*.json'):
            expected = json.loads(f.read_text())['type_hashes'][0]
            assert store.hash_rihs01(expected['type_name']) == expected['hash_string']


def test_round_trip_and_mcap_readers(store, tmp_path):
    write_bag(store, tmp_path / 'b')
    contents = bags.load_bag(tmp_path / 'b')
    assert len(contents.data) == 3000
    assert contents.times == sorted(contents.times)
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(tmp_path / 'b' / 'b.mcap', 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert {c.compression for c in summary.chunk_indexes} == {'zstd'}
        [channel] = summary.channels.values()
        assert channel.metadata['topic_type_hash'].startswith('RIHS01_')
        assert 'reliability: reliable' in channel.metadata['offered_qos_profiles']
        [schema] = summary.schemas.values()
        assert schema.encoding == 'ros2msg' and b'MSG: std_msgs/Header' in schema.data
        values = [m.p1 for _, _, _, m in reader.iter_decoded_messages()]
    assert values == [1e5 + i for i in range(3000)]
    info = bags.bag_info(tmp_path / 'b')
    assert info['version'] == 9 and info['topics'][0]['count'] == 3000
    assert abs(info['topics'][0]['rate'] - 1000.0) < 1.0


def test_metadata_names_jazzy_like_rosbag2(store, tmp_path):
    """ros_distro is what rosbag2 Jazzy writes, in metadata.yaml and in the MCAP 'rosbag2'
    metadata record (its serialized_metadata), not rosbags' 'rosbags'."""
    write_bag(store, tmp_path / 'b', n=10)
    assert bags.bag_info(tmp_path / 'b')['ros_distro'] == 'jazzy'
    embedded = bags.embedded_metadata(tmp_path / 'b' / 'b.mcap')
    assert embedded['ros_distro'] == 'jazzy' and embedded['message_count'] == 10


def test_existing_output_is_refused(store, tmp_path):
    (tmp_path / 'b').mkdir()
    (tmp_path / 'b' / 'keep').write_text('x')
    with pytest.raises(bags.BagError, match='exists'):
        bags.BagWriter(tmp_path / 'b', typestore=store)
    assert (tmp_path / 'b' / 'keep').read_text() == 'x'


def test_bad_bags_name_the_file(store, tmp_path):
    write_bag(store, tmp_path / 'b')
    mcap = tmp_path / 'b' / 'b.mcap'
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    with pytest.raises(bags.BagError, match=r'b\.mcap: truncated or corrupt'):
        bags.load_bag(tmp_path / 'b')
    (tmp_path / 'b' / 'metadata.yaml').unlink()
    with pytest.raises(bags.BagError, match=r'metadata\.yaml: missing'):
        bags.load_bag(tmp_path / 'b')


def test_write_error_leaves_a_readable_bag(store, tmp_path):
    """A write failing mid-recording (here: a file size limit) stops writing with BagWriteError;
    the bag closes with every complete chunk before the error."""
    import resource
    w = bags.BagWriter(tmp_path / 'b', typestore=store, compression='none', chunk_interval=0.0)
    w.add_topic('/pam/pressures', PRESSURES, [bags.make_qos()])
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    written = 0
    try:
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, hard))
        with pytest.raises(bags.BagWriteError, match='write failed'):
            for i in range(100_000):
                w.write('/pam/pressures', 10**18 + i * 10**6, pressures(store, i))
                written += 1
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    w.close()
    assert written < 100_000
    contents = bags.load_bag(tmp_path / 'b')
    assert 0 < len(contents.data) <= written
    info = bags.bag_info(tmp_path / 'b')
    assert info['message_count'] == len(contents.data)
