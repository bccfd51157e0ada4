"""The MCAP records the bag tools read, parsed as the MCAP specification lays them out (no
rosbags, no rclpy, no mcap package): Schema, Channel, Message, ChunkIndex, Metadata and
MetadataIndex (parse_record); a file's summary section (read_summary) and its metadata records
(metadata_records). Records are walked and chunks unpacked by mcap_check."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import NamedTuple

from .mcap_check import FOOTER, MCAP_MAGIC, RECORD_HEAD, records

SCHEMA, CHANNEL, MESSAGE, CHUNK_INDEX = 0x03, 0x04, 0x05, 0x08        # opcodes
METADATA, METADATA_INDEX = 0x0C, 0x0D
_FOOTER_SIZE = RECORD_HEAD.size + 20        # opcode, length, summary_start, summary_offset, CRC


class Schema(NamedTuple):
    id: int
    name: str
    encoding: str
    data: bytes


class Channel(NamedTuple):
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict


class Message(NamedTuple):
    channel_id: int
    sequence: int
    log_time: int           # ns
    publish_time: int       # ns
    data: bytes


class ChunkIndex(NamedTuple):
    message_start_time: int
    message_end_time: int
    chunk_start_offset: int
    chunk_length: int
    compression: str
    compressed_size: int
    uncompressed_size: int


class Metadata(NamedTuple):
    name: str
    metadata: dict


class MetadataIndex(NamedTuple):
    offset: int
    length: int
    name: str


@dataclass
class Summary:
    """A file's summary section: schemas and channels by id, chunk and metadata indexes."""

    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    chunk_indexes: list = field(default_factory=list)
    metadata_indexes: list = field(default_factory=list)


class _Fields:
    """Reads a record body's fields in order; ValueError if the body ends before them."""

    def __init__(self, body: bytes):
        self.body, self.pos = body, 0

    def _take(self, size: int) -> bytes:
        if self.pos + size > len(self.body):
            raise ValueError(f'record cut short: {len(self.body)} bytes, a field needs '
                             f'{self.pos + size}')
        self.pos += size
        return self.body[self.pos - size:self.pos]

    def int(self, size: int) -> int:
        return int.from_bytes(self._take(size), 'little')

    def bytes(self, length_size: int = 4) -> bytes:
        return self._take(self.int(length_size))

    def str(self) -> str:
        return self.bytes().decode()

    def str_map(self) -> dict:
        inner = _Fields(self.bytes())
        found = {}
        while inner.pos < len(inner.body):
            key = inner.str()       # before its value
            found[key] = inner.str()
        return found

    def rest(self) -> bytes:
        return self._take(len(self.body) - self.pos)


def _chunk_index(f: _Fields) -> ChunkIndex:
    start, end, offset, length = f.int(8), f.int(8), f.int(8), f.int(8)
    f.bytes()                   # message index offsets (channel id -> offset): not needed
    f.int(8)                    # message index length
    return ChunkIndex(start, end, offset, length, f.str(), f.int(8), f.int(8))


_PARSERS = {
    SCHEMA: lambda f: Schema(f.int(2), f.str(), f.str(), f.bytes()),
    CHANNEL: lambda f: Channel(f.int(2), f.int(2), f.str(), f.str(), f.str_map()),
    MESSAGE: lambda f: Message(f.int(2), f.int(4), f.int(8), f.int(8), f.rest()),
    CHUNK_INDEX: _chunk_index,
    METADATA: lambda f: Metadata(f.str(), f.str_map()),
    METADATA_INDEX: lambda f: MetadataIndex(f.int(8), f.int(8), f.str()),
}


def parse_record(opcode: int, body: bytes):
    """The record of `opcode` (one of _PARSERS') read from `body`; None for other kinds;
    ValueError if the body is too short for its fields."""
    parser = _PARSERS.get(opcode)
    return parser(_Fields(body)) if parser else None


def read_summary(f, size: int) -> Summary | None:
    """The summary section of the open MCAP file `f` (`size` bytes); None if the footer says it
    has none; ValueError if there is no footer or the summary's records are damaged."""
    if size < len(MCAP_MAGIC) + _FOOTER_SIZE + len(MCAP_MAGIC):
        raise ValueError('no footer')
    f.seek(size - len(MCAP_MAGIC) - _FOOTER_SIZE)
    opcode, length = RECORD_HEAD.unpack(f.read(RECORD_HEAD.size))
    if opcode != FOOTER or length != _FOOTER_SIZE - RECORD_HEAD.size:
        raise ValueError('expected a footer at the end of the file')
    (start,) = struct.unpack('<Q', f.read(8))
    if not start:
        return None
    footer_at = size - len(MCAP_MAGIC) - _FOOTER_SIZE
    if not len(MCAP_MAGIC) <= start <= footer_at:
        raise ValueError(f'summary start {start} outside the file')
    f.seek(start)
    summary, end = Summary(), start
    for offset, opcode, body in records(f, footer_at):
        end = offset + RECORD_HEAD.size + len(body)
        record = parse_record(opcode, body)
        if isinstance(record, Schema):
            summary.schemas[record.id] = record
        elif isinstance(record, Channel):
            summary.channels[record.id] = record
        elif isinstance(record, ChunkIndex):
            summary.chunk_indexes.append(record)
        elif isinstance(record, MetadataIndex):
            summary.metadata_indexes.append(record)
    if end != footer_at:
        raise ValueError(f'invalid summary record at byte {end}')
    return summary


def metadata_records(f, size: int):
    """The Metadata records of the open MCAP file `f` (`size` bytes): through the summary's
    metadata index, or without a summary by reading the file's records through."""
    summary = read_summary(f, size)
    if summary is None:
        f.seek(len(MCAP_MAGIC))
        for _, opcode, body in records(f, size):
            if opcode == METADATA:
                yield parse_record(opcode, body)
        return
    for index in summary.metadata_indexes:
        f.seek(index.offset)
        found = list(records(f, min(size, index.offset + index.length)))
        if not found or found[0][1] != METADATA:
            raise ValueError(f'no metadata record at byte {index.offset} (the summary points '
                             'there)')
        yield parse_record(METADATA, found[0][2])


def file_summary(path) -> Summary:
    """The summary section of the MCAP file `path`; ValueError if it has none or it is
    damaged."""
    from pathlib import Path
    path = Path(path)
    with path.open('rb') as f:
        summary = read_summary(f, path.stat().st_size)
    if summary is None:
        raise ValueError(f'{path}: no summary section')
    return summary
