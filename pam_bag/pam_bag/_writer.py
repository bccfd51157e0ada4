"""BagWriter (rosbag2_cpp's Writer): a Jazzy MCAP bag written topic by topic, message by message,
optionally split into several files by size or duration, through the MCAP storage writer
(_mcap_storage).

Imported through pam_bag.bags, the library's public face."""

from __future__ import annotations

import functools
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path

from ._storage import (
    DEFAULT_CHUNK_INTERVAL,
    METADATA,
    BagError,
    BagFile,
    BagWriteError,
    bag_metadata,
    yaml_text,
)
from ._types import known_type, make_typestore

MIN_SPLIT_SIZE = 100_000      # B: smallest max_bag_size (a file of a split bag)
MIN_SPLIT_DURATION = 1.0      # s: smallest max_bag_duration
#: custom_data 'recorder' of every bag written here (metadata.yaml and the rosbag2 record)
RECORDER = 'pam_bag bag_record'


@dataclass
class _Topic:
    name: str
    msgtype: str
    connection: object
    count: int = 0


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
        self._current_file = self.file_name or self._file_name(0)
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        # rosbags' Writer makes its storage writer from this table: ours, of this bag's files
        self._writer.STORAGE_PLUGINS = {StoragePlugin.MCAP: self._open_file}
        if self.compression == 'zstd':
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        elif self.compression != 'none':
            raise BagError(f"unknown compression {self.compression!r}: use 'zstd' or 'none'")
        try:
            self._writer.open()
        except Exception as exc:
            raise BagError(f'{self.path}: cannot create the bag: {exc}') from exc
        self.set_custom_data('recorder', RECORDER)
        self.closed = False
        self.error: BaseException | None = None
        self.files: list[BagFile] = []      # the files closed so far

    def _file_name(self, index: int) -> str:
        return f'{self.path.name}_{index}.mcap' if self.split else f'{self.path.name}.mcap'

    def _open_file(self, path: Path, compression):
        """The MCAP storage writer of the next file of the bag (named self._current_file)."""
        from ._mcap_storage import McapStorage  # imports rosbags: only once writing
        return McapStorage(path, compression, self.chunk_interval, self._current_file)

    @property
    def mcap_path(self) -> Path:
        """The file being written."""
        return self.path / self._current_file

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
        storage.file_name = self._current_file = name

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
        self._current_file = name or self._file_name(len(self.files))
        try:
            new = self._open_file(self.path, self._writer.compression_mode)
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
        info = bag_metadata(self._writer, self.files)
        try:
            storage.close(self._writer.version, yaml_text(info).strip())
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
            tmp.write_text(yaml_text({'rosbag2_bagfile_information':
                                      bag_metadata(self._writer, self.files)}))
            tmp.replace(meta)
        except OSError as exc:
            raise BagWriteError(f'{self.path}: cannot finish the bag: {exc}') from exc

    @_locked
    def counts(self) -> dict[str, int]:
        return {t: e.count for t, e in self.topics.items()}
