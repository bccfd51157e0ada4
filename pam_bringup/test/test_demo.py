"""pam-demo (`make demo`), a short real run of the lab workflow: the quick calibration campaign on
the simulated 'realistic' rig, pam-identify, the nominal-vs-identified comparison on the batch
closed loop, then the one real-time run (the identified stack, pam-bringup in /identified) and
its tracking_report as real processes on this module's ROS domain; the report with its real-time
health, the comparison and out/demo_summary.json written, the stack stopped cleanly afterwards
with no node left running. The batch comparison alone: deterministic."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import yaml

from pam_bringup.demo_workflow import batch_comparison, comparison_lines, loop_settings
from pam_bringup.stack import default_params_file
from pam_common.testing import STARTUP_TIMEOUT, STOP_TIMEOUT, executable
from pam_estimator.pam_ukf import DEFAULT_TUNING
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.model_extensions import NO_EXTENSIONS, load_extensions
from pam_model.parameters import load_parameters
from pam_model.valve_map import load_valve_map

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


def test_the_batch_comparison_is_deterministic():
    """10 s of steps on the realistic plant, the nominal model against the plant's true
    parameters (no extensions): the same figures twice, pi_node's gains from bringup.yaml."""
    settings = loop_settings(yaml.safe_load(default_params_file().read_text()))
    base = yaml.safe_load(default_params_file().read_text())['/pam/pi_node']['ros__parameters']
    assert settings['gains'] == (base['kp_angle'], base['ki_angle'])
    nominal = PamModel(params=load_parameters('default'), valve_map=load_valve_map('default'))
    true = PamModel(params=load_scenario('realistic').apply(nominal.params),
                    valve_map=nominal.valve_map)
    models = {'nominal': (nominal, NO_EXTENSIONS, DEFAULT_TUNING),
              'identified': (true, NO_EXTENSIONS, DEFAULT_TUNING)}
    first = batch_comparison('realistic', models, settings, 10.0, 0)
    assert batch_comparison('realistic', models, settings, 10.0, 0) == first
    for run in ('nominal', 'identified'):
        r = first[run]
        assert r['mode'] == 'angle' and len(r['steps']) == 2, r
        assert r['worst_steady_state_error_pct'] == max(s['steady_state_error_pct']
                                                        for s in r['steps'])
        assert 0.0 < r['estimation']['whole']['Q_pct'] < 100.0, r
    lines = comparison_lines(first)
    assert lines[1].startswith('nominal') and lines[2].startswith('identified'), lines
    assert len(lines) == 3 + 2 + 2, lines


def test_the_demo_runs_the_workflow_and_stops_the_stack(node_process, ros_domain, tmp_path):
    out = tmp_path / 'out'
    demo = node_process('pam-demo', 'pam_bringup', '--campaign', 'quick', '--duration',
                        f'{DURATION:g}', '--out', str(out), '--domain-id', str(ros_domain),
                        raw=True)
    code = demo.wait_exit(timeout=180.0 + STARTUP_TIMEOUT + DURATION + 2 * STOP_TIMEOUT)
    stdout = demo.stdout
    summary = json.loads((out / 'demo_summary.json').read_text())
    # a run that was not real time (a loaded machine) is INVALID: exit 1, said so, never a result
    if summary['valid']:
        assert code == 0, stdout + demo.stderr
        assert 'INVALID' not in stdout + demo.stderr, stdout + demo.stderr
    else:
        assert code == 1, stdout + demo.stderr
        assert 'demo: INVALID: the real-time run was not real time on this machine (' in \
            demo.stderr, demo.stderr
        assert summary['realtime']['health']['valid'] is False, summary['realtime']
    assert stdout.startswith(f"demo: scenario 'realistic', campaign 'quick'; "
                             f'ROS_DOMAIN_ID={ros_domain}; logs in {out}/logs/\n'), stdout
    # the machine's timer floor, measured just before the real-time run, printed and kept
    assert 'demo: this machine now: a bare 1000 Hz sleep loop (' in stdout, stdout
    assert summary['timer_floor']['deadlines'] == 3000, summary['timer_floor']
    # and the models' compute per sample on this machine, with the identified model
    assert "demo: this machine now: the models' compute per sample (the 'realistic' rig, the " \
        f"identified ({out / 'demo' / 'identified'}) UKF, PI): " in stdout, stdout
    cost = summary['model_cost']
    assert cost['scenario'] == 'realistic' and cost['model'].startswith('identified'), cost
    assert 0.0 < cost['back_to_back'] == cost['sim'] + cost['ukf'] + cost['pi'], cost
    assert 0.0 < cost['paced'] < 1e-3, cost
    for step in ('1/4 calibration campaign', '2/4 identification', '3/4 batch comparison',
                 '4/4 real-time sensor-less tracking with the identified model'):
        assert f'demo: {step}' in stdout, stdout
    # the campaign's bags and the identified model the identified stack ran with
    bags = sorted(p.name for p in (out / 'demo' / 'calibration').iterdir())
    assert bags == ['free', 'locked_m15deg', 'locked_p15deg'], bags
    identified = out / 'demo' / 'identified'
    params = (out / 'demo' / 'bringup_identified.yaml').read_text()
    assert str(identified / 'params.yaml') in params and 'scenario: realistic' in params
    assert not (out / 'demo' / 'bringup_nominal.yaml').exists()
    extensions = load_extensions(identified / 'extensions.yaml').describe()
    assert f'model extensions: {extensions}' in (
        out / 'logs' / 'identified' / 'pam_container.log').read_text()
    assert not (out / 'logs' / 'nominal').exists()
    # the batch comparison: both models, worst figures and every step
    assert re.search(r'^  nominal +\d+\.\d\d % +\d+\.\d\d s', stdout, flags=re.MULTILINE), stdout
    assert re.search(r'^  identified +\d+\.\d\d % +\d+\.\d\d s', stdout,
                     flags=re.MULTILINE), stdout
    for run in ('nominal', 'identified'):
        batch = summary['comparison'][run]
        assert batch['mode'] == 'angle' and batch['steps'], batch
        assert batch['worst_steady_state_error_pct'] == max(
            s['steady_state_error_pct'] for s in batch['steps'])
        assert f"{batch['worst_steady_state_error_pct']:.2f} %" in stdout
    # the one real-time run, its report and its health
    assert '=== real-time run, identified model ===' in stdout, stdout
    assert re.search(r'^\[INFO\] \[[\d.]+\] \[identified.tracking_report\]', stdout,
                     flags=re.MULTILINE), stdout
    assert len(re.findall(r'^tracking report: angle mode, \d+\.\d s, \d+ samples', stdout,
                          flags=re.MULTILINE)) == 1, stdout
    assert 'estimation error after t >= 1 s' in stdout, stdout     # --transient's default
    assert re.search(r'^  real-time health: \d+ of \d+ samples received \(\d+ lost\), rig: '
                     r'\d+ late samples', stdout, flags=re.MULTILINE), stdout
    assert (out / 'demo_tracking.png').stat().st_size > 10_000
    assert not (out / 'demo_tracking_nominal.png').exists()
    report = summary['realtime']
    assert report['mode'] == 'angle' and report['steps'], report
    assert report['health']['valid'] is summary['valid'] is report['valid'], report['health']
    assert report['health']['samples_sent'] > 0, report['health']
    for key in ('whole', 'after_transient'):
        m = report['estimation'][key]
        assert 0.0 < m['I'] <= m['M'] and 0.0 < m['Q_pct'] < 100.0, m

    log = (out / 'logs' / 'bringup_identified.log').read_text()
    started = dict(re.findall(r'started (\w+) \(.*?\), pid (\d+):', log))
    assert set(started) == {'pam_container'}, log          # pam-bringup's default: composed
    assert (out / 'logs' / 'identified' / 'pam_container.log').stat().st_size > 0
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
