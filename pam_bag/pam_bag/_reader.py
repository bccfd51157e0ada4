"""Reading bags (rosbag2_cpp's Reader): a bag's topics selected and streamed chunk by chunk
(open_bag) or loaded into memory (load_bag), after the checks of its metadata, files and type
definitions; verify_bag reads every chunk of every file with its CRC.

Imported through pam_bag.bags, the library's public face."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pam_common.stamps import stamp_ns

from ._columns import header_columns
from ._storage import BagError, bag_dir, bag_files, check_bag, check_mcap, read_metadata
from ._types import check_definitions
from .mcap_check import FileCheck, check_file


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

    def columns(self, topic: str, store, fields) -> dict:
        """{'stamp_ns': int64 (N,) header stamps, field: float64 (N,) for each of `fields`} of
        `topic`'s messages (a type with a std_msgs/Header), in receive order (none: empty
        columns). Decoded all at once when the layout allows it (_columns.header_columns), else
        message by message (deserialized, BagError as there)."""
        if topic not in self.topics:
            return {'stamp_ns': np.zeros(0, np.int64), **{f: np.zeros(0) for f in fields}}
        index = self.topic_names.index(topic)
        datas = [d for i, d in zip(self.topic_index, self.data, strict=True) if i == index]
        fast = header_columns(datas, store, self.topics[topic])
        if fast is not None:
            return {'stamp_ns': fast['stamp_ns'],
                    **{f: fast[f].astype(float) for f in fields}}
        messages = [msg for _, msg in self.deserialized(topic, store)]
        return {'stamp_ns': np.array([stamp_ns(m.header.stamp) for m in messages], np.int64),
                **{f: np.array([getattr(m, f) for m in messages], float) for f in fields}}


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
