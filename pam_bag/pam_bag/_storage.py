"""The bag on disk (rosbag2_storage's part): the errors, the bag directory and its files,
metadata.yaml (version 9) written and read, and the checks of an .mcap file's ends and summary.

Imported through pam_bag.bags, the library's public face."""

from __future__ import annotations

import collections
from dataclasses import dataclass, field
from pathlib import Path

from .mcap_check import MCAP_MAGIC, summary_problem
from .mcap_records import read_summary

METADATA = 'metadata.yaml'
DEFAULT_CHUNK_INTERVAL = 1.0   # s: longest time a received message stays only in memory
ROS_DISTRO = 'jazzy'   # the bags' ros_distro (rosbag2 writes $ROS_DISTRO; rosbags 'rosbags')
EXIT_BAD_INPUT = 2   # exit code of every tool for bad input: a missing, bad or damaged bag
#                      (docs/stopping.md, Exit codes)


class BagError(RuntimeError):
    """A bag cannot be written or read; the message names the file and the problem."""


class BagWriteError(BagError):
    """Writing failed; the bag was closed with what had been written before the error."""


@dataclass
class BagFile:
    """One .mcap file of a bag: its name, first and last message time (ns) and message counts
    per channel id."""

    name: str
    start_ns: int = 2**63 - 1
    end_ns: int = 0
    counts: dict = field(default_factory=dict)

    @property
    def count(self) -> int:
        return sum(self.counts.values())


def bag_metadata(writer, files: list) -> dict:
    """The rosbag2_bagfile_information (version 9) of a bag made of `files` (BagFile)."""
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


def yaml_text(data) -> str:
    from io import StringIO

    from ruamel.yaml import YAML
    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    out = StringIO()
    yaml.dump(data, out)
    return out.getvalue()


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


def bag_files(path) -> list[Path]:
    """The .mcap files metadata.yaml lists, in order."""
    return [Path(path) / name for name in read_metadata(path)['relative_file_paths']]
