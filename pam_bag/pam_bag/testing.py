"""Test support for bags (imported by tests only, never by production code): a chunk damaged
the way the CRCs catch, and a bag recorded before Pressures had its sample counter."""

from __future__ import annotations

import tempfile
from pathlib import Path

from pam_common.stamps import ns_pair


def damage_chunk(mcap, index: int, nbytes: int = 8) -> int:
    """Flip `nbytes` bytes (in place) inside the compressed records of chunk `index` of the
    MCAP file `mcap`, at the first place from the chunk's middle on where, without a CRC, the
    damage goes unnoticed (the issue's corrupted bag): the chunk still decompresses to its
    uncompressed_size and into complete records, only other ones. Returns the file offset of
    the first flipped byte."""
    import io

    from pam_bag.mcap_check import RECORD_HEAD, decompress, records
    from pam_bag.mcap_records import file_summary
    mcap = Path(mcap)
    chunk = file_summary(mcap).chunk_indexes[index]
    data = bytearray(mcap.read_bytes())
    end = chunk.chunk_start_offset + chunk.chunk_length
    start = end - chunk.compressed_size

    def unpack(compressed: bytes) -> bytes | None:
        try:
            out = decompress(compressed, chunk.compression, chunk.uncompressed_size)
        except Exception:  # noqa: BLE001 - the decompressor noticed the damage
            return None
        inner = list(records(io.BytesIO(out), len(out)))
        framed = inner and inner[-1][0] + RECORD_HEAD.size + len(inner[-1][2]) == len(out)
        return out if len(out) == chunk.uncompressed_size and framed else None
    original = unpack(bytes(data[start:end]))
    for at in range(start + chunk.compressed_size // 2, end - nbytes):
        trial = bytearray(data[start:end])
        for i in range(at - start, at - start + nbytes):
            trial[i] ^= 0xFF
        damaged = unpack(bytes(trial))
        if damaged is not None and damaged != original:
            data[start:end] = trial
            mcap.write_bytes(data)
            return at
    raise AssertionError(f'{mcap}: no place in chunk {index} to damage unnoticed by zstd')


#: pam_interfaces/msg/Pressures before its sample counter (`uint64 sample`) was appended: the
#: definition the bags recorded before hold; its RIHS01 hash is theirs (their channels'
#: topic_type_hash, e.g. bags/closed_mild_angle as of commit 26ad2a9).
PRESSURES_BEFORE_SAMPLE = 'std_msgs/Header header\n\nfloat64 p1\nfloat64 p2\n'
PRESSURES_BEFORE_SAMPLE_RIHS01 = (
    'RIHS01_18016bc73ee25333229b2e5f0fe1772a9ba3a145c1edc48cea637e4ebc556b53')


def write_bag_before_sample(path, samples: int = 100, labelled_as_now: bool = False) -> Path:
    """A bag as recorded before Pressures had its sample counter: `samples` samples at 1 kHz of
    /pam/pressures (the old definition, embedded and hashed in its channel),
    /pam/joint_measured and /pam/valve_command (today's definitions, unchanged since).
    `labelled_as_now`: the channels claim today's definitions (what pam-bag-recover made of such
    a bag before it kept the recorded ones), the Pressures messages are still the old ones."""
    from pam_bag.bags import BagWriter, make_typestore
    with tempfile.TemporaryDirectory() as folder:
        old = Path(folder) / 'Pressures.msg'
        old.write_text(PRESSURES_BEFORE_SAMPLE)
        store = make_typestore([('pam_interfaces/msg/Pressures', old)])
    types = {'/pam/pressures': 'pam_interfaces/msg/Pressures',
             '/pam/joint_measured': 'pam_interfaces/msg/JointMeasurement',
             '/pam/valve_command': 'pam_interfaces/msg/ValveCommand'}
    writer = BagWriter(Path(path), typestore=make_typestore() if labelled_as_now else store)
    for topic, msgtype in types.items():
        writer.add_topic(topic, msgtype)
    fields = {'/pam/pressures': dict(p1=4.5e5, p2=4.5e5),
              '/pam/joint_measured': dict(angle=0.0, angular_velocity=0.0, torque=0.0),
              '/pam/valve_command': dict(u1=5.5, u2=5.5)}
    Header, Time = store.types['std_msgs/msg/Header'], store.types['builtin_interfaces/msg/Time']
    try:
        for k in range(samples):
            t_ns = 1_700_000_000_000_000_000 + k * 1_000_000
            sec, nanosec = ns_pair(t_ns)
            header = Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id='pam_joint')
            for topic, msgtype in types.items():
                msg = store.types[msgtype](header=header, **fields[topic])
                writer.write(topic, t_ns, store.serialize_cdr(msg, msgtype))
    finally:
        writer.close()
    return Path(path)
