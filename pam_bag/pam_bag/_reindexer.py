"""Recovery of a crashed or damaged bag (rosbag2_cpp's Reindexer, and more): every message of
the complete records of its .mcap files rewritten, through BagWriter, into a complete bag of the
same file names; the originals kept beside it as <name>.damaged.

Imported through pam_bag.bags, the library's public face."""

from __future__ import annotations

import collections
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from ._info import embedded_metadata
from ._reader import open_bag, verify_bag
from ._storage import METADATA, BagError, bag_dir, check_mcap, read_metadata
from ._types import channel_hash, known_type
from ._writer import BagWriter
from .mcap_check import CHUNK, DATA_END, FOOTER, MCAP_MAGIC, RECORD_HEAD, chunk_records, records
from .mcap_records import CHANNEL, MESSAGE, SCHEMA, parse_record

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
