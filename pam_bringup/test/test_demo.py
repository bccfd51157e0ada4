"""pam-demo (`make demo`), a short real run of the lab workflow: the quick calibration campaign on
the simulated 'realistic' rig, pam-identify, then the two stacks (nominal and identified model,
pam-bringup in /nominal and /identified) and their tracking_reports as real processes on this
module's ROS domain; the reports, the comparison and out/demo_summary.json written, the stacks
stopped cleanly afterwards with no node left running."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

from pam_common.testing import STARTUP_TIMEOUT, STOP_TIMEOUT, executable
from pam_model.model_extensions import load_extensions

DURATION = 12.0   # s recorded: the first 8 s reference step, then about 4 s of the next one


def test_help_exits_0():
    run = subprocess.run([executable('pam-demo', 'pam_bringup'), '--help'],
                         capture_output=True, text=True, timeout=30)
    assert run.returncode == 0, run.stderr
    for option in ('--duration', '--transient', '--out', '--domain-id', '--scenario',
                   '--campaign', '--seed'):
        assert option in run.stdout


def test_a_bad_duration_is_refused_in_one_line(tmp_path):
    run = subprocess.run([executable('pam-demo', 'pam_bringup'), '--duration', '0.5', '--out',
                          str(tmp_path)], capture_output=True, text=True, timeout=30)
    assert run.returncode == 2
    assert run.stderr.splitlines()[-1] == 'pam-demo: error: --duration must be in 1..86400 s, ' \
                                          'got 0.5', run.stderr
    assert not (tmp_path / 'logs').exists()


def test_an_unknown_scenario_is_refused_in_one_line(tmp_path):
    run = subprocess.run([executable('pam-demo', 'pam_bringup'), '--scenario', 'nosuch',
                          '--out', str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert run.stderr.splitlines()[-1].startswith('pam-demo: error: --scenario nosuch: '), \
        run.stderr
    assert not (tmp_path / 'demo').exists()


def test_a_directory_pam_demo_did_not_write_is_kept(tmp_path):
    (tmp_path / 'demo').mkdir()
    (tmp_path / 'demo' / 'mine.txt').write_text('precious')
    run = subprocess.run([executable('pam-demo', 'pam_bringup'), '--out', str(tmp_path)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert 'was not written by pam-demo; not replacing it' in run.stderr, run.stderr
    assert (tmp_path / 'demo' / 'mine.txt').read_text() == 'precious'


def test_the_demo_runs_the_workflow_and_stops_the_stacks(node_process, ros_domain, tmp_path):
    out = tmp_path / 'out'
    demo = node_process('pam-demo', 'pam_bringup', '--campaign', 'quick', '--duration',
                        f'{DURATION:g}', '--out', str(out), '--domain-id', str(ros_domain),
                        raw=True)
    code = demo.wait_exit(timeout=120.0 + STARTUP_TIMEOUT + DURATION + 2 * STOP_TIMEOUT)
    stdout = demo.stdout
    assert code == 0, stdout + demo.stderr
    assert stdout.startswith(f"demo: scenario 'realistic', campaign 'quick'; "
                             f'ROS_DOMAIN_ID={ros_domain}; logs in {out}/logs/\n'), stdout
    for step in ('1/3 calibration campaign', '2/3 identification', '3/3 real-time'):
        assert f'demo: {step}' in stdout, stdout
    # the campaign's bags and the identified model the identified stack ran with
    bags = sorted(p.name for p in (out / 'demo' / 'calibration').iterdir())
    assert bags == ['free', 'locked_m15deg', 'locked_p15deg'], bags
    identified = out / 'demo' / 'identified'
    params = (out / 'demo' / 'bringup_identified.yaml').read_text()
    assert str(identified / 'params.yaml') in params and 'mismatch: realistic' in params
    assert str(identified) not in (out / 'demo' / 'bringup_nominal.yaml').read_text()
    # the identified stack's ukf_node runs with the identified extensions, the nominal one none
    extensions = load_extensions(identified / 'extensions.yaml').describe()
    assert f'model extensions: {extensions}' in (
        out / 'logs' / 'identified' / 'pam_container.log').read_text()
    assert 'model extensions: none' in (out / 'logs' / 'nominal' / 'pam_container.log').read_text()
    for run in ('nominal', 'identified'):
        assert f'=== {run} model ===' in stdout, stdout
        assert re.search(rf'^\[INFO\] \[[\d.]+\] \[{run}.tracking_report\]', stdout,
                         flags=re.MULTILINE), stdout
    assert len(re.findall(r'^tracking report: angle mode, \d+\.\d s, \d+ samples', stdout,
                          flags=re.MULTILINE)) == 2, stdout
    assert 'estimation error after t >= 1 s' in stdout, stdout     # --transient's default
    assert re.search(r'^  nominal +\d+\.\d\d % +\d+\.\d\d s', stdout, flags=re.MULTILINE), stdout
    assert re.search(r'^  identified +\d+\.\d\d % +\d+\.\d\d s', stdout, flags=re.MULTILINE), \
        stdout
    assert (out / 'demo_tracking.png').stat().st_size > 10_000
    assert (out / 'demo_tracking_nominal.png').stat().st_size > 10_000

    summary = json.loads((out / 'demo_summary.json').read_text())
    assert summary['scenario'] == 'realistic' and summary['campaign'] == 'quick'
    for run in ('nominal', 'identified'):
        report = summary[run]
        assert report['mode'] == 'angle' and report['steps'], report
        assert report['worst_steady_state_error_pct'] == max(
            s['steady_state_error_pct'] for s in report['steps'])
        assert report['worst_settling_time_s'] == max(s['settling_time_s']
                                                      for s in report['steps'])
        for key in ('whole', 'after_transient'):
            m = report['estimation'][key]
            assert 0.0 < m['I'] <= m['M'] and 0.0 < m['Q_pct'] < 100.0, m
    # the summary holds what the comparison printed
    assert f"{summary['identified']['worst_steady_state_error_pct']:.2f} %" in stdout

    for run in ('nominal', 'identified'):
        log = (out / 'logs' / f'bringup_{run}.log').read_text()
        started = dict(re.findall(r'started (\w+) \(.*?\), pid (\d+):', log))
        assert set(started) == {'pam_container'}, log          # pam-bringup's default: composed
        assert (out / 'logs' / run / 'pam_container.log').stat().st_size > 0, run
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
