"""pam-bag-info: what `ros2 bag info` prints for a Jazzy MCAP bag (topics, types, counts,
duration, rates, compression). Exit code 1 with one error line for a bad bag."""

from __future__ import annotations

import argparse
import sys

from pam_driver.bags import BagError, bag_info, format_info


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog='pam-bag-info', description='Summary of a rosbag2 MCAP bag directory (like '
        '`ros2 bag info`): files, size, duration, message counts and rates per topic.')
    parser.add_argument('bag', help='bag directory (with metadata.yaml)')
    args = parser.parse_args(argv)
    try:
        sys.stdout.write(format_info(bag_info(args.bag)))
    except BagError as exc:
        print(f'pam-bag-info: error: {exc}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
