"""Support of test_two_hosts.py: two network namespaces joined by a veth pair (two "hosts" on one
machine), processes run inside them, and a topic watcher to run in a namespace.

TwoHosts (a context manager; root and `ip netns` needed) makes namespaces `pam2h_a_<pid>` and
`pam2h_b_<pid>`, a veth pair `p2ha<pid>` / `p2hb<pid>` with 10.231.0.1/24 and 10.231.0.2/24 (the
subnet exists only inside the two namespaces, so it cannot clash with the machine's own
networks), `lo` up in both. On exit it kills whatever still runs in them (`ip netns pids`) and
deletes them (the veth pair goes with them), also after a failure or Ctrl-C; namespaces left by
a test process that was killed outright (SIGKILL: no cleanup runs) are removed by the next run
(remove_stale).

Run as a script, inside a namespace, it is the test's probe there (the machine's own namespace has
no route to the two):

    python two_hosts_support.py watch TIMEOUT TOPIC...

prints `received <topic>` at the first message of each topic (pam_common.topics names under /pam,
types from TOPIC_TYPES), `all received` and exits 0 when every topic has arrived, or prints
`timeout` and exits 3 after TIMEOUT s.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time

SUBNET = '10.231.0'          # /24, inside the two namespaces only
ADDRESS = {'a': f'{SUBNET}.1', 'b': f'{SUBNET}.2'}
WATCH_TIMEOUT_CODE = 3


def netns_unavailable() -> str | None:
    """Why the two namespaces cannot be made here, or None."""
    if os.geteuid() != 0:
        return 'not root: network namespaces need root'
    if shutil.which('ip') is None:
        return 'the ip command (iproute2) is not installed'
    probe = subprocess.run(['ip', 'netns', 'list'], capture_output=True, text=True, check=False)
    if probe.returncode != 0:
        return f'`ip netns` is unavailable: {probe.stderr.strip()}'
    return None


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    done = subprocess.run(['ip', *args], capture_output=True, text=True, check=False)
    if check and done.returncode != 0:
        raise RuntimeError(f'ip {" ".join(args)}: {done.stderr.strip()}')
    return done


def remove_stale() -> list[str]:
    """Delete the namespaces (and kill what runs in them) of test processes that no longer exist:
    `pam2h_a_<pid>`, `pam2h_b_<pid>` with no process <pid>. Their names, sorted."""
    removed = []
    for name in _ip('netns', 'list', check=False).stdout.split():
        parts = name.split('_')
        if (len(parts) == 3 and parts[0] == 'pam2h' and parts[2].isdigit()
                and not os.path.exists(f'/proc/{parts[2]}')):
            TwoHosts(parts[2]).close()
            removed.append(name)
    return sorted(removed)


class TwoHosts:
    """Namespaces 'a' and 'b' joined by a veth pair; see the module docstring."""

    def __init__(self, tag: str | None = None):
        tag = tag or str(os.getpid())
        self.names = {'a': f'pam2h_a_{tag}', 'b': f'pam2h_b_{tag}'}
        self.devices = {'a': f'p2ha{tag}'[:15], 'b': f'p2hb{tag}'[:15]}

    def __enter__(self) -> TwoHosts:
        try:
            for side in 'ab':
                _ip('netns', 'add', self.names[side])
            _ip('link', 'add', self.devices['a'], 'type', 'veth', 'peer', 'name',
                self.devices['b'])
            for side in 'ab':
                ns, dev = self.names[side], self.devices[side]
                _ip('link', 'set', dev, 'netns', ns)
                _ip('-n', ns, 'addr', 'add', f'{ADDRESS[side]}/24', 'dev', dev)
                _ip('-n', ns, 'link', 'set', 'lo', 'up')
            self.set_link(True)
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def set_link(self, up: bool) -> None:
        """Both ends of the veth pair up or down (the addresses stay)."""
        for side in 'ab':
            _ip('-n', self.names[side], 'link', 'set', self.devices[side], 'up' if up else 'down')

    def argv(self, side: str, argv: list[str]) -> list[str]:
        """`argv` run inside namespace `side` ('a' or 'b')."""
        return ['ip', 'netns', 'exec', self.names[side], *argv]

    def link_bytes(self, side: str) -> tuple[int, int]:
        """(received, sent) bytes counted by the veth end of `side`."""
        import json
        done = _ip('-n', self.names[side], '-s', '-j', 'link', 'show', self.devices[side])
        stats = json.loads(done.stdout)[0]['stats64']
        return stats['rx']['bytes'], stats['tx']['bytes']

    def pids(self, side: str) -> list[int]:
        done = _ip('netns', 'pids', self.names[side], check=False)
        return [int(p) for p in done.stdout.split()]

    def close(self) -> None:
        """Kill what still runs in the namespaces (SIGKILL), then delete them."""
        present = _ip('netns', 'list', check=False).stdout.split()
        for side in 'ab':
            name = self.names[side]
            if name not in present:
                continue
            for _ in range(50):
                left = self.pids(side)
                if not left:
                    break
                for pid in left:
                    try:
                        os.kill(pid, signal.SIGKILL)
                    except ProcessLookupError:
                        pass
                time.sleep(0.05)
            _ip('netns', 'delete', name, check=False)
        if _ip('link', 'show', 'dev', self.devices['a'], check=False).returncode == 0:
            _ip('link', 'delete', self.devices['a'], check=False)   # made, never moved

    def exists(self) -> bool:
        present = _ip('netns', 'list', check=False).stdout.split()
        return any(name in present for name in self.names.values())


# ---------------------------------------------------------------------------- the watcher
def topic_types() -> dict:
    from pam_common import topics
    from pam_interfaces import msg
    return {f'{topics.DEFAULT_NAMESPACE}/{name}': kind for name, kind in (
        (topics.PRESSURES, msg.Pressures), (topics.JOINT_MEASURED, msg.JointMeasurement),
        (topics.ESTIMATE, msg.JointEstimate), (topics.VALVE_COMMAND, msg.ValveCommand),
        (topics.REFERENCE, msg.Reference))}


def watch(timeout: float, topics: list[str]) -> int:
    """Wait for one message of each topic; exit code 0, or WATCH_TIMEOUT_CODE."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    types = topic_types()
    unknown = [t for t in topics if t not in types]
    if unknown:
        print(f'unknown topics {unknown}; known: {sorted(types)}', flush=True)
        return 2
    rclpy.init()
    node = rclpy.create_node('two_hosts_watch')
    seen: set = set()

    def on_message(topic):
        def callback(_msg):
            if topic not in seen:
                seen.add(topic)
                print(f'received {topic}', flush=True)
        return callback

    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    for topic in topics:
        node.create_subscription(types[topic], topic, on_message(topic), qos)
    end = time.monotonic() + timeout
    while len(seen) < len(topics) and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    code = 0 if len(seen) == len(topics) else WATCH_TIMEOUT_CODE
    print('all received' if code == 0 else 'timeout', flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    if len(sys.argv) < 4 or sys.argv[1] != 'watch':
        sys.exit(__doc__)
    sys.exit(watch(float(sys.argv[2]), sys.argv[3:]))
