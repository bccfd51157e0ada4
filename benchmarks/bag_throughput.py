"""bag_record at 4 topics x 1 kHz: published vs recorded counts; bag_play send lateness.

Run after `source scripts/env.sh`:  .venv/bin/python benchmarks/bag_throughput.py [--seconds 20]
[--play BAG]
A publisher thread in this process sends Pressures, ValveCommand, JointMeasurement and
JointEstimate at 1 kHz each (absolute deadlines; Pressures and JointEstimate numbered by their
sample counter) while bag_record runs as a separate process on an isolated ROS_DOMAIN_ID, and
the gaps in the recorded counters are printed; then bag_play replays the bag twice and prints its
send lateness:
with the default read-ahead queue (reading while playing) and with the whole bag read ahead,
and its peak memory. `--play BAG` replays another bag (e.g. a 130 s reference bag).
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault('ROS_DOMAIN_ID', str(os.getpid() % 100 + 120))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy

from pam_bag.bags import bag_info, load_bag, make_typestore
from pam_common.sample_gaps import SampleGaps, loss_summary
from pam_common.stamps import ns_stamp
from pam_interfaces.msg import JointEstimate, JointMeasurement, Pressures, ValveCommand


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument('--seconds', type=float, default=20.0)
    parser.add_argument('--play', metavar='BAG', help='replay this bag instead of the recorded '
                        'one (e.g. bags/validation_mild_free)')
    args = parser.parse_args()
    out = Path(tempfile.mkdtemp()) / 'bench'
    rec = subprocess.Popen(['bag_record', '--ros-args', '-p', f'output:={out}'],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    rclpy.init()
    node = rclpy.create_node('bag_bench_publisher')
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    types = {'pressures': Pressures, 'valve_command': ValveCommand,
             'joint_measured': JointMeasurement, 'estimate': JointEstimate}
    pubs = [node.create_publisher(cls, f'/pam/{name}', qos) for name, cls in types.items()]
    msgs = [cls() for cls in types.values()]
    time.sleep(4.0)   # let bag_record discover the topics
    published = 0
    t0 = time.monotonic()
    k = 0
    while time.monotonic() - t0 < args.seconds:
        k += 1
        due = t0 + k * 1e-3
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        for pub, msg in zip(pubs, msgs, strict=True):
            msg.header.stamp = ns_stamp(k * 1_000_000)
            if hasattr(msg, 'sample'):
                msg.sample = k
            pub.publish(msg)
            published += 1
    time.sleep(1.0)
    rec.send_signal(signal.SIGINT)
    rec.wait(timeout=30)
    info = bag_info(out)
    recorded = sum(t['count'] for t in info['topics'] if t['name'] != '/diagnostics')
    print(f'published {published} messages on 4 topics in {args.seconds:g} s; recorded '
          f'{recorded} (lost {published - recorded}); bag {info["size"] / 2**20:.1f} MiB '
          f'({info["compression"]})')
    for topic, line in recorded_gaps(out).items():
        print(f'  recorded {topic}: {line}')
    node.destroy_node()
    rclpy.shutdown()
    # the default read-ahead (reading while playing) vs one that holds the whole bag (read in
    # the first second, as a preload would)
    bag = Path(args.play) if args.play else out
    for label, size in (('read-ahead 10000 messages', 10000), ('whole bag read ahead', 10**7)):
        play = subprocess.Popen(['bag_play', '--ros-args', '-p', f'bag:={bag}', '-p',
                                 'delay:=0.5', '-p', f'read_ahead_size:={size}'],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        peak = peak_rss_kib(play)
        stdout, stderr = play.communicate(timeout=30)
        last = stdout.strip().splitlines()[-1] if stdout.strip() else stderr
        print(f'{label}: {last}; peak RSS {peak / 1024:.0f} MiB')
    return 0


def recorded_gaps(bag) -> dict:
    """topic -> the loss its sample counter shows, for the recorded topics that have one."""
    contents, store = load_bag(bag), make_typestore()
    gaps = {name: SampleGaps() for name in contents.topic_names
            if contents.topics[name].endswith(('/Pressures', '/JointEstimate'))}
    for name, found in gaps.items():
        for _, msg in contents.deserialized(name, store):
            found.update(msg.sample)
    return {name: loss_summary(g.values()) for name, g in sorted(gaps.items())}


def peak_rss_kib(proc) -> int:
    """The process's peak resident memory (VmHWM, KiB), last read before it exits."""
    peak = 0
    while proc.poll() is None:
        try:
            for line in Path(f'/proc/{proc.pid}/status').read_text().splitlines():
                if line.startswith('VmHWM:'):
                    peak = int(line.split()[1])
        except OSError:
            break
        time.sleep(0.2)
    return peak


if __name__ == '__main__':
    sys.exit(main())
