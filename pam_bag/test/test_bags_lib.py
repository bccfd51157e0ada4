"""pam_bag.bags without ROS: type hashes, round trip, readers, bad input, write errors,
recovery of a crashed recording (truncated at several offsets, damaged, garbage)."""

import json
import time
from pathlib import Path

import pytest

from pam_bag import bags
from pam_bag.testing import damage_chunk

PRESSURES = 'pam_interfaces/msg/Pressures'


@pytest.fixture(scope='module')
def store():
    return bags.make_typestore()


def pressures(store, i):
    t = store.types
    msg = t[PRESSURES](header=t['std_msgs/msg/Header'](
        stamp=t['builtin_interfaces/msg/Time'](sec=i // 1000, nanosec=(i % 1000) * 1_000_000),
        frame_id='pam'), p1=1e5 + i, p2=2e5, sample=i + 1)
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


def assert_crcs(mcap):
    """Every chunk's uncompressed_crc, the DataEnd's data_section_crc and the Footer's
    summary_crc of the MCAP file are set and are zlib.crc32 of what the MCAP specification says
    (found by parsing the file with the mcap package, not pam_driver); the mcap package's own
    CRC validation passes too."""
    import zlib

    import zstandard
    from mcap.records import Chunk, DataEnd, Footer
    from mcap.stream_reader import StreamReader
    data = Path(mcap).read_bytes()
    found = [r for r in StreamReader(str(mcap), emit_chunks=True).records
             if isinstance(r, (Chunk, DataEnd, Footer))]
    chunks = [r for r in found if isinstance(r, Chunk)]
    [data_end] = [r for r in found if isinstance(r, DataEnd)]
    [footer] = [r for r in found if isinstance(r, Footer)]
    assert chunks
    for chunk in chunks:
        records = (zstandard.decompress(chunk.data, max_output_size=chunk.uncompressed_size)
                   if chunk.compression == 'zstd' else chunk.data)
        assert chunk.uncompressed_crc == zlib.crc32(records) != 0
    data_end_at = footer.summary_start - 13      # DataEnd (opcode, length, CRC) ends the data
    assert data[data_end_at] == 0x0F
    assert data_end.data_section_crc == zlib.crc32(data[:data_end_at]) != 0
    assert footer.summary_crc == zlib.crc32(data[footer.summary_start:len(data) - 12]) != 0
    assert sum(1 for _ in StreamReader(str(mcap), validate_crcs=True).records) > len(chunks)


def test_chunks_data_section_and_summary_carry_crcs(store, tmp_path):
    """As the MCAP specification and rosbag2's writer: chunk CRCs, data section and summary
    CRCs, in a bag of one file (2 chunks, zstd) and in each file of a split bag (no
    compression)."""
    write_bag(store, tmp_path / 'b', n=25_000)
    assert len(_mcap_summary(tmp_path / 'b' / 'b.mcap').chunk_indexes) >= 2
    assert_crcs(tmp_path / 'b' / 'b.mcap')
    write_bag(store, tmp_path / 's', n=3000, compression='none', max_bag_duration=1.0,
              chunk_interval=0.0)
    files = sorted((tmp_path / 's').glob('*.mcap'))
    assert len(files) == 3
    for f in files:
        assert_crcs(f)


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


def damaged_chunk_bag(full, path, k):
    """A copy of the complete one-message-per-chunk bag `full` (the `chunked` fixture) whose
    chunk `k` holds garbage instead of its compressed records; summary and footer intact."""
    import shutil

    from mcap.reader import make_reader
    shutil.copytree(full, path)
    mcap = path / f'{full.name}.mcap'
    with open(mcap, 'rb') as f:
        chunk = make_reader(f).get_summary().chunk_indexes[k]
    data = bytearray(mcap.read_bytes())
    end = chunk.chunk_start_offset + chunk.chunk_length
    data[end - chunk.compressed_size:end] = b'\xaa' * chunk.compressed_size
    mcap.write_bytes(data)
    return path


def test_open_bag_streams_what_load_bag_loads(store, tmp_path):
    write_bag(store, tmp_path / 'b', n=500)
    selection = bags.open_bag(tmp_path / 'b', start_offset=0.1)
    assert selection.message_count == 500 and selection.topic_names == ['/pam/pressures']
    assert selection.first_ns == 10**18 + 100_000_000
    loaded = bags.load_bag(tmp_path / 'b', start_offset=0.1)
    streamed = list(selection.messages())
    assert streamed == list(zip(loaded.times, loaded.topic_index, loaded.data, strict=True))
    assert [t for t, _, _ in streamed] == [10**18 + i * 10**6 for i in range(100, 500)]
    assert list(selection.messages()) == streamed      # again (a loop's next pass)


def test_a_damaged_chunk_stops_reading_after_the_messages_before_it(store, chunked, tmp_path):
    """The summary is intact (check_bag passes); the damage shows when reading reaches it."""
    full, _ = chunked
    path = damaged_chunk_bag(full, tmp_path / 'full', 20)
    selection = bags.open_bag(path)
    got = []
    with pytest.raises(bags.BagError, match=r'full\.mcap: corrupt data after 20 messages'):
        for item in selection.messages():
            got.append(item)
    assert [data for _, _, data in got] == [pressures(store, i) for i in range(20)]


@pytest.fixture(scope='module')
def two_chunks(store, tmp_path_factory):
    """A complete bag of 25000 messages in two zstd chunks (1 MB uncompressed each at most),
    and the number of messages in its chunk 0."""
    path = tmp_path_factory.mktemp('two_chunks') / 'b'
    write_bag(store, path, n=25_000)
    [first, _] = _mcap_summary(path / 'b.mcap').chunk_indexes
    return path, (first.message_end_time - 10**18) // 10**6 + 1     # write_bag: 1 ms apart


def test_silent_damage_in_a_chunk_is_found_by_its_crc(store, two_chunks, tmp_path):
    """8 bytes flipped in chunk 1 where zstd still decompresses (the issue's corrupted bag):
    every read path stops at chunk 1 with an error naming it (after chunk 0's messages),
    verify_bag names it, recover_bag rebuilds the bag without it."""
    import shutil
    full, in_first = two_chunks
    bag = tmp_path / 'b'
    shutil.copytree(full, bag)
    damage_chunk(bag / 'b.mcap', 1)
    with pytest.raises(bags.BagError, match=r'b\.mcap: corrupt data after \d+ messages: b\.mcap: '
                       r'chunk 1 at byte \d+ \(messages .* into the bag\) is damaged: CRC '
                       'mismatch'):
        bags.load_bag(bag)
    got = []
    with pytest.raises(bags.BagError, match='chunk 1 at byte'):
        for item in bags.open_bag(bag).messages():
            got.append(item[2])
    assert got == [pressures(store, i) for i in range(in_first)]
    problems = [p for check in bags.verify_bag(bag) for p in check.problems]
    assert len(problems) == 2, problems
    assert problems[0].startswith('b.mcap: chunk 1 at byte') and 'CRC mismatch' in problems[0]
    assert 'data section CRC mismatch' in problems[1] and 'damaged chunk(s) above' in problems[1]
    assert not any(check.problems for check in bags.verify_bag(full))

    result = bags.recover_bag(bag)
    assert result.counts == {'/pam/pressures': in_first} and not result.missing
    assert 'CRC mismatch' in result.problems[0]
    assert bags.load_bag(bag).data == [pressures(store, i) for i in range(in_first)]


def test_a_bag_without_crcs_still_reads(store, two_chunks, tmp_path):
    """Bags written before pam_driver wrote CRCs have 0 there ("not computed"): accepted."""
    import shutil
    import struct
    full, _ = two_chunks
    bag = tmp_path / 'b'
    shutil.copytree(full, bag)
    mcap = bag / 'b.mcap'
    data = bytearray(mcap.read_bytes())
    for chunk in _mcap_summary(mcap).chunk_indexes:
        struct.pack_into('<I', data, chunk.chunk_start_offset + 9 + 24, 0)
    summary_start = struct.unpack_from('<Q', data, len(data) - 8 - 20)[0]
    struct.pack_into('<I', data, summary_start - 4, 0)      # DataEnd's data_section_crc
    struct.pack_into('<I', data, len(data) - 8 - 4, 0)      # Footer's summary_crc
    mcap.write_bytes(data)
    assert len(bags.load_bag(bag).data) == 25_000
    [check] = bags.verify_bag(bag)
    assert (check.chunks, check.chunks_with_crc, check.data_crc, check.problems) == (
        2, 0, False, [])


def test_topics_added_while_another_thread_writes(store, tmp_path):
    """bag_record adds a topic from its executor thread (discovery) while its writer thread
    writes and closes chunks: every chunk must stay consistent (a clean-clone CI run once read
    'Chunk size mismatch' back from a bag whose /diagnostics was discovered mid-recording)."""
    import threading
    w = bags.BagWriter(tmp_path / 'b', typestore=store, chunk_interval=0.0)
    w.add_topic('/pam/pressures', PRESSURES, [bags.make_qos()])
    data = pressures(store, 0)
    n, types = 6000, sorted(t for t in store.types if t.startswith(('std_msgs/msg/',
                                                                      'geometry_msgs/msg/')))
    added = []

    def add_topics():
        for i, msgtype in enumerate(types[:60]):
            w.add_topic(f'/extra/t{i}', msgtype, [bags.make_qos()])
            added.append(msgtype)
            time.sleep(0.0005)
    adder = threading.Thread(target=add_topics)
    adder.start()
    for i in range(n):
        w.write('/pam/pressures', 10**18 + i * 10**6, data)
    adder.join()
    w.close()
    assert len(added) == 60
    assert len(bags.load_bag(tmp_path / 'b').data) == n      # every chunk decompresses
    from mcap.reader import make_reader
    with open(tmp_path / 'b' / 'b.mcap', 'rb') as f:
        reader = make_reader(f)
        assert sum(1 for _ in reader.iter_messages()) == n
        assert len(reader.get_summary().channels) == 61


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
    assert_crcs(tmp_path / 'b' / 'b.mcap')    # the CRCs of the file as truncated
    contents = bags.load_bag(tmp_path / 'b')
    assert 0 < len(contents.data) <= written
    info = bags.bag_info(tmp_path / 'b')
    assert info['message_count'] == len(contents.data)


def _mcap_summary(path):
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        return make_reader(f).get_summary()


def test_split_by_size_gives_complete_files_under_the_limit(store, tmp_path):
    """max_bag_size: files <dir>_0.mcap, _1, ... each under the limit (plus its metadata record
    and summary, which grow with the files listed), each a complete MCAP file with the schema
    and channel; together every message, once, in order, and metadata.yaml lists them with
    their own times and counts (as rosbag2 splits)."""
    limit = 150_000
    write_bag(store, tmp_path / 'b', n=20_000, compression='none', max_bag_size=limit)
    info = bags.bag_info(tmp_path / 'b')
    files = [tmp_path / 'b' / f'b_{i}.mcap' for i in range(len(info['files']))]
    assert info['files'] == [str(f) for f in files] and len(files) >= 4
    assert not (tmp_path / 'b' / 'b.mcap').exists()
    total, last_end = 0, 0
    from ruamel.yaml import YAML
    meta = YAML(typ='safe').load((tmp_path / 'b' / 'metadata.yaml').read_text())
    entries = meta['rosbag2_bagfile_information']['files']
    for f, entry in zip(files, entries, strict=True):
        assert f.stat().st_size < limit + 5_000   # + metadata record and summary
        summary = _mcap_summary(f)
        assert len(summary.schemas) == 1 and len(summary.channels) == 1
        stats = summary.statistics
        assert entry['path'] == f.name and entry['message_count'] == stats.message_count
        assert entry['starting_time']['nanoseconds_since_epoch'] == stats.message_start_time
        assert stats.message_start_time > last_end
        last_end = stats.message_end_time
        total += stats.message_count
        assert bags.embedded_metadata(f)['relative_file_paths'][-1] == f.name
    assert total == 20_000 == info['message_count']
    contents = bags.load_bag(tmp_path / 'b')
    values = [store.deserialize_cdr(d, PRESSURES).p1 for d in contents.data]
    assert values == [1e5 + i for i in range(20_000)]
    from rosbags.rosbag2 import Reader
    with Reader(tmp_path / 'b') as reader:
        assert reader.message_count == 20_000
        assert sum(1 for _ in reader.messages()) == 20_000


def test_split_by_duration(store, tmp_path):
    """max_bag_duration 2 s over 7 s of messages: 4 files, each starting 2 s after the last."""
    write_bag(store, tmp_path / 'b', n=7000, max_bag_duration=2.0)
    info = bags.bag_info(tmp_path / 'b')
    assert len(info['files']) == 4
    starts = [_mcap_summary(f).statistics.message_start_time for f in info['files']]
    assert starts == [10**18 + k * 2 * 10**9 for k in range(4)]
    assert info['message_count'] == 7000 and abs(info['duration'] - 6.999) < 1e-6


def test_split_bag_stops_cleanly_on_a_write_error(store, tmp_path):
    """A write error in the third file: the first two stay complete, the third keeps its
    complete chunks; the bag reads back with no gap before the error."""
    import resource
    w = bags.BagWriter(tmp_path / 'b', typestore=store, compression='none', chunk_interval=0.0,
                       max_bag_size=100_000)
    w.add_topic('/pam/pressures', PRESSURES, [bags.make_qos()])
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    written = 0
    try:
        with pytest.raises(bags.BagWriteError, match=r'b_2\.mcap: write failed'):
            for i in range(100_000):
                if len(w.files) == 2:    # the third file is open: limit each file to 20 kB
                    resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, hard))
                w.write('/pam/pressures', 10**18 + i * 10**6, pressures(store, i))
                written += 1
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    with pytest.raises(bags.BagWriteError, match='stopped'):
        w.write('/pam/pressures', 10**18 + written * 10**6, pressures(store, written))
    w.close()
    info = bags.bag_info(tmp_path / 'b')
    assert [Path(f).name for f in info['files']] == ['b_0.mcap', 'b_1.mcap', 'b_2.mcap']
    for f in info['files']:
        assert_crcs(f)
    contents = bags.load_bag(tmp_path / 'b')
    values = [store.deserialize_cdr(d, PRESSURES).p1 for d in contents.data]
    in_two = sum(_mcap_summary(f).statistics.message_count for f in info['files'][:2])
    assert in_two < len(values) <= written and values == [1e5 + i for i in range(len(values))]


def test_split_sizes_are_validated(store, tmp_path):
    """0 (no split) or at least the minimum: a 1-byte limit would make a file per message."""
    for kw, name in (({'max_bag_size': -1}, 'max_bag_size'),
                     ({'max_bag_size': 99_999}, 'max_bag_size'),
                     ({'max_bag_duration': 0.5}, 'max_bag_duration'),
                     ({'max_bag_duration': float('nan')}, 'max_bag_duration')):
        with pytest.raises(bags.BagError, match=f'{name} .*: use 0 .no split. or at least'):
            bags.BagWriter(tmp_path / 'b', typestore=store, **kw)
        assert not (tmp_path / 'b').exists()


# ------------------------------------------------------------------------------- recovery
@pytest.fixture(scope='module')
def chunked(store, tmp_path_factory):
    """A complete bag of 60 messages, one chunk each (chunk 0 also holds the schema and the
    channel), and its chunk indexes."""
    from mcap.reader import make_reader
    path = tmp_path_factory.mktemp('chunked') / 'full'
    write_bag(store, path, n=60, chunk_interval=0.0)
    with open(path / 'full.mcap', 'rb') as f:
        return path, make_reader(f).get_summary().chunk_indexes


def crashed(full, path, cut=None, edit=None):
    """A bag directory as a killed recorder leaves it: no metadata.yaml, the .mcap of the
    complete bag `full` cut to its first `cut` bytes, after edit(bytearray) if given."""
    data = bytearray((full / f'{full.name}.mcap').read_bytes()[:cut])
    if edit:
        edit(data)
    path.mkdir()
    (path / f'{path.name}.mcap').write_bytes(data)
    return path


def summary(mcap):
    from mcap.reader import make_reader
    with open(mcap, 'rb') as f:
        return make_reader(f).get_summary()


def check_recovered(store, path, indices, original: bytes, full):
    """The bag at `path` is complete and holds the messages `indices` of write_bag in order,
    on a channel like the original's (QoS, type hash); the damaged .mcap is kept unchanged
    beside it."""
    contents = bags.load_bag(path)
    assert contents.data == [pressures(store, i) for i in indices]
    assert contents.times == [10**18 + i * 10**6 for i in indices]
    info = bags.bag_info(path)
    assert info['message_count'] == len(indices) and info['ros_distro'] == 'jazzy'
    assert info['version'] == 9 and info['compression'] == 'zstd'
    assert bags.embedded_metadata(path / f'{path.name}.mcap')['message_count'] == len(indices)
    assert (path / f'{path.name}.mcap.damaged').read_bytes() == original
    got, reference = summary(path / f'{path.name}.mcap'), summary(full / 'full.mcap')
    assert got.statistics.message_count == len(indices)
    assert all(c.message_index_offsets for c in got.chunk_indexes)
    assert ([(c.topic, c.metadata) for c in got.channels.values()] ==
            [(c.topic, c.metadata) for c in reference.channels.values()])
    assert sorted(p.name for p in path.iterdir()) == [
        f'{path.name}.mcap', f'{path.name}.mcap.damaged', 'metadata.yaml']


# where a crash cuts the file, relative to chunk 30 -> (cut, messages kept, bytes dropped)
CUTS = {
    'in the record head': lambda c: (c.chunk_start_offset + 5, 30, 5),
    'mid chunk': lambda c: (c.chunk_start_offset + 100, 30, 100),
    'mid message index': lambda c: (c.chunk_start_offset + c.chunk_length + 10, 31, 10),
    'at a record boundary': lambda c: (
        c.chunk_start_offset + c.chunk_length + c.message_index_length, 31, 0),
}


@pytest.mark.parametrize('where', sorted(CUTS))
def test_recover_truncated(store, chunked, tmp_path, where):
    """Every complete chunk is recovered; the cut-off record is dropped (and counted)."""
    full, chunks = chunked
    cut, n, dropped = CUTS[where](chunks[30])
    path = crashed(full, tmp_path / 'b', cut)
    with pytest.raises(bags.BagError, match=r'metadata\.yaml: missing'):
        bags.load_bag(path)
    result = bags.recover_bag(path)
    assert result.counts == {'/pam/pressures': n} and result.dropped_bytes == dropped
    assert (result.start_ns, result.end_ns) == (10**18, 10**18 + (n - 1) * 10**6)
    assert len(result.problems) == (dropped > 0)
    check_recovered(store, path, range(n), (full / 'full.mcap').read_bytes()[:cut], full)


def test_recover_a_complete_mcap_without_metadata(store, chunked, tmp_path):
    """Cut inside the summary (or metadata.yaml lost): every message, nothing dropped."""
    full, _ = chunked
    size = (full / 'full.mcap').stat().st_size
    path = crashed(full, tmp_path / 'b', size - 10)
    result = bags.recover_bag(path)
    assert result.counts == {'/pam/pressures': 60} and result.dropped_bytes == 0
    check_recovered(store, path, range(60), (full / 'full.mcap').read_bytes()[:-10], full)


def test_recover_skips_an_unreadable_chunk(store, chunked, tmp_path):
    """A damaged chunk in the middle (here: a wrong uncompressed size) is dropped and named;
    the chunks after it are kept."""
    full, chunks = chunked
    bad, last = chunks[10], chunks[40]
    cut = last.chunk_start_offset + last.chunk_length + last.message_index_length

    def damage(data):
        data[bad.chunk_start_offset + 9 + 16] ^= 0xFF    # its uncompressed_size field
    path = crashed(full, tmp_path / 'b', cut, damage)
    original = (path / 'b.mcap').read_bytes()
    result = bags.recover_bag(path)
    assert result.dropped_bytes == bad.chunk_length
    assert result.problems[0].startswith(
        f'b.mcap offset {bad.chunk_start_offset}: unreadable record')
    check_recovered(store, path, [i for i in range(41) if i != 10], original, full)


def test_recover_a_complete_bag_with_a_damaged_chunk(store, chunked, tmp_path):
    """Summary and metadata.yaml intact, chunk 20 garbage (bag_play stops there): recovery
    keeps the 59 other messages; the original file and metadata.yaml are kept as .damaged."""
    full, chunks = chunked
    path = damaged_chunk_bag(full, tmp_path / 'full', 20)
    original = (path / 'full.mcap').read_bytes()
    result = bags.recover_bag(path)
    assert result.counts == {'/pam/pressures': 59}
    assert result.dropped_bytes == chunks[20].chunk_length
    assert result.problems[0].startswith(
        f'full.mcap offset {chunks[20].chunk_start_offset}: unreadable record')
    contents = bags.load_bag(path)
    kept = [i for i in range(60) if i != 20]
    assert contents.data == [pressures(store, i) for i in kept]
    assert (path / 'full.mcap.damaged').read_bytes() == original
    assert sorted(p.name for p in path.iterdir()) == [
        'full.mcap', 'full.mcap.damaged', 'metadata.yaml', 'metadata.yaml.damaged']


def test_recover_a_split_bag(store, tmp_path):
    """A split recording killed in its third file: the two complete files and the complete
    chunks of the third are rewritten into b_0.mcap .. b_2.mcap (same boundaries), the originals
    kept as .damaged."""
    write_bag(store, tmp_path / 'b', n=2500, max_bag_duration=1.0, chunk_interval=0.0)
    bag = tmp_path / 'b'
    (bag / 'metadata.yaml').unlink()
    third = bag / 'b_2.mcap'
    chunks = summary(third).chunk_indexes
    cut = chunks[200].chunk_start_offset + 7           # inside chunk 200 of the third file
    originals = {f.name: f.read_bytes() for f in bag.glob('*.mcap')}
    third.write_bytes(originals['b_2.mcap'][:cut])
    result = bags.recover_bag(bag)
    assert result.counts == {'/pam/pressures': 2200} and result.dropped_bytes == 7
    assert [p.name for p in result.damaged] == [
        'b_0.mcap.damaged', 'b_1.mcap.damaged', 'b_2.mcap.damaged']
    info = bags.bag_info(bag)
    assert [f.split('/')[-1] for f in info['files']] == ['b_0.mcap', 'b_1.mcap', 'b_2.mcap']
    assert [summary(f).statistics.message_count for f in info['files']] == [1000, 1000, 200]
    contents = bags.load_bag(bag)
    assert contents.data == [pressures(store, i) for i in range(2200)]
    assert (bag / 'b_0.mcap.damaged').read_bytes() == originals['b_0.mcap']
    assert (bag / 'b_2.mcap.damaged').read_bytes() == originals['b_2.mcap'][:cut]


@pytest.fixture(scope='module')
def split4(store, tmp_path_factory):
    """A complete split bag: b_0.mcap .. b_3.mcap with 2000, 2000, 2000 and 1000 messages."""
    path = tmp_path_factory.mktemp('split4') / 'b'
    write_bag(store, path, n=7000, max_bag_duration=2.0)
    return path


def test_recover_names_the_missing_file_of_a_split_bag(store, split4, tmp_path):
    """b_2.mcap deleted: recovery rebuilds the bag from the other files, which keep their
    names (b_3.mcap stays b_3.mcap), and names the missing one with its 2000 messages (from
    metadata.yaml)."""
    import shutil
    bag = tmp_path / 'b'
    shutil.copytree(split4, bag)
    (bag / 'b_2.mcap').unlink()
    result = bags.recover_bag(bag)
    assert result.missing == [('b_2.mcap', 2000)] and result.lost_messages == 2000
    assert result.counts == {'/pam/pressures': 5000}
    assert [Path(f).name for f in bags.bag_info(bag)['files']] == [
        'b_0.mcap', 'b_1.mcap', 'b_3.mcap']
    kept = [*range(4000), *range(6000, 7000)]
    assert bags.load_bag(bag).data == [pressures(store, i) for i in kept]
    assert sorted(p.name for p in bag.iterdir()) == sorted(
        [f'b_{i}.mcap{s}' for i in (0, 1, 3) for s in ('', '.damaged')] +
        ['metadata.yaml', 'metadata.yaml.damaged'])


def test_recover_a_crashed_split_bag_with_a_file_missing(store, split4, tmp_path):
    """No metadata.yaml (a killed recorder), the last file cut, b_1.mcap gone and the directory
    renamed: the missing file and its count come from the 'rosbag2' record of b_2.mcap (the
    bag's metadata as of its closing); the files keep their names."""
    import shutil
    bag = tmp_path / 'renamed'
    shutil.copytree(split4, bag)
    (bag / 'metadata.yaml').unlink()
    (bag / 'b_1.mcap').unlink()
    last = bag / 'b_3.mcap'
    last.write_bytes(last.read_bytes()[:_mcap_summary(last).chunk_indexes[0].chunk_start_offset
                                       + _mcap_summary(last).chunk_indexes[0].chunk_length])
    result = bags.recover_bag(bag)
    assert result.missing == [('b_1.mcap', 2000)]
    assert [Path(f).name for f in bags.bag_info(bag)['files']] == [
        'b_0.mcap', 'b_2.mcap', 'b_3.mcap']
    assert bags.load_bag(bag).data == [pressures(store, i) for i in
                                       (*range(2000), *range(4000, 7000))]


def test_recover_keeps_no_compression(store, tmp_path):
    from mcap.reader import make_reader
    write_bag(store, tmp_path / 'full', n=20, compression='none', chunk_interval=0.0)
    with open(tmp_path / 'full' / 'full.mcap', 'rb') as f:
        cut = make_reader(f).get_summary().chunk_indexes[10].chunk_start_offset + 10
    path = crashed(tmp_path / 'full', tmp_path / 'b', cut)
    assert bags.recover_bag(path).counts == {'/pam/pressures': 10}
    with open(path / 'b.mcap', 'rb') as f:
        assert {c.compression for c in make_reader(f).get_summary().chunk_indexes} == {''}


def test_recover_refuses_what_it_cannot_or_need_not_repair(store, chunked, tmp_path):
    """One clear error, nothing changed: a complete bag, garbage, no complete message, a
    missing directory, a .damaged file in the way."""
    full, chunks = chunked
    write_bag(store, tmp_path / 'ok', n=10)
    with pytest.raises(bags.BagError, match=r'ok: a complete bag .* needs no recovery'):
        bags.recover_bag(tmp_path / 'ok')
    garbage = tmp_path / 'garbage'
    garbage.mkdir()
    (garbage / 'garbage.mcap').write_bytes(bytes(range(256)) * 40)
    empty = crashed(full, tmp_path / 'empty', 0)
    header_only = crashed(full, tmp_path / 'header', chunks[0].chunk_start_offset + 3)
    no_channel = crashed(full, tmp_path / 'nochannel', chunks[5].chunk_start_offset,
                         lambda data: data.__setitem__(chunks[0].chunk_start_offset + 25, 0))
    junk = crashed(full, tmp_path / 'junk', chunks[0].chunk_start_offset,
                   lambda data: data.extend(b'\x00' * 4096))    # zeros after a power loss
    for path, error in ((garbage, r'garbage\.mcap: not an MCAP file \(bad magic\)'),
                        (empty, r'empty\.mcap: not an MCAP file'),
                        (header_only, r'header\.mcap: no complete message to recover'),
                        (no_channel, 'unreadable record .*; nochannel.mcap: 4 messages on '
                                     'channel.s. 1 dropped'),
                        (junk, 'the last 4096 bytes are not a complete record'),
                        (tmp_path / 'nope', 'nope: no such bag directory')):
        before = sorted(tmp_path.rglob('*'))
        with pytest.raises(bags.BagError, match=error):
            bags.recover_bag(path)
        assert sorted(tmp_path.rglob('*')) == before, 'a refused recovery changed files'
    header_only.joinpath('header.mcap.damaged').write_bytes(b'')
    with pytest.raises(bags.BagError, match=r'header\.mcap\.damaged: already exists'):
        bags.recover_bag(header_only)
