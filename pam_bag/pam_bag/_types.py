"""Message types of the bags (a rosbags typestore: Jazzy's types and pam_interfaces') and their
RIHS01 hashes: as installed, as a bag's channels record them, and the check that a bag's topics
were recorded with the installed definitions.

Imported through pam_bag.bags, the library's public face."""

from __future__ import annotations

import os
from pathlib import Path

from ._storage import BagError
from .mcap_records import file_summary


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
