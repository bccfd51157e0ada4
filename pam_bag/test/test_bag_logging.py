"""bag_record and bag_play log through their rclpy loggers: the end summaries
are INFO lines (stderr, and /rosout: a probe subscribed to rcl_interfaces/msg/Log receives
bag_record's); with `--log-level <node>:=debug` a split file closed (bag_record) and the start of
a pass (bag_play) are DEBUG lines from our own code; without it there is no DEBUG line."""

import time

import pytest
from rcl_interfaces.msg import Log

from pam_common.testing import log_lines

SPLIT = 100_000     # B: the smallest max_bag_size; sim_node's 1 kHz topics fill it in < 0.3 s


@pytest.mark.parametrize('debug', [True, False], ids=['debug', 'default'])
def test_summaries_at_info_and_split_files_at_debug(node_process, probe, tmp_path, debug):
    rosout = probe.subscribe(Log, '/rosout', depth=1000)
    level = ['--log-level', 'bag_record:=debug'] if debug else []
    sim = node_process('sim_node', 'pam_driver')
    time.sleep(1.0)
    out = tmp_path / 'run'
    rec = node_process('bag_record', 'pam_bag', '-p', f'output:={out}', '-p', 'duration:=6.0',
                       '-p', f'max_bag_size:={SPLIT}', *level)
    assert rec.wait_exit(60.0) == 0, rec.stderr       # ends by itself: ROS still up at finish
    sim.stop()
    files = sorted((p.name for p in out.glob('*.mcap')), key=lambda n: int(n[4:-5]))  # run_<i>
    assert len(files) >= 3, (files, rec.stderr)     # discovery can take 3 s of the 6
    summary = [line for line in log_lines(rec.stderr, 'INFO', 'bag_record') if ': wrote ' in line]
    assert len(summary) == 1 and f'({len(files)} files)' in summary[0], (files, summary)
    assert 'wrote' not in rec.stdout, rec.stdout
    assert any(']:   /pam/pressures: ' in line
               for line in log_lines(rec.stderr, 'INFO', 'bag_record')), rec.stderr
    logged = [m for m in rosout.messages() if m.name == 'bag_record']
    assert any(m.level == Log.INFO and m.msg.startswith('wrote ') for m in logged), \
        [m.msg for m in logged]
    debug_lines = log_lines(rec.stderr, 'DEBUG')
    if not debug:
        assert debug_lines == [], debug_lines
        return
    split = [line for line in debug_lines if '[bag_record]: split file ' in line]
    # every file but the last one is closed by a split (the last one by the end of recording)
    assert [line.split('split file ')[1].split()[0] for line in split] == files[:-1], split
    assert all(' closed: ' in line and ' messages over ' in line for line in split), split
    assert f'next file {files[1]}' in split[0], split

    player = node_process('bag_play', 'pam_bag', '-p', f'bag:={out}', '-p', 'delay:=0.0',
                          '-p', 'wait_for_subscribers:=0.0', '--log-level', 'bag_play:=debug')
    assert player.wait_exit(60.0) == 0, player.stderr
    assert any('[bag_play]: pass 1 started: 0 messages published before it' in line
               for line in log_lines(player.stderr, 'DEBUG')), player.stderr
    assert any(': published ' in line and ' messages; send lateness p50 ' in line
               for line in log_lines(player.stderr, 'INFO', 'bag_play')), player.stderr


def test_the_recorder_and_player_keep_synchronous_publication():
    """Finite tools publish their summary just before they exit: their processes keep FastDDS's
    synchronous publication (pam_common.executors.finite_tool), or the summary's /rosout lines
    were lost with the asynchronous writer at exit (the first test above, once in CI)."""
    from pam_bag.bag_play import BagPlayer
    from pam_bag.bag_record import BagRecorder
    from pam_common.executors import Component, finite_tool
    assert finite_tool(Component('bag_record', BagRecorder))
    assert finite_tool(Component('bag_play', BagPlayer))
    assert not finite_tool(Component('other', object))
