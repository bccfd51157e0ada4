"""rosbag2 (Jazzy) MCAP bags without rosbag2 and without rclpy: writing, checking, reading, info.

The bag layout is Jazzy's (see shared/BAGS.md): a directory with metadata.yaml version 9 and one
`<dir>.mcap` file (or, split by size or duration, `<dir>_0.mcap`, `<dir>_1.mcap`, ... each complete
on its own), profile ros2, one ros2msg schema per type with its full definition, one channel
per topic with metadata offered_qos_profiles and topic_type_hash (RIHS01), a rosbag2 metadata
record, zstd chunk compression and the per-message index; ros_distro 'jazzy' in metadata.yaml and
in that record, as rosbag2 Jazzy writes. Writing goes through rosbags' Writer with a storage
writer that also writes topic_type_hash, closes a chunk at least every `chunk_interval` seconds
and writes it to disk at once (unbuffered), so that a crash loses at most the last chunk, and a
write error leaves the file truncated to its last complete chunk and closed with a valid summary
(a readable bag of what was written). Every chunk carries the CRC32 of its records, and each
file the data section and summary CRCs (MCAP specification; as rosbag2's MCAP writer); every
read checks the chunk CRCs (a CRC of 0, in bags written before, is not checked), verify_bag()
also the data section's. recover_bag() turns the directory a crashed recorder left (every
complete chunk, no summary, no metadata.yaml), or a bag with a damaged chunk or a missing file,
into a complete bag again.

Types: the Jazzy typestore of rosbags plus the messages of pam_interfaces, registered from their
.msg files (their RIHS01 hashes equal rosidl's).
"""

from __future__ import annotations

import collections
import functools
import os
import shutil
import struct
import threading
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from .mcap_check import (
    CHUNK,
    DATA_END,
    FOOTER,
    MCAP_MAGIC,
    RECORD_HEAD,
    FileCheck,
    check_file,
    chunk_records,
    records,
    summary_problem,
)
from .mcap_records import (
    CHANNEL,
    MESSAGE,
    SCHEMA,
    file_summary,
    metadata_records,
    parse_record,
    read_summary,
)

METADATA = 'metadata.yaml'
DEFAULT_CHUNK_INTERVAL = 1.0   # s: longest time a received message stays only in memory
MIN_SPLIT_SIZE = 100_000      # B: smallest max_bag_size (a file of a split bag)
MIN_SPLIT_DURATION = 1.0      # s: smallest max_bag_duration
ROS_DISTRO = 'jazzy'   # the bags' ros_distro (rosbag2 writes $ROS_DISTRO; rosbags 'rosbags')


EXIT_BAD_INPUT = 2   # exit code of every tool for bad input: a missing, bad or damaged bag
#                      (docs/stopping.md, Exit codes)


class BagError(RuntimeError):
    """A bag cannot be written or read; the message names the file and the problem."""


class BagWriteError(BagError):
    """Writing failed; the bag was closed with what had been written before the error."""


# ------------------------------------------------------------------------------- types
def interface_dirs() -> list[Path]:
    """Folders holding pam_interfaces/msg/*.msg: the installed share folder(s), else the source."""
    dirs = []
    import sys
    prefixes = [*os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep), sys.prefix]
    for prefix in prefixes:
        if prefix and (Path(prefix) / 'share' / 'pam_interfaces' / 'msg').is_dir():
            dirs.append(Path(prefix) / 'share' / 'pam_interfaces' / 'msg')
    source = Path(__file__).resolve().parents[2] / 'pam_interfaces' / 'msg'
    if not dirs and source.is_dir():
        dirs.append(source)
    return dirs


def make_typestore(extra_msg_files=()):
    """rosbags typestore: Jazzy's types + pam_interfaces (+ extra (msgtype, path) .msg files)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    files = [(f'pam_interfaces/msg/{p.stem}', p) for d in interface_dirs()[:1]
             for p in sorted(d.glob('*.msg'))]
    for msgtype, path in [*files, *extra_msg_files]:
        types.update(get_types_from_msg(Path(path).read_text(), msgtype))
    store.register(types)
    return store


def known_type(store, msgtype: str) -> bool:
    return msgtype in store.fielddefs


def definition_hash(msgtype: str, definition: str) -> str:
    """The RIHS01 hash of `msgtype` as the ros2msg `definition` defines it (with the types it
    uses after it, as a bag's schema embeds them); '' if the text cannot be parsed."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    try:
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(definition, msgtype))
        return store.hash_rihs01(msgtype)
    except Exception:  # noqa: BLE001 - an incomplete or damaged definition: not checkable
        return ''


# ------------------------------------------------------------------------------- QoS
def make_qos(reliable: bool = True, depth: int = 100, transient_local: bool = False,
             keep_all: bool = False):
    """A rosbags Qos (the form of metadata.yaml's offered_qos_profiles)."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )
    infinite = QosTime(sec=2147483647, nsec=4294967295)
    return Qos(history=QosHistory.KEEP_ALL if keep_all else QosHistory.KEEP_LAST, depth=depth,
               reliability=QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               durability=(QosDurability.TRANSIENT_LOCAL if transient_local
                           else QosDurability.VOLATILE),
               deadline=infinite, lifespan=infinite, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=infinite, avoid_ros_namespace_conventions=False)


def qos_from_ints(history: int, depth: int, reliability: int, durability: int, liveliness: int,
                  deadline=(0, 0), lifespan=(0, 0), lease=(0, 0)):
    """A rosbags Qos from the integer enums of rmw (rclpy's QoSProfile policies use the same)."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    def enum(cls, value):
        try:
            return cls(int(value))
        except ValueError:
            return cls.UNKNOWN
    return Qos(history=enum(QosHistory, history), depth=int(depth),
               reliability=enum(QosReliability, reliability),
               durability=enum(QosDurability, durability), deadline=QosTime(*deadline),
               lifespan=QosTime(*lifespan), liveliness=enum(QosLiveliness, liveliness),
               liveliness_lease_duration=QosTime(*lease), avoid_ros_namespace_conventions=False)


# ------------------------------------------------------------------------------- writing
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
        from io import BytesIO
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


def _storage_writer_class():
    from io import BytesIO

    from rosbags.rosbag2.storage_mcap import Channel, McapWriter, write_channel, write_string

    class PamMcapWriter(McapWriter):
        """rosbags' MCAP writer + channel topic_type_hash, time-bounded chunks, write-error
        recovery (truncate to the last complete chunk)."""

        chunk_interval = DEFAULT_CHUNK_INTERVAL
        file_name = ''    # the .mcap's name in the bag directory ('': rosbags' <dir>.mcap)

        def __init__(self, path, compression):
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
                from collections import defaultdict

                from rosbags.rosbag2.storage_mcap import PendingChunk
                self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
                if start <= 8 + 64:   # nothing but the header was written: keep the definitions
                    for schema in self.schemas:
                        from rosbags.rosbag2.storage_mcap import write_schema
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

        def stats(self, name: str) -> _BagFile:
            """What this file holds as of its last complete chunk (after an error) or now."""
            return _BagFile(name, self.message_start_time, self.message_end_time,
                            dict(self.channel_stats))

        def size(self) -> int:
            """Bytes on disk plus the open chunk (uncompressed) and its message indexes: an
            upper bound of the file's size before its metadata record and summary."""
            pending = self.chunk.msgs
            return (self.bio.tell() + self.chunk.bio.tell() + 64 +
                    sum(16 * len(v) + 24 for v in pending.values()))

    return PamMcapWriter


@dataclass
class _Topic:
    name: str
    msgtype: str
    connection: object
    count: int = 0


@dataclass
class _BagFile:
    """One .mcap file of a bag: its name, first and last message time (ns) and message counts
    per channel id."""

    name: str
    start_ns: int = 2**63 - 1
    end_ns: int = 0
    counts: dict = field(default_factory=dict)

    @property
    def count(self) -> int:
        return sum(self.counts.values())


def _metadata(writer, files: list) -> dict:
    """The rosbag2_bagfile_information (version 9) of a bag made of `files` (_BagFile)."""
    from rosbags.rosbag2.metadata import dump_qos_v9
    counts = collections.Counter()
    for f in files:
        counts.update(f.counts)
    start = min(f.start_ns for f in files)
    return {
        'version': writer.version,
        'storage_identifier': 'mcap',
        'relative_file_paths': [f.name for f in files],
        'duration': {'nanoseconds': max(0, max(f.end_ns for f in files) - start)},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': sum(counts.values()),
        'topics_with_message_count': [
            {'topic_metadata': {'name': c.topic, 'type': c.msgtype,
                                'serialization_format': c.ext.serialization_format,
                                'offered_qos_profiles': dump_qos_v9(c.ext.offered_qos_profiles),
                                'type_description_hash': c.digest},
             'message_count': counts[c.id]}
            for c in writer.connections],
        'compression_format': '',
        'compression_mode': '',
        'files': [{'path': f.name, 'starting_time': {'nanoseconds_since_epoch': f.start_ns},
                   'duration': {'nanoseconds': max(0, f.end_ns - f.start_ns)},
                   'message_count': f.count} for f in files],
        'custom_data': writer.custom_data or None,
        'ros_distro': ROS_DISTRO,
    }


def _yaml_text(data) -> str:
    from io import StringIO

    from ruamel.yaml import YAML
    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    out = StringIO()
    yaml.dump(data, out)
    return out.getvalue()


def check_split(max_bag_size: int, max_bag_duration: float) -> None:
    """BagError naming the parameter unless each is 0 (no split) or at least its minimum."""
    if max_bag_size != 0 and not max_bag_size >= MIN_SPLIT_SIZE:
        raise BagError(f'max_bag_size {max_bag_size} B: use 0 (no split) or at least '
                       f'{MIN_SPLIT_SIZE} B')
    if max_bag_duration != 0 and not max_bag_duration >= MIN_SPLIT_DURATION:
        raise BagError(f'max_bag_duration {max_bag_duration} s: use 0 (no split) or at least '
                       f'{MIN_SPLIT_DURATION} s')


def _locked(method):
    """A BagWriter method run under the writer's (reentrant) lock."""
    @functools.wraps(method)
    def run(self, *args, **kwargs):
        with self._lock:
            return method(self, *args, **kwargs)
    return run


@dataclass
class BagWriter:
    """A Jazzy MCAP bag being written: add_topic(), write(topic, t_ns, cdr_bytes), close().

    The output directory must not exist (never overwritten). After a BagWriteError the bag holds
    what was written before the error; close() then finishes it (summary, metadata.yaml).

    Split bags (as `ros2 bag record --max-bag-size/--max-bag-duration`): with max_bag_size
    (bytes) or max_bag_duration (s) set, the bag is the files <dir>_0.mcap, <dir>_1.mcap, ...;
    a file is closed (summary written: it is then complete on its own) and the next one opened
    before a message that would make the bytes written plus the open chunk (uncompressed) reach
    max_bag_size, or that comes max_bag_duration or more after the file's first message. The
    rosbag2 metadata record and the summary (a few kB) come on top of max_bag_size. Without
    them: one file, <dir>.mcap. `file_name` and next_file(name) name the files otherwise
    (pam-bag-recover keeps the names of the files it rebuilds).

    Thread-safe: bag_record adds topics from its executor thread (discovery) while its writer
    thread writes (one lock; a topic added during a chunk's compression once corrupted it).
    """

    path: Path
    compression: str = 'zstd'           # 'zstd' (per chunk) or 'none'
    chunk_interval: float = DEFAULT_CHUNK_INTERVAL
    typestore: object = None
    max_bag_size: int = 0               # bytes per file; 0: no split by size
    max_bag_duration: float = 0.0       # s per file; 0: no split by time
    split: bool = False                 # files <dir>_<i>.mcap (implied by the two above)
    topics: dict = field(default_factory=dict)
    file_name: str = ''                 # the first file's name ('': <dir>.mcap, <dir>_0.mcap)

    def __post_init__(self):
        from rosbags.rosbag2 import Writer
        from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
        self._lock = threading.RLock()
        self.path = Path(self.path)
        if self.path.exists():
            raise BagError(f'{self.path}: the output already exists; not overwriting it '
                           '(choose another name or remove it)')
        check_split(self.max_bag_size, self.max_bag_duration)
        self.split = self.split or bool(self.max_bag_size or self.max_bag_duration)
        if self.typestore is None:
            self.typestore = make_typestore()
        self._storage = storage = _storage_writer_class()
        storage.chunk_interval = self.chunk_interval
        storage.file_name = self.file_name or self._file_name(0)

        class _Writer(Writer):
            # rosbags' Writer takes its storage class from this table: one class per writer
            STORAGE_PLUGINS = {StoragePlugin.MCAP: storage}   # noqa: RUF012 - rosbags' own hook

        self._writer = _Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        if self.compression == 'zstd':
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        elif self.compression != 'none':
            raise BagError(f"unknown compression {self.compression!r}: use 'zstd' or 'none'")
        try:
            self._writer.open()
        except Exception as exc:
            raise BagError(f'{self.path}: cannot create the bag: {exc}') from exc
        self.set_custom_data('recorder', 'pam_driver bag_record')
        self.closed = False
        self.error: BaseException | None = None
        self.files: list[_BagFile] = []     # the files closed so far

    def _file_name(self, index: int) -> str:
        return f'{self.path.name}_{index}.mcap' if self.split else f'{self.path.name}.mcap'

    @property
    def mcap_path(self) -> Path:
        """The file being written."""
        return self.path / self._storage.file_name

    @_locked
    def add_topic(self, topic: str, msgtype: str, qos_profiles=(), definition=None) -> None:
        """A topic of `msgtype`, defined as the typestore defines it, or as `definition`
        (ros2msg text, RIHS01 hash) if given: the definition a recorded bag holds."""
        if not known_type(self.typestore, msgtype):
            raise BagError(f'unknown message type {msgtype!r} of topic {topic}')
        msgdef, rihs01 = definition or (None, None)
        conn = self._writer.add_connection(topic, msgtype, typestore=self.typestore,
                                           msgdef=msgdef, rihs01=rihs01,
                                           offered_qos_profiles=list(qos_profiles))
        self.topics[topic] = _Topic(topic, msgtype, conn)

    @_locked
    def set_custom_data(self, key: str, value: str) -> None:
        """A custom_data entry of metadata.yaml."""
        self._writer.set_custom_data(key, value)

    @_locked
    def write(self, topic: str, t_ns: int, data: bytes) -> None:
        entry = self.topics[topic]
        t_ns = int(t_ns)
        if self._writer.storage is None:
            raise BagWriteError(f'{self.path}: writing stopped after an error: {self.error}')
        try:
            if self._file_full(t_ns):
                self.next_file()
            self._writer.write(entry.connection, t_ns, data)
        except BagWriteError as exc:
            self.error = exc
            raise
        except OSError as exc:
            self.error = exc
            raise BagWriteError(f'{self.mcap_path}: write failed: {exc}') from exc
        entry.count += 1

    @_locked
    def file_has_messages(self) -> bool:
        """Whether the file being written holds a message."""
        storage = self._writer.storage
        return storage is not None and any(storage.channel_stats.values())

    @_locked
    def rename_file(self, name: str) -> None:
        """Give the file being written, while it holds no message, another name."""
        storage = self._writer.storage
        new = self.path / name
        if storage is None or self.file_has_messages() or new.exists():
            raise BagError(f'{self.mcap_path}: cannot rename it to {name} (closed, holding '
                           'messages, or the name is taken)')
        os.rename(storage.path, new)
        storage.path = new
        self._storage.file_name = name

    def _file_full(self, t_ns: int) -> bool:
        storage = self._writer.storage
        if not self.split or not self.file_has_messages() or storage.failed is not None:
            return False
        return bool((self.max_bag_size and storage.size() >= self.max_bag_size) or
                    (self.max_bag_duration and
                     t_ns - storage.message_start_time >= self.max_bag_duration * 1e9))

    @_locked
    def next_file(self, name: str = '') -> None:
        """Close the file being written (complete, with its summary) and open the next one,
        `name` ('': <dir>_<i>.mcap), with the same schemas and channels (a split bag)."""
        if not self.split:
            raise BagError(f'{self.path}: not a split bag (max_bag_size, max_bag_duration or '
                           'split)')
        old = self._writer.storage
        self._close_file()
        self._storage.file_name = name or self._file_name(len(self.files))
        try:
            new = self._storage(self.path, self._writer.compression_mode)
        except OSError as exc:
            raise BagWriteError(f'{self.mcap_path}: cannot create the next file of the bag: '
                                f'{exc}') from exc
        added = set()
        for conn in self._writer.connections:
            if conn.msgtype not in added:
                new.add_msgtype(conn)
                added.add(conn.msgtype)
            new.add_connection(conn, old.qos_texts[conn.id])
        self._writer.storage = new

    def _close_file(self) -> None:
        """Write the open file's last chunk and summary; it joins self.files. The file's rosbag2
        record holds the bag's metadata as of this file."""
        storage, self._writer.storage = self._writer.storage, None
        try:
            if storage.failed is None and storage.chunk.bio.tell():
                storage.close_chunk()
        except BagWriteError as exc:
            self.error = exc
        self.files.append(storage.stats(storage.path.name))
        info = _metadata(self._writer, self.files)
        try:
            storage.close(self._writer.version, _yaml_text(info).strip())
        except OSError as exc:
            raise BagWriteError(f'{storage.path}: cannot finish the file: {exc}') from exc

    @_locked
    def close(self) -> None:
        """Write the last file's summary and metadata.yaml (the counts of what is on disk)."""
        if self.closed:
            return
        self.closed = True
        try:
            if self._writer.storage is not None:
                self._close_file()
            meta = self.path / METADATA
            tmp = meta.with_suffix('.yaml.tmp')
            tmp.write_text(_yaml_text({'rosbag2_bagfile_information':
                                       _metadata(self._writer, self.files)}))
            tmp.replace(meta)
        except OSError as exc:
            raise BagWriteError(f'{self.path}: cannot finish the bag: {exc}') from exc

    @_locked
    def counts(self) -> dict[str, int]:
        return {t: e.count for t, e in self.topics.items()}


# ------------------------------------------------------------------------------- reading
def bag_dir(path) -> Path:
    """The bag directory `path` names (an .mcap file: its folder); BagError if it is none."""
    path = Path(path)
    if path.is_file() and path.suffix == '.mcap':
        path = path.parent
    if not path.is_dir():
        raise BagError(f'{path}: no such bag directory')
    return path


def check_bag(path) -> Path:
    """The bag directory, after checking metadata.yaml and its .mcap files; BagError otherwise."""
    path = bag_dir(path)
    for name in read_metadata(path)['relative_file_paths']:
        check_mcap(path / name)
    return path


def read_metadata(path) -> dict:
    """The rosbag2_bagfile_information of the bag directory `path` (its metadata.yaml), with
    its file list (relative_file_paths) and storage 'mcap'; BagError otherwise."""
    meta = Path(path) / METADATA
    if not meta.is_file():
        raise BagError(f'{meta}: missing (not a rosbag2 bag directory, or the recorder was '
                       f'killed before closing it: `pam-bag-recover {path}` repairs that)')
    try:
        from ruamel.yaml import YAML
        info = YAML(typ='safe').load(meta.read_text())['rosbag2_bagfile_information']
        files = info['relative_file_paths']
        storage = info.get('storage_identifier')
        if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
            raise ValueError('relative_file_paths is not a list of file names')
    except Exception as exc:
        raise BagError(f'{meta}: unreadable metadata: {exc}') from exc
    if storage != 'mcap':
        raise BagError(f'{meta}: storage {storage!r} is not supported (only mcap)')
    return info


def check_mcap(path) -> None:
    """Magic at both ends, a readable summary and its CRC (if it has one); BagError naming the
    file and the problem."""
    path = Path(path)
    if not path.is_file():
        raise BagError(f'{path}: missing (listed in {METADATA})')
    size = path.stat().st_size
    with path.open('rb') as f:
        head = f.read(8)
        f.seek(max(0, size - 8))
        tail = f.read(8)
    if head != MCAP_MAGIC:
        raise BagError(f'{path}: not an MCAP file (bad magic)')
    if size < 16 + 29 or tail != MCAP_MAGIC:
        raise BagError(f'{path}: truncated or corrupt MCAP file (no footer: the recording was '
                       'cut short or the file was damaged; pam-bag-recover keeps what is readable)')
    try:
        with path.open('rb') as f:
            problem = summary_problem(f, size)
            if problem:
                raise ValueError(problem)
            summary = read_summary(f, size)
        if summary is None:
            raise ValueError('no summary section')
    except Exception as exc:
        raise BagError(f'{path}: corrupt MCAP file: {exc}') from exc


def verify_bag(path, first_only: bool = False) -> list[FileCheck]:
    """Every file of a bag read through (mcap_check.check_file: every chunk with its CRC, the
    data section and summary CRCs), after the checks of check_mcap; a file metadata.yaml lists
    that is missing is a problem too. `first_only`: stop at the first problem. BagError if
    the bag directory or its metadata.yaml is unusable."""
    path = bag_dir(path)
    info = read_metadata(path)
    start_ns = (info.get('starting_time') or {}).get('nanoseconds_since_epoch')
    checks = []
    for name in info['relative_file_paths']:
        check = FileCheck(path / name)
        try:
            check_mcap(path / name)
        except BagError as exc:
            check.problems.append(str(exc).replace(f'{path / name}: ', f'{name}: ', 1))
        if check.path.is_file() and not (first_only and check.problems):
            found = check_file(check.path, start_ns, first_only)
            check.chunks, check.chunks_with_crc = found.chunks, found.chunks_with_crc
            check.data_crc = found.data_crc
            check.problems += found.problems
        checks.append(check)
        if first_only and check.problems:
            break
    return checks


@dataclass
class BagSelection:
    """A bag's selected topics, opened for streaming: what they are now, their messages on
    demand (messages()), in receive-time order from `first_ns` on."""

    path: Path
    topics: dict                # topic -> msgtype
    qos: dict                   # topic -> list of rosbags Qos
    topic_names: list           # sorted; messages() gives indexes into it
    start_ns: int               # the bag's first and last receive times (all topics)
    end_ns: int
    first_ns: int               # start_ns + start_offset: where reading starts
    message_count: int          # of the selected topics in the whole bag
    files: list                 # the .mcap files, in order
    unchecked: list = field(default_factory=list)   # topics whose definition was not checked

    def messages(self):
        """Yield (receive time ns, topic index, CDR bytes) of the selected topics from
        first_ns on, reading the bag chunk by chunk; BagError on a damaged chunk (after the
        messages before it)."""
        from rosbags.rosbag2 import Reader
        if not self.topic_names:
            return
        index = {n: i for i, n in enumerate(self.topic_names)}
        count = 0
        try:
            with Reader(self.path) as reader:
                conns = [c for c in reader.connections if c.topic in index]
                for conn, t, raw in reader.messages(connections=conns, start=self.first_ns):
                    yield t, index[conn.topic], bytes(raw)
                    count += 1
        except Exception as exc:   # damaged, or changed since open_bag
            where = self.files[0] if len(self.files) == 1 else self.path
            raise BagError(f'{where}: corrupt data after {count} messages: '
                           f'{self._first_damage(exc)} (`pam-bag-recover {self.path}` keeps the '
                           'readable chunks)') from exc

    def _first_damage(self, error: Exception) -> str:
        """The first problem verify_bag finds (it names the file and the chunk), else what
        the reader said (`error`)."""
        try:
            problems = [p for c in verify_bag(self.path, first_only=True) for p in c.problems]
        except BagError as exc:
            problems = [str(exc)]
        return problems[0] if problems else str(error)


def bag_files(path) -> list[Path]:
    """The .mcap files metadata.yaml lists, in order."""
    return [Path(path) / name for name in read_metadata(path)['relative_file_paths']]


def recorded_types(files) -> list[tuple[Path, str, str, str]]:
    """(file, topic, type, RIHS01 hash) of every channel of the .mcap `files` (read from their
    summaries): the channel's topic_type_hash, else the hash of the schema's embedded ros2msg
    definition (a bag of a rosbag2 older than Jazzy has no hashes); '' if neither."""
    found = []
    for path in files:
        summary = file_summary(path)
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            found.append((Path(path), channel.topic, schema.name if schema else '',
                          channel_hash(channel, schema)))
    return found


def channel_hash(channel, schema) -> str:
    """The RIHS01 hash of an MCAP channel's type as recorded: the channel's topic_type_hash,
    else the hash of its schema's ros2msg definition; '' if neither."""
    rihs01 = channel.metadata.get('topic_type_hash', '')
    if rihs01.startswith('RIHS01_'):
        return rihs01
    if schema is None or schema.encoding != 'ros2msg' or not schema.data.strip():
        return ''      # rosbag2 writes an empty schema for a type it found no definition of
    return definition_hash(schema.name, schema.data.decode(errors='replace'))


def check_definitions(files, topics, store=None) -> list[str]:
    """BagError naming the topic, its type and both hashes if one of `topics` was recorded
    with another definition of its type than the installed one (`store`, make_typestore()'s
    by default): its messages would not deserialize here, and a subscriber of the installed
    type would receive none of them. Returns the topics that could not be checked (no hash and
    no readable definition, or a type not installed)."""
    store = make_typestore() if store is None else store
    unchecked, wrong = set(), []
    for path, topic, msgtype, rihs01 in recorded_types(files):
        if topic not in topics:
            continue
        if not rihs01 or not known_type(store, msgtype):
            unchecked.add(topic)
        elif rihs01 != (installed := store.hash_rihs01(msgtype)):
            wrong.append((path, topic, msgtype, rihs01, installed))
    if wrong:
        path, topic, msgtype, rihs01, installed = wrong[0]
        others = sorted({w[1] for w in wrong} - {topic})
        raise BagError(f'{path}: topic {topic} was recorded with a different definition of '
                       f'{msgtype} (bag {rihs01}, installed {installed}): re-record or convert '
                       'the bag' + (f' (so were {", ".join(others)})' if others else ''))
    return sorted(unchecked)


def open_bag(path, topics=None, start_offset: float = 0.0,
             check_types: bool = True) -> BagSelection:
    """Check a bag (check_bag) and select `topics` (all if None) from start_offset (s) on;
    BagError naming the file and the problem, or a topic the bag does not have, or (with
    `check_types`) a topic recorded with another definition of its type than the installed
    one (check_definitions)."""
    from rosbags.rosbag2 import Reader
    path = check_bag(path)
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:
        raise BagError(f'{path}: cannot open the bag: {exc}') from exc
    try:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        if topics is not None:
            missing = sorted(set(topics) - {c.topic for c in reader.connections})
            if missing:
                raise BagError(f'{path}: no topic {", ".join(missing)} in the bag (it has: '
                               f'{", ".join(sorted(reader.topics))})')
        selection = BagSelection(path, {c.topic: c.msgtype for c in conns},
                                 {c.topic: list(c.ext.offered_qos_profiles) for c in conns},
                                 sorted({c.topic for c in conns}), reader.start_time,
                                 reader.end_time, reader.start_time + round(start_offset * 1e9),
                                 sum(c.msgcount for c in conns), bag_files(path))
    finally:
        reader.close()
    if check_types:
        selection.unchecked = check_definitions(selection.files, selection.topics)
    return selection


@dataclass
class BagContents:
    """Messages of a bag loaded into memory, in receive-time order."""

    path: Path
    topics: dict                # topic -> msgtype
    qos: dict                   # topic -> list of rosbags Qos
    times: list                 # int ns, sorted
    topic_index: list           # index into topic_names
    topic_names: list
    data: list                  # bytes
    start_ns: int = 0
    end_ns: int = 0

    def deserialized(self, topic: str, store) -> list:
        """[(receive time ns, message)] of `topic` (none if the bag has not got it), read with
        the rosbags typestore `store`; BagError naming the message that cannot be read."""
        if topic not in self.topics:
            return []
        index, msgtype, out = self.topic_names.index(topic), self.topics[topic], []
        for t, i, data in zip(self.times, self.topic_index, self.data, strict=True):
            if i == index:
                try:
                    out.append((t, store.deserialize_cdr(data, msgtype)))
                except Exception as exc:   # short, long or garbled CDR
                    raise BagError(f'{self.path}: message {len(out) + 1} of {topic} is not a '
                                   f'valid {msgtype} ({len(data)} bytes: {exc}); was it '
                                   'recorded with another definition of the type?') from exc
        return out


def load_bag(path, topics=None, start_offset: float = 0.0,
             check_types: bool = True) -> BagContents:
    """Read a bag's messages (only `topics` if given) from start_offset (s) into memory;
    BagError as open_bag."""
    selection = open_bag(path, topics, start_offset, check_types)
    contents = BagContents(selection.path, selection.topics, selection.qos, [], [],
                           selection.topic_names, [], selection.start_ns, selection.end_ns)
    for t, i, data in selection.messages():
        contents.times.append(t)
        contents.topic_index.append(i)
        contents.data.append(data)
    return contents


def embedded_metadata(mcap_path) -> dict:
    """The bag metadata rosbag2 also stores in the MCAP file (its 'rosbag2' metadata record,
    key serialized_metadata: the metadata.yaml content); {} if there is none."""
    from ruamel.yaml import YAML
    with open(mcap_path, 'rb') as f:
        for record in metadata_records(f, os.fstat(f.fileno()).st_size):
            if record.name == 'rosbag2' and 'serialized_metadata' in record.metadata:
                return YAML(typ='safe').load(record.metadata['serialized_metadata'])
    return {}


def bag_info(path) -> dict:
    """Topics, types, counts, duration, rates and compression of a bag (from its metadata and
    the MCAP summary)."""
    path = check_bag(path)
    meta = read_metadata(path)
    files = [path / f for f in meta['relative_file_paths']]
    duration = meta['duration']['nanoseconds'] * 1e-9
    chunk_compression = set()
    for f in files:
        chunk_compression |= {c.compression or 'none' for c in file_summary(f).chunk_indexes}
    topics = []
    for entry in meta['topics_with_message_count']:
        tm = entry['topic_metadata']
        n = entry['message_count']
        topics.append({'name': tm['name'], 'type': tm['type'], 'count': n,
                       'rate': (n - 1) / duration if duration > 0 and n > 1 else 0.0,
                       'serialization_format': tm['serialization_format'],
                       'type_description_hash': tm.get('type_description_hash', '')})
    return {'path': str(path), 'version': meta['version'],
            'storage': meta['storage_identifier'], 'files': [str(f) for f in files],
            'size': sum(f.stat().st_size for f in files), 'duration': duration,
            'start_ns': meta['starting_time']['nanoseconds_since_epoch'],
            'ros_distro': meta.get('ros_distro', ''),
            'message_count': meta['message_count'],
            'compression': ', '.join(sorted(chunk_compression)) or 'none',
            'compression_mode': (meta.get('compression_mode') or
                                 ('chunk (storage)' if chunk_compression - {'none'} else '')),
            'topics': sorted(topics, key=lambda t: t['name'])}


def format_info(info: dict) -> str:
    import datetime
    start = datetime.datetime.fromtimestamp(info['start_ns'] * 1e-9, tz=datetime.timezone.utc)
    end = datetime.datetime.fromtimestamp(info['start_ns'] * 1e-9 + info['duration'],
                                          tz=datetime.timezone.utc)
    lines = [f"Files:             {', '.join(Path(f).name for f in info['files'])}",
             f"Bag size:          {info['size'] / 2**20:.1f} MiB",
             f"Storage id:        {info['storage']} (metadata version {info['version']})",
             f"Duration:          {info['duration']:.3f}s",
             f"Start:             {start:%b %d %Y %H:%M:%S.%f} (UTC)",
             f"End:               {end:%b %d %Y %H:%M:%S.%f} (UTC)",
             f"Messages:          {info['message_count']}",
             f"Compression:       {info['compression']} ({info['compression_mode'] or 'none'})",
             'Topic information:']
    width = max((len(t['name']) for t in info['topics']), default=0)
    for t in info['topics']:
        lines.append(f"  Topic: {t['name']:<{width}} | Type: {t['type']} | Count: {t['count']} | "
                     f"Rate: {t['rate']:.1f} Hz | Serialization Format: "
                     f"{t['serialization_format']}")
    return '\n'.join(lines) + '\n'


# ------------------------------------------------------------------------------- recovery
DAMAGED = '.damaged'            # suffix of the original files recover_bag() keeps
RECOVER_TMP = '.pam-bag-recover.tmp'


@dataclass
class Recovery:
    """What recover_bag() made of a crashed bag."""

    path: Path                  # the bag directory, now a complete bag
    damaged: list               # the original files, renamed to <name>.damaged
    size: int                   # bytes of the damaged .mcap file(s)
    dropped_bytes: int = 0      # of them not recovered: a cut-off tail, unreadable records
    counts: dict = field(default_factory=dict)     # topic -> messages recovered
    start_ns: int = 0           # first and last message (receive) time
    end_ns: int = 0
    problems: list = field(default_factory=list)   # what was dropped, where and why
    missing: list = field(default_factory=list)    # (name, messages or None): files the bag
    #                                                listed that were not there

    @property
    def lost_messages(self) -> int:
        """Messages of the missing files (as far as the bag's metadata counted them)."""
        return sum(n or 0 for _, n in self.missing)


def first_problems(problems: list, limit: int = 3) -> list:
    """The first `limit` problems, then how many more there are."""
    more = len(problems) - limit
    return problems[:limit] + ([f'... and {more} more'] if more > 0 else [])


def _parse_records(opcode: int, body: bytes) -> tuple[str, list]:
    """(chunk compression or None, the schema/channel/message records) of one record; a chunk
    is checked and unpacked by mcap_check.chunk_records."""
    if opcode != CHUNK:
        record = parse_record(opcode, body) if opcode in (SCHEMA, CHANNEL, MESSAGE) else None
        return None, [record] if record is not None else []
    compression, inner = chunk_records(body)
    return compression, [r for _, op, b in inner for r in _parse_records(op, b)[1]]


def _file_index(mcap: Path) -> tuple:
    """Sort key of a bag's files: <dir>.mcap, then <dir>_0.mcap, <dir>_1.mcap, ... by number,
    then any other name."""
    number = mcap.stem[len(mcap.parent.name) + 1:]
    if mcap.stem == mcap.parent.name:
        return (0, 0, '')
    if mcap.stem.startswith(mcap.parent.name + '_') and number.isdigit():
        return (1, int(number), '')
    return (2, 0, mcap.name)


def _listed_files(path: Path) -> list[tuple[str, int | None]]:
    """(name, message count or None) of each file the bag lists, in order: its metadata.yaml,
    or without one the 'rosbag2' record of its complete .mcap that lists the most files (each
    file of a split recording holds the bag's metadata as of its closing)."""
    try:
        info = read_metadata(path)
    except BagError:
        info = {}
        for mcap in path.glob('*.mcap'):
            try:
                check_mcap(mcap)
                embedded = embedded_metadata(mcap)
            except Exception:  # noqa: BLE001 - incomplete or damaged: it lists nothing
                continue
            if (len(embedded.get('relative_file_paths') or []) >
                    len(info.get('relative_file_paths') or [])):
                info = embedded
    counts = {f.get('path'): f.get('message_count') for f in info.get('files') or []
              if isinstance(f, dict)}
    return [(name, counts.get(name)) for name in info.get('relative_file_paths') or []
            if isinstance(name, str)]


def _readable(path: Path) -> bool:
    """Whether the bag passes verify_bag (every chunk, the CRCs) and every message reads."""
    try:
        if any(check.problems for check in verify_bag(path, first_only=True)):
            return False
        for _ in open_bag(path, check_types=False).messages():
            pass
    except BagError:
        return False
    return True


def _find_damaged(path) -> tuple[Path, list, list]:
    """The bag directory, its .mcap files in order (as listed, then the others) and the
    (name, messages) of the files it lists that are missing, if it needs recovery; BagError
    otherwise."""
    path = bag_dir(path)
    listed = _listed_files(path)
    order = {name: i for i, (name, _) in enumerate(listed)}
    mcaps = sorted(path.glob('*.mcap'), key=lambda p: (order.get(p.name, len(order)),
                                                        _file_index(p)))
    missing = [(name, n) for name, n in listed if not (path / name).is_file()]
    if not mcaps:
        raise BagError(f'{path}: no .mcap file' + (
            f' (it lists {", ".join(name for name, _ in missing)}: all missing)'
            if missing else ''))
    if (path / METADATA).exists() and _readable(path):
        raise BagError(f'{path}: a complete bag (metadata.yaml and .mcap files with their '
                       'summaries, every chunk and CRC checked): it needs no recovery')
    for original in (*mcaps, path / METADATA):
        kept = original.with_name(original.name + DAMAGED)
        if kept.exists():
            raise BagError(f'{kept}: already exists (left by an earlier recovery?); move it '
                           'away first')
    return path, mcaps, missing


def _rewrite(sources: list, out: Path) -> Recovery:
    """Every message of the complete records of `sources` (the .mcap files of a crashed
    recording, in order) into a new bag at `out`, through BagWriter (summary, indexes,
    metadata.yaml, the rosbag2 record); one output file per source file with messages, of the
    source's name."""
    result = Recovery(path=out, damaged=[], size=sum(f.stat().st_size for f in sources))
    split = len(sources) > 1 or _file_index(sources[0])[0] == 1     # <dir>_<i>.mcap names
    state = _Rebuild(out, split)
    try:
        for source in sources:
            _rewrite_file(source, state, result)
    finally:
        writer = state.writer
        if writer is not None:
            writer.set_custom_data('recovered_by', 'pam-bag-recover')
            writer.close()
    result.counts = {t: n for t, n in (writer.counts() if writer else {}).items() if n}
    if not result.counts:
        names = ', '.join(str(f) for f in sources)
        what = '; '.join([f'{result.size} bytes', *first_problems(result.problems)])
        raise BagError(f'{names}: no complete message to recover ({what})')
    return result


@dataclass
class _Rebuild:
    """The bag recover_bag() is writing: made at the first usable channel record, with the
    compression of the chunks seen so far."""

    out: Path
    split: bool
    compression: str = 'zstd'
    writer: BagWriter | None = None

    def bag(self, file_name: str) -> BagWriter:
        """The bag, made now if need be, its first file named `file_name`."""
        if self.writer is None:
            self.writer = BagWriter(self.out, compression=self.compression, split=self.split,
                                    file_name=file_name)
        return self.writer


def _rewrite_file(source: Path, state: _Rebuild, result: Recovery) -> None:
    """The messages of one crashed .mcap into the bag being rebuilt, into an output file of
    the source's name: a new one if the bag's holds messages already, else that one
    renamed."""
    from rosbags.rosbag2.metadata import parse_qos
    from rosbags.typesys import get_types_from_msg

    from .mcap_records import Channel, Message, Schema

    size = source.stat().st_size
    writer = state.writer
    if writer is not None and writer.file_has_messages():
        writer.next_file(source.name)
    elif writer is not None:
        writer.rename_file(source.name)
    schemas, topics, lost = {}, {}, collections.Counter()   # lost: channel id -> messages
    with source.open('rb') as f:
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise BagError(f'{source}: not an MCAP file (bad magic)')
        end = len(MCAP_MAGIC)
        for offset, opcode, body in records(f, size):
            end = offset + RECORD_HEAD.size + len(body)
            if opcode in (FOOTER, DATA_END):   # the summary follows
                end = size
                break
            try:
                kind, parsed = _parse_records(opcode, body)
            except Exception as exc:  # noqa: BLE001 - any damage: drop this record
                result.dropped_bytes += end - offset
                result.problems.append(f'{source.name} offset {offset}: unreadable record '
                                       f'(opcode {opcode:#04x}, {end - offset} bytes): {exc}')
                continue
            if kind is not None:
                state.compression = 'zstd' if kind else 'none'
            for record in parsed:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel) and record.schema_id in schemas:
                    schema = schemas[record.schema_id]
                    writer = state.bag(source.name)
                    try:
                        if not known_type(writer.typestore, schema.name):
                            writer.typestore.register(get_types_from_msg(
                                schema.data.decode(), schema.name))
                        if record.topic not in writer.topics:   # as recorded, not as now
                            rihs01 = channel_hash(record, schema)
                            writer.add_topic(record.topic, schema.name, parse_qos(
                                record.metadata.get('offered_qos_profiles', '')),
                                (schema.data.decode(), rihs01) if rihs01 else None)
                        topics[record.id] = record.topic
                    except Exception as exc:  # noqa: BLE001 - its messages count as lost
                        result.problems.append(f'topic {record.topic}: {exc}')
                elif isinstance(record, Message) and record.channel_id not in topics:
                    lost[record.channel_id] += 1
                elif isinstance(record, Message):
                    writer.write(topics[record.channel_id], record.log_time, record.data)
                    result.start_ns = min(result.start_ns or record.log_time, record.log_time)
                    result.end_ns = max(result.end_ns, record.log_time)
    if end < size:
        result.dropped_bytes += size - end
        result.problems.append(f'{source.name} offset {end}: the last {size - end} bytes are '
                               'not a complete record (cut off by the crash)')
    if lost:
        result.problems.append(f'{source.name}: {sum(lost.values())} messages on channel(s) '
                               f'{", ".join(map(str, sorted(lost)))} dropped: no usable '
                               'channel record')


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def recover_bag(path) -> Recovery:
    """Make the bag directory a crashed recorder left (an .mcap without summary, or a split
    bag's complete files and the last one without summary; no metadata.yaml), or a complete
    bag with a damaged chunk or a missing file, a complete bag again:
    every message of their complete records is rewritten into new files of the same names
    (one per original that holds a message) + metadata.yaml; the original files (and
    metadata.yaml) are kept beside them as `<name>.damaged`. The files the bag listed that are
    missing are in Recovery.missing, with their message counts. BagError (nothing changed) if
    the directory needs no recovery or holds no complete message."""
    bag, sources, missing = _find_damaged(path)
    tmp = bag / RECOVER_TMP
    shutil.rmtree(tmp, ignore_errors=True)     # left by an interrupted recovery
    tmp.mkdir()
    try:
        result = _rewrite(sources, tmp / bag.name)
        new_files = sorted((tmp / bag.name).iterdir(), key=lambda p: p.name == METADATA)
        for new in new_files:
            _fsync(new)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    for original in (*sources, bag / METADATA):   # the recovered data is on disk: swap
        if original.exists():
            result.damaged.append(original.rename(original.with_name(original.name + DAMAGED)))
    for new in new_files:                         # metadata.yaml last: it marks the bag complete
        new.rename(bag / new.name)
    shutil.rmtree(tmp)
    _fsync(bag)
    result.path = bag
    result.missing = missing
    return result
