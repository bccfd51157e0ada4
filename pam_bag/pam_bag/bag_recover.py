"""pam-bag-recover: makes the bag directory a crashed recorder left (SIGKILL, power loss: an
.mcap without summary, no metadata.yaml), or a complete bag with a damaged chunk (bag_play
stops at it) or a missing file, a complete bag again (pam_bag.bags.recover_bag).

Every message of the complete records is rewritten into new .mcap files of the original names
(one per original) and metadata.yaml; the original files are kept beside them as
`<name>.damaged`. Prints what was recovered. Exit code 2 with one error line if the directory
needs no recovery or holds nothing to recover (nothing changed), or if files the bag listed
are missing (the error names them and the messages lost; the rest was recovered).
"""

from __future__ import annotations

import argparse
import datetime
import sys

from pam_bag.bags import EXIT_BAD_INPUT, BagError, Recovery, first_problems, recover_bag


def format_missing(missing: list) -> str:
    """'<name> (<n> messages), ...' of the missing files."""
    return ', '.join(f'{name} ({"?" if n is None else n} messages)' for name, n in missing)


def format_recovery(r: Recovery) -> str:
    def utc(ns):
        return datetime.datetime.fromtimestamp(ns * 1e-9, tz=datetime.timezone.utc)
    width = max(len(t) for t in r.counts)
    lines = [f'recovered {r.path} ({", ".join(p.name for p in r.damaged)} kept)',
             f'  messages: {sum(r.counts.values())}, per topic:',
             *(f'    {t:<{width}}  {n}' for t, n in sorted(r.counts.items())),
             f'  span:     {(r.end_ns - r.start_ns) * 1e-9:.3f} s, '
             f'{utc(r.start_ns):%Y-%m-%d %H:%M:%S.%f} to {utc(r.end_ns):%H:%M:%S.%f} (UTC)',
             f'  dropped:  {r.dropped_bytes} of {r.size} bytes of the damaged file(s)',
             *(f'    {p}' for p in first_problems(r.problems, 10))]
    if r.missing:
        lines.append(f'  missing:  {format_missing(r.missing)}: listed in the bag, not there')
    return '\n'.join(lines) + '\n'


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog='pam-bag-recover', description='Repairs a bag directory left by a crashed '
        'recorder (an .mcap with no summary, no metadata.yaml; or a split bag whose last file '
        'has no summary; or a complete bag with a damaged chunk): keeps every complete, '
        'readable chunk, writes new .mcap files (same names) with their summaries and '
        'metadata.yaml, and keeps the originals as <name>.damaged. '
        'Messages the recorder still held in memory (at most the last chunk_interval, 1 s) '
        'were never on disk and cannot be recovered. Files metadata.yaml lists that are '
        'missing are named with the messages lost (exit 2; the rest is recovered).')
    parser.add_argument('bag', help='bag directory (or its .mcap file)')
    args = parser.parse_args(argv)
    try:
        result = recover_bag(args.bag)
    except BagError as exc:
        print(f'pam-bag-recover: error: {exc}', file=sys.stderr)
        return EXIT_BAD_INPUT
    sys.stdout.write(format_recovery(result))
    if result.missing:
        known = all(n is not None for _, n in result.missing)
        print(f'pam-bag-recover: error: {result.path}: missing {format_missing(result.missing)}'
              f': {result.lost_messages}{"" if known else "+"} messages lost (the bag was '
              'rebuilt from the other files)', file=sys.stderr)
        return EXIT_BAD_INPUT
    return 0


if __name__ == '__main__':
    sys.exit(main())
