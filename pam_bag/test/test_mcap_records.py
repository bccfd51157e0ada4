"""pam_bag reads MCAP files without the mcap package (mcap_records, mcap_check: so that running the
stack needs no key outside the public rosdistro); here every record it reads is held against the
mcap package's reading of the same file (the MCAP reference library, a test dependency): the
summary (schemas, channels, chunk and metadata indexes), the metadata records, and every schema,
channel and message record inside the chunks, for each shipped bag and a bag without summary."""

import io
from pathlib import Path

import pytest

from pam_bag import bags
from pam_bag.mcap_check import MCAP_MAGIC, chunk_records, records
from pam_bag.mcap_records import (
    Channel,
    ChunkIndex,
    Message,
    Metadata,
    MetadataIndex,
    Schema,
    file_summary,
    metadata_records,
    parse_record,
    read_summary,
)

BAG_ROOT = Path(__file__).resolve().parents[2] / 'bags'
FILES = sorted(BAG_ROOT.glob('*/*.mcap'))


@pytest.fixture(params=FILES[:3], ids=lambda p: p.name)
def mcap_file(request):
    return request.param


def test_there_are_reference_files():
    assert len(FILES) >= 4


def test_the_summary_is_the_reference_librarys(mcap_file):
    from mcap.reader import make_reader
    with mcap_file.open('rb') as f:
        theirs = make_reader(f).get_summary()
    ours = file_summary(mcap_file)
    assert ours.schemas == {i: Schema(s.id, s.name, s.encoding, s.data)
                            for i, s in theirs.schemas.items()}
    assert ours.channels == {i: Channel(c.id, c.schema_id, c.topic, c.message_encoding,
                                        c.metadata) for i, c in theirs.channels.items()}
    assert ours.chunk_indexes == [
        ChunkIndex(c.message_start_time, c.message_end_time, c.chunk_start_offset,
                   c.chunk_length, c.compression, c.compressed_size, c.uncompressed_size)
        for c in theirs.chunk_indexes]
    assert ours.metadata_indexes == [MetadataIndex(m.offset, m.length, m.name)
                                     for m in theirs.metadata_indexes]
    assert ours.channels and ours.chunk_indexes and ours.metadata_indexes


def test_metadata_records_are_the_reference_librarys(mcap_file):
    from mcap.reader import make_reader
    with mcap_file.open('rb') as f:
        theirs = [Metadata(m.name, m.metadata) for m in make_reader(f).iter_metadata()]
        ours = list(metadata_records(f, mcap_file.stat().st_size))
    assert ours == theirs and ours[0].name == 'rosbag2'


def test_every_record_in_the_chunks_is_the_reference_librarys(mcap_file):
    from mcap.records import Channel as TheirChannel, Message as TheirMessage, Schema as TheirSchema
    from mcap.stream_reader import StreamReader
    with mcap_file.open('rb') as f:
        theirs = [r for r in StreamReader(f).records
                  if isinstance(r, (TheirSchema, TheirChannel, TheirMessage))]
    ours = []
    with mcap_file.open('rb') as f:
        f.seek(len(MCAP_MAGIC))
        for _, opcode, body in records(f, mcap_file.stat().st_size):
            inner = chunk_records(body)[1] if opcode == 0x06 else [(0, opcode, body)]
            ours += [r for _, op, b in inner if isinstance(r := parse_record(op, b),
                                                          (Schema, Channel, Message))]
    assert len(ours) == len(theirs) > 1000
    for mine, their in zip(ours, theirs, strict=True):
        assert tuple(mine) == tuple(getattr(their, f) for f in type(mine)._fields)


def test_a_file_without_summary_gives_its_metadata_by_reading_through(tmp_path):
    """The footer's summary_start 0 ('no summary'): read_summary is None, and the metadata
    records are found by walking the file, as the reference library's reader does."""
    from mcap.reader import make_reader
    source = FILES[0]
    data = bytearray(source.read_bytes())
    footer = len(data) - len(MCAP_MAGIC) - 29
    data[footer + 9:footer + 17] = bytes(8)      # summary_start := 0
    data[footer + 25:footer + 29] = bytes(4)     # its CRC: not computed
    path = tmp_path / source.name
    path.write_bytes(bytes(data))
    with path.open('rb') as f:
        assert read_summary(f, len(data)) is None
        ours = list(metadata_records(f, len(data)))
        f.seek(0)
        theirs = [Metadata(m.name, m.metadata) for m in make_reader(f).iter_metadata()]
    assert ours == theirs and ours
    with pytest.raises(ValueError, match='no summary section'):
        file_summary(path)


def test_a_damaged_record_is_a_value_error():
    assert parse_record(0x0B, b'statistics: not read') is None
    with pytest.raises(ValueError, match='record cut short'):
        parse_record(0x04, b'\x01\x00\x02\x00\xff\x00\x00\x00topic')
    with pytest.raises(ValueError, match=r'no footer|expected a footer'):
        read_summary(io.BytesIO(MCAP_MAGIC * 8), len(MCAP_MAGIC) * 8)


def test_bag_info_reads_the_compression_from_the_chunk_indexes():
    info = bags.bag_info(FILES[0].parent)
    assert info['compression'] == 'zstd'
