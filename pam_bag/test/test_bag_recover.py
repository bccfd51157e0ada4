"""pam-bag-recover on the bag of a SIGKILLed bag_record, as real processes (~20 s): what the
recorder had written survives, pam-bag-info / load_bag / bag_play accept the repaired bag."""

import subprocess
import time

import pytest

from pam_common.testing import executable

RATE, PUBLISH_S = 200.0, 3.0     # Hz, s: published while recording
CHUNK_S = 1.0                    # bag_record's default chunk_interval: what a crash may lose
_CACHE = {}


def run(name, *args):
    return subprocess.run([executable(name, 'pam_bag'), *map(str, args)],
                          capture_output=True, text=True, timeout=60)


def sample(i):
    """The i-th published message: p1 carries its index."""
    from pam_interfaces.msg import Pressures
    msg = Pressures(p1=float(i), p2=2e5)
    msg.header.frame_id = 'pam'
    return msg


def test_killed_recording_is_recovered(node_process, probe, tmp_path_factory):
    from pam_interfaces.msg import Pressures
    out = tmp_path_factory.mktemp('killed') / 'run'
    rec = node_process('bag_record', 'pam_bag', '-p', f'output:={out}',
                       '-p', 'topics:=/pam/pressures')
    pub = probe.publisher(Pressures, '/pam/pressures', depth=1000)
    rec.wait_for(lambda: 'subscribed to /pam/pressures' in rec.stderr, 45.0, 'subscription')
    rec.wait_for(lambda: pub.get_subscription_count() > 0, 10.0, 'the recorder to match')
    published, start = 0, time.monotonic()
    while published < RATE * PUBLISH_S:
        time.sleep(max(0.0, start + published / RATE - time.monotonic()))
        pub.publish(sample(published))
        published += 1
    rec.proc.kill()                                    # SIGKILL: no chance to close the bag
    assert rec.wait_exit(10.0) == -9

    refused = run('pam-bag-info', out)
    assert refused.returncode == 2 and 'metadata.yaml: missing' in refused.stderr
    assert 'pam-bag-recover' in refused.stderr

    fixed = run('pam-bag-recover', out)
    assert fixed.returncode == 0, fixed.stderr
    from pam_bag.bags import load_bag
    contents = load_bag(out)
    n = len(contents.data)
    assert f'/pam/pressures  {n}' in fixed.stdout and 'dropped:' in fixed.stdout, fixed.stdout
    assert sorted(p.name for p in out.iterdir()) == ['metadata.yaml', 'run.mcap',
                                                     'run.mcap.damaged']
    from rclpy.serialization import deserialize_message
    indices = [round(deserialize_message(d, Pressures).p1) for d in contents.data]
    assert indices == list(range(n)), 'not the published messages from the first, in order'
    # lost: the chunk in memory (up to CHUNK_S, closed only by a write after it) + the queue
    assert published - RATE * (CHUNK_S + 0.5) <= n <= published, (n, published)

    info = run('pam-bag-info', out)
    assert info.returncode == 0 and f'Count: {n} ' in info.stdout, info.stderr
    again = run('pam-bag-recover', out)
    assert again.returncode == 2 and 'needs no recovery' in again.stderr
    assert again.stderr.count('\n') == 1
    _CACHE['bag'], _CACHE['n'] = out, n


def test_recovered_bag_plays(node_process, probe):
    bag = _CACHE.get('bag') or pytest.skip('no recovered bag')
    from pam_interfaces.msg import Pressures
    got = probe.subscribe(Pressures, '/replay/pressures', depth=1000)
    player = node_process('bag_play', 'pam_bag', '-p', f'bag:={bag}', '-p', 'rate:=4.0',
                          '-p', 'remap:=/pam/pressures:=/replay/pressures', '-p', 'delay:=1.5')
    player.wait_for(lambda: len(got) >= _CACHE['n'], 30.0, f'{_CACHE["n"]} replayed messages')
    assert player.wait_exit(10.0) == 0, player.stderr
    assert [round(m.p1) for m in got.messages()] == list(range(_CACHE['n']))


def test_cli_errors_are_one_line(tmp_path):
    (tmp_path / 'x.mcap').write_bytes(b'not a bag')
    for path, error in ((tmp_path, 'x.mcap: not an MCAP file'),
                        (tmp_path / 'nope', 'no such bag directory')):
        out = run('pam-bag-recover', path)
        assert out.returncode == 2 and out.stderr.count('\n') == 1, out.stderr
        assert out.stderr.startswith('pam-bag-recover: error: ') and error in out.stderr
    assert run('pam-bag-recover', '--help').stdout.startswith('usage: pam-bag-recover')
