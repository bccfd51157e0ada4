"""bag_record / bag_play / pam-bag-info as real processes on an isolated domain (~50 s)."""

import itertools
import subprocess
import time
from pathlib import Path

import pytest

from pam_common.qos import RECORD_DEPTH
from pam_common.testing import executable, stamp_ns, wait_until

RECORD_S = 3.0
_CACHE = {}
N, PERIOD = 100, 20_000_000   # the small test bag: N Pressures samples every PERIOD ns (1.98 s)


def record(node_process, out: Path, *params):
    sim = node_process('sim_node', 'pam_driver')
    rec = node_process('bag_record', 'pam_bag', '-p', f'output:={out}', *params)
    rec.wait_for(lambda: rec.stderr.count('subscribed to /pam/') >= 2, 45.0, 'subscriptions')
    time.sleep(RECORD_S)
    code = rec.stop()
    sim.stop()
    return code, rec


def test_record_sim_node(node_process, tmp_path_factory):
    out = tmp_path_factory.mktemp('bags') / 'run'
    code, rec = record(node_process, out)
    assert code == 0, rec.stderr
    _CACHE['bag'] = out
    from rosbags.rosbag2 import Reader
    from ruamel.yaml import YAML

    from pam_bag.bags import make_typestore
    meta = YAML(typ='safe').load((out / 'metadata.yaml').read_text())
    info = meta['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert {'/pam/pressures', '/pam/joint_measured'} <= set(topics)
    for t in topics.values():
        assert t['topic_metadata']['type_description_hash'].startswith('RIHS01_')
        assert t['topic_metadata']['offered_qos_profiles'][0]['reliability'] == 'reliable'
    store = make_typestore()
    with Reader(out) as reader:
        conns = [c for c in reader.connections if c.topic == '/pam/pressures']
        stamps = [stamp_ns(store.deserialize_cdr(raw, c.msgtype).header.stamp)
                  for c, _, raw in reader.messages(connections=conns)]
        duration = reader.duration * 1e-9
    assert duration >= RECORD_S - 0.5
    # realtime sim_node stamps sample k at its deadline, start + k ms, and catches up a stall
    # in a burst (it never pauses): the recorded samples span len - 1 ms of stamps when none is
    # lost; loss at 4 topics x 1 kHz is measured by benchmarks/bag_throughput.py
    span_ms = (stamps[-1] - stamps[0]) / 1e6
    assert 0.6 * 1000 * duration < len(stamps) <= span_ms + 1.01, (len(stamps), span_ms)
    steps = [b - a for a, b in itertools.pairwise(stamps)]
    # realtime sim_node stamps with the wall clock (jitter of a loaded machine): check order
    assert min(steps) > 0, 'pressure samples reordered'
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(out / 'run.mcap', 'rb') as f:
        decoded = [m for _, ch, _, m in make_reader(
            f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()
            if ch.topic == '/pam/pressures']
    assert [stamp_ns(m.header.stamp) for m in decoded] == stamps
    from test_bags_lib import assert_crcs
    assert_crcs(out / 'run.mcap')     # chunk, data section and summary CRCs


def resumed_player(node_process, probe, topic: str, *params, name: str = 'bag_play'):
    """bag_play (node `name`) started paused and resumed once the probe has discovered its
    publisher of `topic`: at the resume the player itself waits until its writers matched a
    subscription (wait_for_subscribers), so no message is sent before the probe's subscription
    is matched, however slowly the processes start (a fixed delay is not enough on a loaded
    machine, and the probe sees only its side of the match)."""
    from std_srvs.srv import Trigger
    player = node_process('bag_play', 'pam_bag', *params, '-p', 'start_paused:=true',
                          '-p', 'delay:=0.0', '-r', f'__node:={name}')
    player.wait_for(lambda: probe.node.count_publishers(topic) > 0, 30.0, 'the publisher')
    client = probe.client(Trigger, f'/{name}/resume')
    assert client.wait_for_service(timeout_sec=30.0), player.stderr
    future = client.call_async(Trigger.Request())
    assert wait_until(future.done, 10.0) and future.result().success, 'no answer from ~/resume'
    return player


def test_record_split_by_duration_and_play_it_back(node_process, probe, tmp_path):
    """max_bag_duration 1 s over > 3 s: run_0.mcap, run_1.mcap, ... each complete and within 1 s
    of receive times; bag_play plays all of it across the files, in order; pam-bag-info lists
    the files."""
    out = tmp_path / 'run'
    code, rec = record(node_process, out, '-p', 'max_bag_duration:=1.0')
    assert code == 0, rec.stderr
    assert 'files)' in rec.stderr, rec.stderr       # the summary: INFO lines
    from mcap.reader import make_reader

    from pam_bag.bags import bag_info, load_bag
    info = bag_info(out)
    names = [Path(f).name for f in info['files']]
    assert len(names) >= 3 and names == [f'run_{i}.mcap' for i in range(len(names))], info
    for f in info['files']:
        with open(f, 'rb') as stream:
            stats = make_reader(stream).get_summary().statistics
        assert stats.message_count > 0, f
        assert stats.message_end_time - stats.message_start_time < 1e9, (f, stats)
    expected = load_bag(out, ['/pam/pressures'])
    assert len(expected.data) == next(t['count'] for t in info['topics']
                                      if t['name'] == '/pam/pressures')
    from pam_interfaces.msg import Pressures
    n = len(expected.data)
    # a reader history for all of it: a probe that lags (a busy test process) loses nothing
    got = probe.subscribe(Pressures, '/pam/pressures', depth=min(2 * n, RECORD_DEPTH))
    player = resumed_player(node_process, probe, '/pam/pressures', '-p', f'bag:={out}',
                            '-p', 'topics:=/pam/pressures')
    assert player.wait_exit(30.0) == 0, player.stderr
    wait_until(lambda: len(got) >= n, 5.0)
    from pam_bag.bags import make_typestore
    store = make_typestore()
    played = [stamp_ns(m.header.stamp) for m in got.messages()]
    recorded = [stamp_ns(store.deserialize_cdr(d, 'pam_interfaces/msg/Pressures').header.stamp)
                for d in expected.data]
    seen = set(played)
    missing = [k for k, t in enumerate(recorded) if t not in seen]
    assert played == recorded, (len(played), len(recorded), missing[:5], missing[-5:])
    shown = subprocess.run([executable('pam-bag-info', 'pam_bag'), str(out)],
                           capture_output=True, text=True, timeout=30)
    assert shown.returncode == 0 and f"Files:             {', '.join(names)}" in shown.stdout, \
        shown.stdout + shown.stderr


def test_play_remap_select_timing(node_process, probe):
    bag = _CACHE.get('bag') or pytest.skip('no recorded bag')
    from pam_bag.bags import load_bag
    from pam_interfaces.msg import JointMeasurement, Pressures
    expected = load_bag(bag, ['/pam/pressures'])
    n = len(expected.data)
    got = probe.subscribe(Pressures, '/replay/pressures', depth=min(2 * n, RECORD_DEPTH))
    other = probe.subscribe(JointMeasurement, '/pam/joint_measured', depth=1000)
    player = resumed_player(node_process, probe, '/replay/pressures', '-p', f'bag:={bag}',
                            '-p', 'topics:=/pam/pressures',
                            '-p', 'remap:=/pam/pressures:=/replay/pressures')
    player.wait_for(lambda: len(got) >= n, 30.0, f'{n} replayed pressures')
    assert player.wait_exit(10.0) == 0
    items = got.items()
    stamps = [stamp_ns(m.header.stamp) for _, m in items]
    assert stamps == sorted(stamps) and len(stamps) == n
    span = items[-1][0] - items[0][0]
    bag_span = (expected.times[-1] - expected.times[0]) * 1e-9
    assert abs(span - bag_span) < 0.25, (span, bag_span)
    assert len(other) == 0, 'an unselected topic was played'


def test_existing_output_refused(node_process, tmp_path):
    out = tmp_path / 'exists'
    out.mkdir()
    rec = node_process('bag_record', 'pam_bag', '-p', f'output:={out}')
    assert rec.wait_exit(30.0) != 0
    assert 'exists' in rec.stderr and str(out) in rec.stderr
    assert list(out.iterdir()) == []


def test_too_small_split_refused(node_process, tmp_path):
    rec = node_process('bag_record', 'pam_bag', '-p', f'output:={tmp_path / "b"}',
                       '-p', 'max_bag_size:=1000')
    assert rec.wait_exit(30.0) == 2
    assert 'parameter max_bag_size 1000 B: use 0 (no split) or at least 100000 B' in rec.stderr
    assert not (tmp_path / 'b').exists()


def test_bad_bags_exit_nonzero(node_process, tmp_path):
    bag = _CACHE.get('bag') or pytest.skip('no recorded bag')
    import shutil
    cut = tmp_path / 'cut'
    shutil.copytree(bag, cut)
    data = (cut / 'run.mcap').read_bytes()
    (cut / 'run.mcap').write_bytes(data[: len(data) // 2])
    nometa = tmp_path / 'nometa'
    shutil.copytree(bag, nometa)
    (nometa / 'metadata.yaml').unlink()
    for path, what in ((cut, 'run.mcap: truncated'), (nometa, 'metadata.yaml: missing')):
        player = node_process('bag_play', 'pam_bag', '-p', f'bag:={path}')
        assert player.wait_exit(30.0) != 0
        assert what in player.stderr, player.stderr


def test_bag_info_prints_counts():
    bag = _CACHE.get('bag') or pytest.skip('no recorded bag')
    out = subprocess.run([executable('pam-bag-info', 'pam_bag'), str(bag)],
                         capture_output=True, text=True, timeout=30)
    assert out.returncode == 0, out.stderr
    from pam_bag.bags import load_bag
    n = len(load_bag(bag, ['/pam/pressures']).data)
    assert 'Topic: /pam/pressures' in out.stdout and f'Count: {n} ' in out.stdout
    assert 'zstd' in out.stdout and 'Duration:' in out.stdout
    bad = subprocess.run([executable('pam-bag-info', 'pam_bag'), str(bag.parent / 'nope')],
                         capture_output=True, text=True, timeout=30)
    assert bad.returncode == 2 and 'no such bag directory' in bad.stderr


# ------------------------------------------------------------- bag_play options on a small bag
@pytest.fixture(scope='module')
def small_bag(tmp_path_factory):
    from pam_bag.bags import make_typestore
    from test_bags_lib import write_bag  # the same test folder (pytest's prepend import mode)
    path = tmp_path_factory.mktemp('small') / 'b'
    write_bag(make_typestore(), path, n=N, period_ns=PERIOD)
    return path


def index(msg) -> int:
    """The sample index the small bag's message carries."""
    return round(msg.p1 - 1e5)


def play(node_process, bag, *params, delay=1.5, name='bag_play'):
    """bag_play on `bag` with `-p` params; delay: s for the test's subscriptions to match."""
    args = [a for p in (f'bag:={bag}', f'delay:={delay}', *params) for a in ('-p', p)]
    return node_process('bag_play', 'pam_bag', *args, '-r', f'__node:={name}')


def pressures(probe, topic='/pam/pressures'):
    from pam_interfaces.msg import Pressures
    return probe.subscribe(Pressures, topic, depth=1000)


def test_rate_scales_the_schedule(node_process, probe, small_bag):
    """Two players at once, rates 1 and 2: the receive span at rate 2 is half the other."""
    rates = (1.0, 2.0)
    got = [pressures(probe, f'/rate{i}/pressures') for i in range(len(rates))]
    players = [resumed_player(node_process, probe, f'/rate{i}/pressures', '-p',
                              f'bag:={small_bag}', '-p', f'rate:={r}', '-p',
                              f'remap:=/pam/pressures:=/rate{i}/pressures', name=f'play{i}')
               for i, r in enumerate(rates)]
    spans = []
    for player, received in zip(players, got, strict=True):
        player.wait_for(lambda received=received: len(received) >= N, 30.0, f'{N} messages')
        assert player.wait_exit(10.0) == 0, player.stderr
        items = received.items()
        assert [index(m) for _, m in items] == list(range(N))
        spans.append(items[-1][0] - items[0][0])
    assert 0.4 < spans[1] / spans[0] < 0.6, spans
    assert 0.8 < spans[0] / ((N - 1) * PERIOD * 1e-9) < 1.2, spans


def test_loop_plays_again_after_the_end(node_process, probe, small_bag):
    got = pressures(probe)
    # a read-ahead queue smaller than the bag: reading while playing, and across passes
    player = play(node_process, small_bag, 'loop:=true', 'rate:=4.0', 'read_ahead_size:=100')
    player.wait_for(lambda: len(got) >= 2 * N + 10, 30.0, 'two loops and more')
    assert player.alive()
    assert player.stop() == 0
    seen = [index(m) for m in got.messages()]
    assert all(b == (a + 1) % N for a, b in itertools.pairwise(seen)), 'not in bag order'
    assert sum(a == N - 1 and b == 0 for a, b in itertools.pairwise(seen)) >= 2


def test_start_offset_starts_at_the_message_at_the_offset(node_process, probe, small_bag):
    got = pressures(probe)
    player = resumed_player(node_process, probe, '/pam/pressures', '-p', f'bag:={small_bag}',
                            '-p', 'start_offset:=1.0', '-p', 'rate:=4.0')
    assert player.wait_exit(30.0) == 0, player.stderr
    first = round(1.0e9 / PERIOD)
    wait_until(lambda: len(got) >= N - first, 5.0)
    assert [index(m) for m in got.messages()] == list(range(first, N))


def test_start_paused_plays_nothing_until_resumed(node_process, probe, small_bag):
    """Paused: no message, /clock at the bag's start time; ~/resume plays all of it, once every
    played topic has a subscriber (wait_for_subscribers)."""
    from rosgraph_msgs.msg import Clock
    from std_srvs.srv import Trigger
    got = pressures(probe)
    clock = probe.subscribe(Clock, '/clock', depth=1000)
    player = play(node_process, small_bag, 'start_paused:=true', 'rate:=4.0', 'clock:=20.0',
                  delay=0.2)
    client = probe.client(Trigger, '/bag_play/resume')
    assert client.wait_for_service(timeout_sec=30.0), player.stderr
    player.wait_for(lambda: probe.node.count_publishers('/pam/pressures') > 0, 30.0,
                    'the publisher')
    time.sleep(1.5)    # > delay + the bag's 0.5 s at rate 4: all of it, were it not paused
    assert len(got) == 0
    frozen = [stamp_ns(m.clock) for m in clock.messages()]
    assert len(frozen) >= 10 and set(frozen) == {10**18}, frozen

    future = client.call_async(Trigger.Request())
    assert wait_until(future.done, 10.0), 'no answer from ~/resume'
    assert future.result().success
    player.wait_for(lambda: len(got) >= N, 30.0, f'{N} messages after resuming')
    assert [index(m) for m in got.messages()] == list(range(N))
    assert player.wait_exit(10.0) == 0
    # the first ~/resume waited for its writer to match the probe's reader, as an unpaused
    # start does: the probe sees only its own side of the match
    assert 'every topic has a subscriber' in player.stderr + player.stdout


@pytest.fixture(scope='module')
def burst_bag(tmp_path_factory):
    """3000 Pressures messages 0.1 ms apart (0.3 s)."""
    from pam_bag.bags import make_typestore
    from test_bags_lib import write_bag
    path = tmp_path_factory.mktemp('burst') / 'b'
    write_bag(make_typestore(), path, n=3000, period_ns=100_000)
    return path


def test_every_message_arrives_though_the_player_exits_at_once(node_process, probe, burst_bag):
    """bag_play sends 3000 messages in 0.3 s and exits: wait_for_all_acked (default 2 s) keeps
    it until the reliable subscriber has acknowledged every message (samples not yet
    acknowledged when a writer's process exits are lost: without it, the split-bag replay above
    lost its last messages in about one run in three right after `make setup`)."""
    from pam_interfaces.msg import Pressures
    got = probe.subscribe(Pressures, '/pam/pressures', depth=RECORD_DEPTH)   # room for all of it
    player = resumed_player(node_process, probe, '/pam/pressures', '-p', f'bag:={burst_bag}',
                            '-p', 'read_ahead_size:=100')   # read while sending at 10 kHz
    assert player.wait_exit(30.0) == 0, player.stderr
    wait_until(lambda: len(got) >= 3000, 5.0)
    assert [index(m) for m in got.messages()] == list(range(3000))


def test_a_damaged_chunk_is_reported_after_playing_what_precedes_it(node_process, probe,
                                                                    tmp_path):
    """A complete file whose chunk 20 (of 60, one message each) has 8 bytes flipped where zstd
    still decompresses (only its CRC shows it) passes the checks at start; the player plays
    messages 0-19, then names the file and the chunk, exit 2 (bad input)."""
    from pam_bag.bags import make_typestore
    from pam_bag.testing import damage_chunk
    from test_bags_lib import write_bag
    bag = tmp_path / 'full'
    write_bag(make_typestore(), bag, n=60, chunk_interval=0.0)
    damage_chunk(bag / 'full.mcap', 20)
    got = pressures(probe)
    player = resumed_player(node_process, probe, '/pam/pressures', '-p', f'bag:={bag}')
    assert player.wait_exit(30.0) == 2, player.stderr
    assert ('full.mcap: corrupt data after 20 messages: full.mcap: chunk 20 at byte'
            in player.stderr and 'CRC mismatch' in player.stderr), player.stderr
    wait_until(lambda: len(got) >= 20, 5.0)
    assert [index(m) for m in got.messages()] == list(range(20))


def test_clock_publishes_the_bag_time_at_the_requested_rate(node_process, probe, small_bag):
    import numpy as np
    from rosgraph_msgs.msg import Clock
    clock = probe.subscribe(Clock, '/clock', depth=1000)
    # resumed once the probe sees the /clock publisher: a fixed delay can end before DDS has
    # matched the pair (up to one 3 s announcement period, docs/nodes.md "Start-up discovery")
    player = resumed_player(node_process, probe, '/clock', '-p', f'bag:={small_bag}', '-p',
                            'clock:=50.0', '-p', 'rate:=2.0')
    resumed = time.monotonic()
    assert player.wait_exit(30.0) == 0, player.stderr
    items = [(r, m) for r, m in clock.items() if r >= resumed]   # not the paused, frozen clock
    assert len(items) > 10, f'{len(items)} /clock messages'
    wall = np.array([r for r, _ in items])
    bag_ns = np.array([stamp_ns(m.clock) for _, m in items])
    start, end = 10**18, 10**18 + (N - 1) * PERIOD     # the bag's first and last receive times
    assert np.all(np.diff(bag_ns) >= 0)
    assert start <= bag_ns[0] < start + 0.1e9 and end - 0.1e9 < bag_ns[-1] <= end, bag_ns
    span = wall[-1] - wall[0]
    assert 35.0 < (len(items) - 1) / span < 65.0         # 50 Hz of wall time
    assert 1.6 < (bag_ns[-1] - bag_ns[0]) * 1e-9 / span < 2.4   # bag time runs at rate 2


# ------------------------------------------------ bag_play waits for its subscribers to match
def test_default_start_waits_for_the_subscriber_and_delivers_every_message(node_process, probe,
                                                                           small_bag):
    """Default parameters, a subscriber that exists already: bag_play plays only once the pair
    has matched (the fixed 0.5 s delay alone lost the first messages when discovery took one
    3 s announcement period), so every message arrives and none is counted as unmatched."""
    got = pressures(probe)
    player = node_process('bag_play', 'pam_bag', '-p', f'bag:={small_bag}')
    assert player.wait_exit(30.0) == 0, player.stderr
    assert 'every topic has a subscriber (waited' in player.stderr, player.stderr
    wait_until(lambda: len(got) >= N, 5.0)
    assert [index(m) for m in got.messages()] == list(range(N))
    assert 'sent before any subscriber matched' not in player.stderr, player.stderr


def test_a_topic_without_subscriber_starts_after_the_bound_and_counts_the_lost(node_process,
                                                                              probe, small_bag):
    """Nobody subscribes to /nobody/pressures: play starts after wait_for_subscribers (1 s) with
    one line naming it; a subscriber that comes once messages were sent (the /clock bag time,
    never ahead of the next message to send, shows they were) gets a warning with the count of
    those, and the end summary the total."""
    from rosgraph_msgs.msg import Clock
    clock = probe.subscribe(Clock, '/clock', depth=1000)
    start = time.monotonic()
    player = play(node_process, small_bag, 'remap:=/pam/pressures:=/nobody/pressures',
                  'wait_for_subscribers:=1.0', 'loop:=true', 'clock:=50.0', delay=0.0)
    player.wait_for(lambda: 'playing; no subscriber yet on: /nobody/pressures' in player.stderr,
                    30.0, 'the no-subscriber line')
    assert time.monotonic() - start >= 1.0
    sent = 10**18 + 10 * PERIOD     # the bag time once 10 messages were sent
    player.wait_for(lambda: any(stamp_ns(m.clock) > sent for m in clock.messages()), 30.0,
                    'ten messages sent')
    got = pressures(probe, '/nobody/pressures')
    player.wait_for(lambda: 'first subscriber matched after' in player.stderr, 30.0,
                    'the late-subscriber warning')
    wait_until(lambda: len(got) > 0, 10.0)
    assert player.stop() == 0
    line = next(s for s in player.stderr.splitlines() if 'first subscriber matched' in s)
    lost = int(line.split('first subscriber matched after ')[1].split()[0])
    assert lost >= 10 and '/nobody/pressures' in line and 'WARN' in line, line
    assert f'sent before any subscriber matched: /nobody/pressures {lost}' in player.stderr


def test_negative_wait_for_subscribers_is_refused_in_one_line(node_process, small_bag):
    player = play(node_process, small_bag, 'wait_for_subscribers:=-1.0')
    assert player.wait_exit(30.0) == 2
    assert player.stderr.splitlines() == [
        "[bag_play] error: parameter 'wait_for_subscribers': -1.0 is out of range "
        "[0.0, 600.0]"], player.stderr
