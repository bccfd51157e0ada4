"""pam-bag-info: what `ros2 bag info` prints for a Jazzy MCAP bag (topics, types, counts,
duration, rates, compression), after reading every chunk of it through (chunk CRCs, data
section CRCs: bags.verify_bag). A bad or damaged bag: one error line naming the first problem,
exit code 2. --verify also prints what was checked and lists every problem."""

from __future__ import annotations

import argparse
import sys

from pam_bag.bags import EXIT_BAD_INPUT, BagError, bag_info, format_info, verify_bag


def format_verification(checks: list) -> str:
    """The line --verify adds to the info: files, chunks, the CRCs there were to check."""
    chunks = sum(c.chunks for c in checks)
    with_crc = sum(c.chunks_with_crc for c in checks)
    data_crc = sum(c.data_crc for c in checks)
    line = (f'Verified:          {len(checks)} files, {chunks} chunks read; chunk CRCs: '
            f'{with_crc} of {chunks}, data section CRCs: {data_crc} of {len(checks)} files')
    if with_crc < chunks:
        line += ('\n                   (no CRC: written before pam_driver wrote them; damage '
                 'that still decompresses cannot be found there)')
    return line + '\n'


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog='pam-bag-info', description='Summary of a rosbag2 MCAP bag directory (like '
        '`ros2 bag info`): files, size, duration, message counts and rates per topic. Every '
        'chunk is read and its CRC checked first; a damaged bag is an error (exit 2).')
    parser.add_argument('bag', help='bag directory (with metadata.yaml)')
    parser.add_argument('--verify', action='store_true',
                        help='also print what was checked (chunks, CRCs) and name every '
                             'damaged chunk and file, not only the first')
    args = parser.parse_args(argv)
    try:
        return verify(args.bag) if args.verify else info(args.bag)
    except BagError as exc:
        print(f'pam-bag-info: error: {exc}', file=sys.stderr)
        return EXIT_BAD_INPUT


def info(bag: str) -> int:
    """Print the info of a bag read through without a problem; BagError naming the first."""
    problems = [p for check in verify_bag(bag, first_only=True) for p in check.problems]
    if problems:
        raise BagError(f'{bag}: {problems[0]} (`pam-bag-info --verify {bag}` names every '
                       f'damaged part; `pam-bag-recover {bag}` rebuilds the bag without them)')
    sys.stdout.write(format_info(bag_info(bag)))
    return 0


def verify(bag: str) -> int:
    """Print the info (if the summaries are intact) and what was checked; every problem to
    stderr (exit code 2)."""
    checks = verify_bag(bag)
    problems = [p for check in checks for p in check.problems]
    try:
        text = format_info(bag_info(bag))
    except BagError:
        if not problems:
            raise
        text = ''      # a damaged summary or a missing file: the problems say which
    sys.stdout.write(text + format_verification(checks))
    if not problems:
        return 0
    print(f'pam-bag-info: error: {bag}: {len(problems)} problem(s) found (`pam-bag-recover '
          f'{bag}` rebuilds the bag without the damaged parts):\n' +
          '\n'.join(f'  {p}' for p in problems), file=sys.stderr)
    return EXIT_BAD_INPUT


if __name__ == '__main__':
    sys.exit(main())
