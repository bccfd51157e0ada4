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

The library's public face: its layers are modules of their own, as rosbag2's packages are, and
everything is imported from here (`from pam_bag.bags import BagWriter, load_bag`):

    _storage       the errors, the bag directory, metadata.yaml, an .mcap file's checks
                   (rosbag2_storage)
    _types         the typestore and the RIHS01 hashes, installed and recorded
    _qos           offered QoS profiles (metadata.yaml's form)
    _mcap_storage  the MCAP storage writer (rosbag2_storage_mcap); it imports rosbags
    _writer        BagWriter (rosbag2_cpp's Writer)
    _reader        open_bag, load_bag, verify_bag (rosbag2_cpp's Reader)
    _info          bag_info, format_info (rosbag2_cpp's Info)
    _reindexer     recover_bag (rosbag2_cpp's Reindexer)
"""

from ._info import bag_info, embedded_metadata, format_info
from ._qos import make_qos, qos_from_ints
from ._reader import BagContents, BagSelection, load_bag, open_bag, verify_bag
from ._reindexer import DAMAGED, RECOVER_TMP, Recovery, first_problems, recover_bag
from ._storage import (
    DEFAULT_CHUNK_INTERVAL,
    EXIT_BAD_INPUT,
    METADATA,
    ROS_DISTRO,
    BagError,
    BagWriteError,
    bag_dir,
    bag_files,
    check_bag,
    check_mcap,
    read_metadata,
)
from ._types import (
    channel_hash,
    check_definitions,
    definition_hash,
    interface_dirs,
    known_type,
    make_typestore,
    recorded_types,
)
from ._writer import MIN_SPLIT_DURATION, MIN_SPLIT_SIZE, RECORDER, BagWriter, check_split
from .mcap_check import FileCheck

__all__ = [
    'DAMAGED',
    'DEFAULT_CHUNK_INTERVAL',
    'EXIT_BAD_INPUT',
    'METADATA',
    'MIN_SPLIT_DURATION',
    'MIN_SPLIT_SIZE',
    'RECORDER',
    'RECOVER_TMP',
    'ROS_DISTRO',
    'BagContents',
    'BagError',
    'BagSelection',
    'BagWriteError',
    'BagWriter',
    'FileCheck',
    'Recovery',
    'bag_dir',
    'bag_files',
    'bag_info',
    'channel_hash',
    'check_bag',
    'check_definitions',
    'check_mcap',
    'check_split',
    'definition_hash',
    'embedded_metadata',
    'first_problems',
    'format_info',
    'interface_dirs',
    'known_type',
    'load_bag',
    'make_qos',
    'make_typestore',
    'open_bag',
    'qos_from_ints',
    'read_metadata',
    'recorded_types',
    'recover_bag',
    'verify_bag',
]
