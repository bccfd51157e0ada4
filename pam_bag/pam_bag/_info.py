"""What a bag holds (rosbag2_cpp's Info, `ros2 bag info`): topics, types, counts, rates, duration
and compression, from its metadata and the MCAP summaries; the metadata each .mcap file embeds.

Imported through pam_bag.bags, the library's public face."""

from __future__ import annotations

import os
from pathlib import Path

from ._storage import check_bag, read_metadata
from .mcap_records import file_summary, metadata_records


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
