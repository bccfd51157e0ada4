"""pam-demo (`make demo`), a short real run: pam-bringup's stack and tracking_report as real
processes on this module's ROS domain, the report printed, the figure and the logs written, the
stack stopped cleanly afterwards with no node left running."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

from pam_common.testing import STARTUP_TIMEOUT, STOP_TIMEOUT, executable

DURATION = 12.0   # s recorded: the first 8 s reference step, then about 4 s of the next one


def test_help_exits_0():
    run = subprocess.run([executable('pam-demo', 'pam_bringup'), '--help'],
                         capture_output=True, text=True, timeout=30)
    assert run.returncode == 0, run.stderr
    for option in ('--duration', '--transient', '--out', '--domain-id'):
        assert option in run.stdout


def test_a_bad_duration_is_refused_in_one_line(tmp_path):
    run = subprocess.run([executable('pam-demo', 'pam_bringup'), '--duration', '0.5', '--out',
                          str(tmp_path)], capture_output=True, text=True, timeout=30)
    assert run.returncode == 2
    assert run.stderr.splitlines()[-1] == 'pam-demo: error: --duration must be in 1..86400 s, ' \
                                          'got 0.5', run.stderr
    assert not (tmp_path / 'logs').exists()


def test_the_demo_reports_the_tracking_and_stops_the_stack(node_process, ros_domain, tmp_path):
    out = tmp_path / 'out'
    demo = node_process('pam-demo', 'pam_bringup', '--duration', f'{DURATION:g}', '--out',
                        str(out), '--domain-id', str(ros_domain), raw=True)
    code = demo.wait_exit(timeout=STARTUP_TIMEOUT + DURATION + 2 * STOP_TIMEOUT + 30.0)
    stdout = demo.stdout
    assert code == 0, stdout + demo.stderr
    assert stdout.startswith(f'demo: ROS_DOMAIN_ID={ros_domain}, {DURATION:g} s of closed-loop '
                             f'angle tracking; node logs in {out}/logs/\n'), stdout
    assert re.search(r'^tracking report: angle mode, \d+\.\d s, \d+ samples', stdout,
                     flags=re.MULTILINE), stdout
    assert 'estimation error' in stdout and f'figure: {out}/demo_tracking.png' in stdout, stdout
    assert 'estimation error after t >= 1 s' in stdout, stdout     # --transient's default
    assert (out / 'demo_tracking.png').stat().st_size > 10_000

    log = (out / 'logs' / 'bringup.log').read_text()
    started = dict(re.findall(r'started (\w+) \(.*?\), pid (\d+):', log))
    assert set(started) == {'pam_container'}, log          # pam-bringup's default: composed
    for name in started:
        assert (out / 'logs' / f'{name}.log').stat().st_size > 0, name
    assert 'SIGINT received: stopping every node' in log, log
    assert 'all nodes stopped cleanly' in log, log
    leftovers = [name for name, pid in started.items() if running(int(pid), name)]
    assert not leftovers, f'still running after pam-demo exited: {leftovers}'


def running(pid: int, name: str) -> bool:
    """True if pid is (still) a process running the executable `name`."""
    try:
        return name.encode() in Path(f'/proc/{pid}/cmdline').read_bytes()
    except OSError:
        return False
