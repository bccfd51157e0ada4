"""The reference bags in bags/ (every bag directory there): readable by rosbags and by mcap +
mcap_ros2 (embedded schemas alone), and structurally what Jazzy's rosbag2 writes (summary, chunk
indexes, one schema per type, channel metadata, counts, ros_distro)."""

from collections import Counter
from pathlib import Path

import pytest

from pam_bag import bags

BAG_ROOT = Path(__file__).resolve().parents[2] / 'bags'
REFERENCE = sorted(p for p in BAG_ROOT.glob('*') if (p / bags.METADATA).is_file())
EXPECTED = {'validation_mild_free', 'validation_mild_locked', 'closed_mild_angle',
            'closed_mild_torque'}
OPEN_LOOP = {'/pam/pressures', '/pam/valve_command', '/pam/joint_measured'}
TOPICS = {'validation': OPEN_LOOP,   # by the bag name's first word (bags/README.md)
          'closed': OPEN_LOOP | {'/pam/estimate', '/pam/reference'}}


def test_the_reference_bags_are_there_and_small():
    """Every file under 4.5 MB (the validation bags are split); the validation bags hold the
    whole 130 s profile (MODEL.md) after the rig's ~2 s at rest."""
    assert EXPECTED <= {p.name for p in REFERENCE}
    total = sum(f.stat().st_size for f in BAG_ROOT.rglob('*') if f.is_file())
    assert total < 40e6
    for f in BAG_ROOT.rglob('*.mcap'):
        assert f.stat().st_size < 4.5e6, f
    for name in ('validation_mild_free', 'validation_mild_locked'):
        assert bags.bag_info(BAG_ROOT / name)['duration'] > 130.0


@pytest.fixture(params=REFERENCE, ids=lambda p: p.name)
def bag(request):
    return request.param


def _rosbags_counts(path):
    from rosbags.rosbag2 import Reader
    store = bags.make_typestore()
    counts = Counter()
    with Reader(path) as reader:
        for conn, _, raw in reader.messages():
            store.deserialize_cdr(raw, conn.msgtype)
            counts[conn.topic] += 1
        assert reader.message_count == sum(counts.values())
    return counts


def test_rosbags_reads_and_decodes_every_message(bag):
    counts = _rosbags_counts(bag)
    assert set(counts) == TOPICS[bag.name.split('_')[0]]
    assert counts['/pam/pressures'] > 10_000     # > 10 s at 1 kHz
    assert min(counts.values()) > 1000


def test_mcap_ros2_decodes_from_the_embedded_schemas_and_the_structure_is_jazzys(bag):
    """Each file of the bag (a split bag has several, in metadata.yaml's order) on its own."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    files = [Path(f) for f in bags.bag_info(bag)['files']]
    assert sorted(files) == sorted(bag.glob('*.mcap'))
    stats, decoded, last_end = Counter(), Counter(), 0
    for path in files:
        with path.open('rb') as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            summary = reader.get_summary()
            header = reader.get_header()
            assert header.profile == 'ros2'
            assert summary is not None and summary.statistics is not None
            assert summary.chunk_indexes and all(c.compression == 'zstd'
                                                 for c in summary.chunk_indexes)
            assert all(c.message_index_offsets for c in summary.chunk_indexes)
            assert summary.statistics.message_start_time > last_end   # files in time order
            last_end = summary.statistics.message_end_time
            names = [s.name for s in summary.schemas.values()]
            assert len(names) == len(set(names))     # one schema per type
            assert all(s.encoding == 'ros2msg' and s.data for s in summary.schemas.values())
            for channel in summary.channels.values():
                assert channel.message_encoding == 'cdr'
                assert channel.metadata['topic_type_hash'].startswith('RIHS01_')
                assert 'reliability' in channel.metadata['offered_qos_profiles']
                assert summary.schemas[channel.schema_id].name in (
                    'pam_interfaces/msg/Pressures', 'pam_interfaces/msg/ValveCommand',
                    'pam_interfaces/msg/JointMeasurement', 'pam_interfaces/msg/JointEstimate',
                    'pam_interfaces/msg/Reference')
            for _, channel, _, msg in reader.iter_decoded_messages():
                assert msg.header.stamp.sec >= 0
                decoded[channel.topic] += 1
            stats.update({summary.channels[cid].topic: n
                          for cid, n in summary.statistics.channel_message_counts.items()})
            embedded = bags.embedded_metadata(path)
            assert embedded['ros_distro'] == 'jazzy'
            assert embedded['relative_file_paths'][-1] == path.name
    assert stats == decoded == _rosbags_counts(bag)
    info = bags.bag_info(bag)
    assert {t['name']: t['count'] for t in info['topics']} == stats
    assert info['version'] == 9 and info['storage'] == 'mcap' and info['ros_distro'] == 'jazzy'
    assert embedded['message_count'] == sum(stats.values())   # the last file's: the whole bag


def test_every_chunk_and_file_carries_its_crc(bag):
    """Recorded by bag_record with CRCs (chunks, data section, summary): verify_bag
    reads every chunk and finds every CRC present and matching."""
    checks = bags.verify_bag(bag)
    assert [p for check in checks for p in check.problems] == []
    for check in checks:
        assert check.chunks and check.chunks_with_crc == check.chunks and check.data_crc, check
