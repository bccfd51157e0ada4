"""The MCAP storage writer of the bags (rosbag2_storage_mcap's part): rosbags' MCAP writer with
the channels' topic_type_hash, chunks closed at least every chunk_interval seconds and written to
disk at once (unbuffered), the chunk, data section and summary CRCs, and, after a write error, the
file truncated to its last complete chunk (closed with a valid summary: a readable bag of what was
written).

It imports rosbags: BagWriter imports this module when it opens a bag, so that importing
pam_bag.bags (a node's --help) stays quick."""

from __future__ import annotations

import functools
import os
import struct
import time
import zlib
from collections import defaultdict
from io import BytesIO

from rosbags.rosbag2.storage_mcap import (
    Channel,
    McapWriter,
    PendingChunk,
    write_channel,
    write_schema,
    write_string,
)

from ._storage import DEFAULT_CHUNK_INTERVAL, BagFile, BagWriteError
from .mcap_check import MCAP_MAGIC


class _FullWrite:
    """An unbuffered file that writes everything or raises (a short write becomes an OSError).

    `crc`: the CRC32 of the file's bytes from its start (`crc` given: that of the bytes already
    in it), as of the last complete write (the MCAP data section CRC)."""

    def __init__(self, raw, crc: int = 0):
        self.raw = raw
        self.crc = crc

    def write(self, data) -> int:
        view = memoryview(data)
        while len(view):
            n = self.raw.write(view)
            if not n:
                raise OSError('short write (file size limit or disk full?)')
            view = view[n:]
        self.crc = zlib.crc32(data, self.crc)
        return len(data)

    def tell(self) -> int:
        return self.raw.tell()

    def flush(self) -> None:
        pass

    def truncate(self, size: int) -> None:
        self.raw.truncate(size)
        self.raw.seek(size)

    def close(self) -> None:
        self.raw.close()


class _Staged:
    """An in-memory file standing at byte `base` of the real one (tell() counts from there):
    records written to it get their CRCs patched in, then go to the file in one write."""

    def __init__(self, base: int):
        self.base = base
        self.data = BytesIO()

    def write(self, data) -> int:
        return self.data.write(data)

    def tell(self) -> int:
        return self.base + self.data.tell()

    def close(self) -> None:
        pass


# byte offsets in MCAP records (opcode 1 + length 8, then the fields; MCAP specification)
_CHUNK_CRC_AT = 9 + 3 * 8        # Chunk: start time, end time, uncompressed size, then the CRC
_DATA_END_SIZE = 9 + 4           # DataEnd: data_section_crc
_FOOTER_TAIL = 4 + len(MCAP_MAGIC)   # Footer's summary_crc, then the closing magic
_CRC = struct.Struct('<I')


def _patch_summary(data: bytearray, base: int, data_crc: int) -> None:
    """The CRCs of what an MCAP writer wrote from the end of its last chunk to the file's end
    (`data`, starting at file byte `base`; `data_crc`: the CRC32 of the file before it): the
    DataEnd record's data_section_crc (every byte from the file's start to the DataEnd record)
    and the Footer's summary_crc (from the summary's start to the Footer's summary_crc)."""
    summary_start = struct.unpack_from('<Q', data, len(data) - _FOOTER_TAIL - 16)[0]
    data_end = summary_start - base - _DATA_END_SIZE      # the DataEnd record precedes it
    if data_end < 0 or data[data_end] != 0x0F:
        raise BagWriteError(f'no DataEnd record before the summary at byte {summary_start}')
    _CRC.pack_into(data, data_end + 9, zlib.crc32(data[:data_end], data_crc))
    footer_crc = len(data) - _FOOTER_TAIL
    _CRC.pack_into(data, footer_crc, zlib.crc32(data[summary_start - base:footer_crc]))


class McapStorage(McapWriter):
    """rosbags' MCAP writer + channel topic_type_hash, time-bounded chunks, write-error
    recovery (truncate to the last complete chunk)."""

    def __init__(self, path, compression, chunk_interval: float = DEFAULT_CHUNK_INTERVAL,
                 file_name: str = ''):
        """rosbags' storage writer of the bag directory `path`; chunk_interval: s a chunk stays
        open at most; file_name: the .mcap's name in it ('': rosbags' <dir>.mcap)."""
        self.chunk_interval = chunk_interval
        self.file_name = file_name
        if self.file_name and (path / self.file_name).exists():
            raise FileExistsError(f'{path / self.file_name} exists already')
        super().__init__(path, compression)
        if self.file_name and self.file_name != self.path.name:
            # rosbags always creates <dir>.mcap; a split bag's files are <dir>_<i>.mcap
            os.rename(self.path, path / self.file_name)
            self.path = path / self.file_name
        self.bio.flush()     # the magic and the Header record: the data section's start
        self.bio = _FullWrite(self.bio.detach(), zlib.crc32(self.path.read_bytes()))
        self._chunk_opened = time.monotonic()
        self._committed_stats = dict(self.channel_stats)
        self._committed_times = (self.message_start_time, self.message_end_time)
        self._committed_chunks = 0
        self._chunk_stats: dict[int, int] = {}
        self.failed: BaseException | None = None
        self.qos_texts: dict[int, str] = {}   # channel id -> offered_qos_profiles YAML

    def add_connection(self, connection, offered_qos_profiles):
        self.qos_texts[connection.id] = offered_qos_profiles
        metadata = BytesIO()
        write_string(metadata, 'offered_qos_profiles')
        write_string(metadata, offered_qos_profiles)
        write_string(metadata, 'topic_type_hash')
        write_string(metadata, connection.digest)
        self.channels.append(Channel(connection.id, connection.msgtype, connection.topic,
                                     connection.ext.serialization_format,
                                     metadata.getvalue()))
        self.channel_stats[connection.id] = 0
        self._committed_stats[connection.id] = 0
        write_channel(self.chunk.bio, self.channels[-1], self.schemas)

    def write(self, connection, timestamp, data):
        if self.failed is not None:
            raise BagWriteError(f'{self.path}: writing stopped after an error: '
                                f'{self.failed}')
        super().write(connection, timestamp, data)
        if time.monotonic() - self._chunk_opened > self.chunk_interval:
            self.close_chunk()

    def _write_staged(self, write, patch) -> None:
        """Run rosbags' `write` into memory, patch(bytes, file offset) its CRCs in, then
        write the result to the file at once."""
        real, staged = self.bio, _Staged(self.bio.tell())
        self.bio = staged
        try:
            write()
        finally:
            self.bio = real
        data = bytearray(staged.data.getbuffer())
        patch(data, staged.base)
        real.write(data)

    def close_chunk(self):
        """The open chunk (rosbags' record, with its uncompressed_crc) and its message
        indexes, written to the file at once."""
        start = self.bio.tell()
        crc = zlib.crc32(self.chunk.bio.getbuffer())
        try:
            self._write_staged(super().close_chunk,
                               lambda data, _: _CRC.pack_into(data, _CHUNK_CRC_AT, crc))
        except OSError as exc:
            self.failed = exc
            self.bio.truncate(start)
            # forget the lost chunk: counts and times as of the last complete chunk
            del self.chunks[self._committed_chunks:]
            self.channel_stats = dict(self._committed_stats)
            self.message_start_time, self.message_end_time = self._committed_times
            self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
            if start <= 8 + 64:   # nothing but the header was written: keep the definitions
                for schema in self.schemas:
                    write_schema(self.chunk.bio, schema)
                for channel in self.channels:
                    write_channel(self.chunk.bio, channel, self.schemas)
            raise BagWriteError(f'{self.path}: write failed: {exc}') from exc
        self._chunk_opened = time.monotonic()
        self._committed_stats = dict(self.channel_stats)
        self._committed_times = (self.message_start_time, self.message_end_time)
        self._committed_chunks = len(self.chunks)

    def close(self, version, metadata):
        """rosbags' metadata record, DataEnd, summary and footer, with the data section's
        and the summary's CRCs, written at once."""
        if self.chunk.bio.tell():
            self.close_chunk()
        real = self.bio
        self._write_staged(functools.partial(super().close, version, metadata),
                           lambda data, base: _patch_summary(data, base, real.crc))
        real.close()

    def stats(self, name: str) -> BagFile:
        """What this file holds as of its last complete chunk (after an error) or now."""
        return BagFile(name, self.message_start_time, self.message_end_time,
                       dict(self.channel_stats))

    def size(self) -> int:
        """Bytes on disk plus the open chunk (uncompressed) and its message indexes: an
        upper bound of the file's size before its metadata record and summary."""
        pending = self.chunk.msgs
        return (self.bio.tell() + self.chunk.bio.tell() + 64 +
                sum(16 * len(v) + 24 for v in pending.values()))
