"""MCAP files read record by record, with every check a reader can make (no rclpy; chunks are
decompressed with rosbags' decompressors).

records() walks a file's (or a chunk's) records; chunk_records() unpacks a Chunk record and
checks it: its data decompress to its uncompressed_size, give its uncompressed_crc and are
complete records; check_file() reads a file's data section so and checks its CRC (the DataEnd
record's: every byte from the file's start to the DataEnd record); summary_problem() checks the
footer and the summary CRC (the Footer's: from the summary's start to the Footer's summary_crc
field); the CRCs as the MCAP specification defines them. A CRC of 0 means "not computed" (bags
written before pam_driver wrote CRCs): it is not checked.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

MCAP_MAGIC = b'\x89MCAP0\r\n'
RECORD_HEAD = struct.Struct('<BQ')      # MCAP record: opcode, body length
CHUNK, DATA_END, FOOTER = 0x06, 0x0F, 0x02
_FOOTER = struct.Struct('<BQQQI')       # opcode, length, summary_start, summary_offset_start, CRC
_CHUNK_HEAD = struct.Struct('<QQQI')    # message_start_time, message_end_time, size, CRC


def records(stream, size: int):
    """(offset, opcode, body) of each complete MCAP record from the stream's position on; stops
    before a record that is cut off (extends past `size`) or whose opcode is invalid."""
    pos = stream.tell()
    while pos + RECORD_HEAD.size <= size:
        opcode, length = RECORD_HEAD.unpack(stream.read(RECORD_HEAD.size))
        if not (0 < opcode < 0x10 or opcode >= 0x80) or pos + RECORD_HEAD.size + length > size:
            return
        yield pos, opcode, stream.read(length)
        pos += RECORD_HEAD.size + length


def chunk_records(body: bytes) -> tuple[str, list]:
    """(compression, (offset, opcode, body) of each record inside) of a Chunk record's body;
    ValueError if its data do not decompress to its uncompressed_size, do not give its
    uncompressed_crc (0: not computed, not checked) or are not complete records."""
    from io import BytesIO
    compression, uncompressed_size, uncompressed_crc, compressed = _chunk_fields(body)
    data = decompress(compressed, compression, uncompressed_size)
    size = len(data)
    if size != uncompressed_size:
        raise ValueError(f'{size} bytes uncompressed, the chunk says {uncompressed_size}')
    crc = zlib.crc32(data)
    if uncompressed_crc and crc != uncompressed_crc:
        raise ValueError(f'CRC mismatch: its records give {crc:#010x}, the chunk says '
                         f'{uncompressed_crc:#010x}')
    inner = list(records(BytesIO(data), size))
    end = inner[-1][0] + RECORD_HEAD.size + len(inner[-1][2]) if inner else 0
    if end != size:
        raise ValueError(f'invalid record at byte {end} of the uncompressed chunk')
    return compression, inner


def _chunk_fields(body: bytes) -> tuple[str, int, int, bytes]:
    """(compression, uncompressed_size, uncompressed_crc, compressed records) of a Chunk
    record's body; ValueError if it is too short for them."""
    if len(body) < _CHUNK_HEAD.size + 4:
        raise ValueError(f'chunk record of {len(body)} bytes: too short')
    _, _, uncompressed_size, uncompressed_crc = _CHUNK_HEAD.unpack_from(body)
    pos = _CHUNK_HEAD.size
    (length,) = struct.unpack_from('<I', body, pos)
    compression = body[pos + 4:pos + 4 + length].decode()
    pos += 4 + length
    if pos + 8 > len(body):
        raise ValueError(f'chunk record of {len(body)} bytes: too short')
    (records_size,) = struct.unpack_from('<Q', body, pos)
    if pos + 8 + records_size > len(body):
        raise ValueError(f'chunk records of {records_size} bytes past the record\'s end')
    return compression, uncompressed_size, uncompressed_crc, body[pos + 8:pos + 8 + records_size]


def decompress(data: bytes, compression: str, uncompressed_size: int) -> bytes:
    """A chunk's records, decompressed ('', 'zstd' or 'lz4': the decompressors of rosbags'
    MCAP reader); ValueError for another compression."""
    from rosbags.rosbag2.storage_mcap import DECOMPRESSORS
    if compression not in DECOMPRESSORS:
        raise ValueError(f'unsupported chunk compression {compression!r}')
    return DECOMPRESSORS[compression](data, uncompressed_size)


def summary_problem(f, size: int) -> str:
    """'' if the open MCAP file `f` (`size` bytes) ends with a Footer whose summary_crc is 0
    or matches its summary, else what is wrong."""
    if size < len(MCAP_MAGIC) + _FOOTER.size + len(MCAP_MAGIC):
        return 'no footer'
    f.seek(size - len(MCAP_MAGIC) - _FOOTER.size)
    opcode, length, start, _, crc = _FOOTER.unpack(f.read(_FOOTER.size))
    if opcode != FOOTER or length != _FOOTER.size - RECORD_HEAD.size:
        return 'no footer'
    if not crc:
        return ''
    end = size - len(MCAP_MAGIC) - 4
    if not len(MCAP_MAGIC) <= start <= end:
        return f'summary start {start} outside the file'
    f.seek(start)
    got = zlib.crc32(f.read(end - start))
    return '' if got == crc else (f'summary CRC mismatch: the summary gives {got:#010x}, the '
                                  f'footer says {crc:#010x}')


@dataclass
class FileCheck:
    """What check_file() found in one MCAP file."""

    path: Path
    chunks: int = 0             # Chunk records read
    chunks_with_crc: int = 0    # of them with an uncompressed_crc (the others: not checkable)
    data_crc: bool = False      # the DataEnd record has a data_section_crc (checked)
    problems: list = field(default_factory=list)    # one line each, naming the file and place


def _chunk_place(index: int, offset: int, body: bytes, start_ns: int | None) -> str:
    """'chunk <index> at byte <offset>' and, if its header is readable and start_ns given, its
    messages' times into the bag."""
    place = f'chunk {index} at byte {offset}'
    if start_ns is not None and len(body) >= _CHUNK_HEAD.size:
        first, last, _, _ = _CHUNK_HEAD.unpack_from(body)
        if start_ns <= first <= last:
            place += f' (messages {(first - start_ns) * 1e-9:.3f} s to ' \
                     f'{(last - start_ns) * 1e-9:.3f} s into the bag)'
    return place


def check_file(path, start_ns: int | None = None, first_only: bool = False) -> FileCheck:
    """Read the data section of the MCAP file `path` through: every chunk (chunk_records) and
    the data section CRC (the footer and summary: summary_problem). Each problem is a line
    naming the file (and the chunk: its index, byte offset and, with the bag's start time
    `start_ns`, its messages' times); `first_only`: stop at the first."""
    path = Path(path)
    result = FileCheck(path)
    problems = result.problems
    size = path.stat().st_size
    with path.open('rb') as f:
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            problems.append(f'{path.name}: not an MCAP file (bad magic)')
            return result
        crc = zlib.crc32(MCAP_MAGIC)
        end = len(MCAP_MAGIC)
        for offset, opcode, body in records(f, size):
            end = offset + RECORD_HEAD.size + len(body)
            if opcode == DATA_END:
                stored = int.from_bytes(body[:4], 'little')
                result.data_crc = bool(stored)
                if stored and stored != crc:
                    where = ('the damaged chunk(s) above' if problems else
                             'a damaged record outside the chunks')
                    problems.append(f'{path.name}: data section CRC mismatch: its bytes give '
                                    f'{crc:#010x}, the DataEnd record says {stored:#010x} '
                                    f'({where})')
                break
            crc = zlib.crc32(body, zlib.crc32(RECORD_HEAD.pack(opcode, len(body)), crc))
            if opcode == CHUNK:
                result.chunks_with_crc += body[24:28] != b'\0\0\0\0'
                try:
                    chunk_records(body)
                except Exception as exc:  # noqa: BLE001 - any damage: name the chunk
                    problems.append(f'{path.name}: '
                                    f'{_chunk_place(result.chunks, offset, body, start_ns)} '
                                    f'is damaged: {exc}')
                result.chunks += 1
                if first_only and problems:
                    return result
        else:
            problems.append(f'{path.name}: no DataEnd record (the records end at byte {end} of '
                            f'{size}: cut off or damaged there)')
    return result
