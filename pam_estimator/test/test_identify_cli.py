"""pam-calibration-bags and pam-identify as a user runs them, on bags of the simulated 'mild'
plant; the identified files loaded by pam-evaluate's computation and by ukf_node; bad bags.

The campaign is a short version of the default (8 hold voltages, lock angles -15/+15 deg, 30 s
free run): about 4 min of simulated rig in bags. Tolerances as in pam_model's identification
tests (the fits are the same; here the path through bags and files is under test).
"""

import shutil
import subprocess

import numpy as np
import pytest
import yaml

from pam_bag.bags import BagWriter, load_bag
from pam_common.testing import executable
from pam_estimator.bag_runs import load_run
from pam_estimator.calibration_runs import identified_tuning
from pam_estimator.evaluation import evaluate
from pam_estimator.noise_choice import CANDIDATES
from pam_estimator.pam_ukf import TUNINGS
from pam_model.identification.force_fit import intercept_combinations
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.model_extensions import NO_EXTENSIONS, load_extensions
from pam_model.parameters import load_parameters
from pam_model.valve_map import load_valve_map

CAMPAIGN = ('--angles=-15,15', '--voltages', '0,2,4,5,5.5,6,7,10', '--free-duration', '30',
            '--seed', '3', '--validation', '20', '--mismatch', 'mild')
CALIBRATION = ('locked_m15deg', 'locked_p15deg', 'free')


def run(*args):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=600)


def identify(*args):
    return run(executable('pam-identify', 'pam_estimator'), *args)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    out = tmp_path_factory.mktemp('campaign') / 'bags'
    result = run(executable('pam-calibration-bags', 'pam_estimator'), out, *CAMPAIGN)
    assert result.returncode == 0, result.stderr
    for name in (*CALIBRATION, 'validation_free', 'validation_locked'):
        assert (out / name / 'metadata.yaml').is_file(), name
    return out


@pytest.fixture(scope='module')
def identified(bags, tmp_path_factory):
    out = tmp_path_factory.mktemp('identified') / 'result'
    result = identify(*(bags / n for n in CALIBRATION), '-o', out, '--truth-mismatch', 'mild')
    assert result.returncode == 0, result.stderr + result.stdout
    return out, result.stdout


def test_identify_recovers_the_plant_and_writes_loadable_files(identified):
    out, stdout = identified
    for group in ('[valve_map]', '[forces]', '[flow]', '[friction]'):
        assert group in stdout
    assert f'wrote {out}/params.yaml' in stdout and 'model_parameters:=' in stdout
    assert '[friction]' in (out / 'report.txt').read_text()
    params = load_parameters(out / 'params.yaml')
    truth = load_scenario('mild').apply(load_parameters())
    for f in ('p_v1_1', 'p_v2_1', 'p_v1_2', 'p_v2_2'):
        assert abs(getattr(params, f) / getattr(truth, f) - 1.0) < 0.005, f
    assert abs(intercept_combinations(params)[0] - intercept_combinations(truth)[0]) < 0.1
    assert abs(params.k1 * params.A1_1 / (truth.k1 * truth.A1_1) - 1.0) < 0.02
    assert abs(params.mu_s / truth.mu_s - 1.0) < 0.03
    kappa = load_valve_map(out / 'kappa.csv')
    np.testing.assert_allclose(kappa.alpha, load_valve_map()(kappa.u), atol=0.005)
    # the UKF's velocity process noise chosen on the free run: tuning.yaml, the report, the
    # ukf_node line
    tuning = identified_tuning(out)
    report = (out / 'report.txt').read_text()
    assert 'UKF velocity process noise' in report and '<- chosen' in report
    assert tuning.Q[1] in (TUNINGS['default'].Q[1], *CANDIDATES)
    assert f'chosen {tuning.Q[1]:.0e} (rad/s)^2' in report
    assert tuning._replace(Q=TUNINGS['default'].Q) == TUNINGS['default']
    assert 'process_noise:=' in stdout and f'--tuning {out}/tuning.yaml' in stdout
    # ROS reads the printed list as doubles only when every entry is written as one
    printed = yaml.safe_load(stdout.split('process_noise:="')[1].split('"')[0])
    assert printed == list(tuning.Q) and all(isinstance(q, float) for q in printed), printed


def test_the_extensions_file_is_written_and_empty_for_a_plant_without_effects(bags, identified,
                                                                              tmp_path):
    """extensions.yaml beside params.yaml, read as ukf_node reads it: no extension on 'mild'
    (each fit says why in the report); --no-extensions gives the same parameters, no extension
    fit in the report."""
    out, stdout = identified
    assert load_extensions(out / 'extensions.yaml') == NO_EXTENSIONS
    assert 'model_extensions:=' in stdout and '--extensions' in stdout
    report = (out / 'report.txt').read_text()
    for group in ('[sensors]', '[hysteresis]', '[valve lag]'):
        assert group in report
    assert 'extensions kept (extensions.yaml): none' in report
    paper = tmp_path / 'paper'
    result = identify(*(bags / n for n in CALIBRATION), '-o', paper, '--no-extensions',
                      '--no-velocity-noise')
    assert result.returncode == 0, result.stderr
    assert not (paper / 'tuning.yaml').exists() and 'process_noise:=' not in result.stdout
    assert load_parameters(paper / 'params.yaml') == load_parameters(out / 'params.yaml')
    assert load_extensions(paper / 'extensions.yaml') == NO_EXTENSIONS
    assert '[hysteresis]' not in (paper / 'report.txt').read_text()


def test_the_identified_model_beats_the_nominal_one_on_a_validation_bag(bags, identified):
    out, _ = identified
    params, kappa = load_parameters(out / 'params.yaml'), load_valve_map(out / 'kappa.csv')
    for mode in ('free', 'locked'):
        record = load_run(bags / f'validation_{mode}')
        q = {}
        for label, p, k in (('nominal', load_parameters(), load_valve_map()),
                            ('identified', params, kappa)):
            table, _, _ = evaluate(record, PamModel(params=p, valve_map=k, locked=record.locked),
                                   TUNINGS['default'])
            q[label] = table['ukf'].Q
        assert q['identified'] < 0.01 and q['identified'] < 0.3 * q['nominal'], (mode, q)
    result = run(executable('pam-evaluate', 'pam_estimator'), '--params', out / 'params.yaml',
                 '--kappa', out / 'kappa.csv', '--tuning', out / 'tuning.yaml',
                 bags / 'validation_free')
    assert result.returncode == 0, result.stderr
    assert f"tuning '{out}/tuning.yaml'" in result.stdout
    result = run(executable('pam-evaluate', 'pam_estimator'), '--tuning', out / 'nothing.yaml',
                 bags / 'validation_free')
    assert result.returncode != 0 and 'neither a preset (default, paper) nor a file' in (
        result.stderr + result.stdout), result.stderr


def test_ukf_node_loads_the_identified_files(identified, node_process):
    out, _ = identified
    ukf = node_process('ukf_node', 'pam_estimator', '--ros-args', '-p',
                       f'model_parameters:={out}/params.yaml', '-p', f'valve_map:={out}/kappa.csv')
    ukf.wait_for(lambda: 'estimating:' in ukf.stderr + ukf.stdout, 60.0, 'ukf_node start')
    assert f'{out}/params.yaml' in ukf.stderr + ukf.stdout
    assert ukf.alive()


def test_missing_runs_are_named_and_nothing_is_written(bags, tmp_path):
    out = tmp_path / 'result'
    result = identify(bags / 'free', '-o', out)
    assert result.returncode == 2
    assert 'kappa(u) needs settled static holds' in result.stderr
    assert 'force coefficients need a locked-joint run' in result.stderr
    assert 'pam1.p_v1' in result.stderr and 'nothing written' in result.stderr
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_partial_identification_keeps_the_prior_where_it_must(bags, tmp_path):
    out = tmp_path / 'result'
    result = identify(bags / 'locked_m15deg', bags / 'locked_p15deg', '-o', out, '--partial')
    assert result.returncode == 0, result.stderr
    assert 'NOT identified' in result.stdout and 'PARTIAL' in result.stdout
    params, prior = load_parameters(out / 'params.yaml'), load_parameters()
    assert params.mu_s == prior.mu_s and params.k2 == prior.k2
    assert params.p_v1_1 != prior.p_v1_1


def test_a_bag_without_valve_commands_is_refused(bags, tmp_path):
    source = load_bag(bags / 'free', topics=['/pam/pressures', '/pam/joint_measured'])
    writer = BagWriter(tmp_path / 'no_commands')
    for topic, msgtype in source.topics.items():
        writer.add_topic(topic, msgtype)
    for t, i, data in zip(source.times, source.topic_index, source.data, strict=True):
        writer.write(source.topic_names[i], t, data)
    writer.close()
    result = identify(tmp_path / 'no_commands', '-o', tmp_path / 'result')
    assert result.returncode == 2
    assert 'no /pam/valve_command messages' in result.stderr
    assert not (tmp_path / 'result').exists()


def test_a_truncated_bag_is_refused_with_its_name(bags, tmp_path):
    broken = tmp_path / 'broken'
    shutil.copytree(bags / 'free', broken)
    mcap = broken / 'free.mcap'
    mcap.write_bytes(mcap.read_bytes()[:mcap.stat().st_size // 2])
    result = identify(broken, '-o', tmp_path / 'result')
    assert result.returncode == 2
    assert 'error:' in result.stderr and str(broken) in result.stderr
    assert not (tmp_path / 'result').exists()


def test_an_existing_output_is_never_overwritten(bags, tmp_path):
    out = tmp_path / 'result'
    out.mkdir()
    (out / 'params.yaml').write_text('mine\n')
    result = identify(*(bags / n for n in CALIBRATION), '-o', out)
    assert result.returncode == 2 and 'already exists' in result.stderr
    assert (out / 'params.yaml').read_text() == 'mine\n'


def copy_bag(source_dir, target, keep):
    """A copy of a bag holding the messages for which keep(topic, index within topic) is true."""
    source = load_bag(source_dir)
    writer = BagWriter(target)
    for topic, msgtype in source.topics.items():
        writer.add_topic(topic, msgtype)
    seen = {}
    for t, i, data in zip(source.times, source.topic_index, source.data, strict=True):
        topic = source.topic_names[i]
        seen[topic] = seen.get(topic, -1) + 1
        if keep(topic, seen[topic]):
            writer.write(topic, t, data)
    writer.close()
    return target


def test_samples_before_the_first_command_are_left_out(bags, tmp_path):
    from pam_estimator.calibration_runs import load_record
    full = load_record(bags / 'free')
    late = copy_bag(bags / 'free', tmp_path / 'late_commands',
                    lambda topic, k: topic != '/pam/valve_command' or k >= 1500)
    record = load_record(late)
    assert len(record.t) == len(full.t) - 1500
    np.testing.assert_array_equal(record.u, full.u[1500:])
    np.testing.assert_array_equal(record.P, full.P[1500:])


def test_a_locked_run_whose_encoder_jitters_still_reads_as_locked(tmp_path):
    from pam_estimator.bag_runs import write_run_bag
    from pam_model.calibration_profiles import locked_calibration_profile
    from pam_model.simulate import simulate
    profile = locked_calibration_profile(hold=0.0, pair_hold=2.0, voltages=(0.0, 5.0, 10.0))
    run = simulate(PamModel(locked=True), profile.u, np.array([0.2, 0.0, 4.5e5, 4.5e5]))
    run.x[:, 0] += np.random.default_rng(0).integers(-1, 2, len(run.t)) * 2 * np.pi / 4096
    locked = load_run(write_run_bag(run, tmp_path / 'jitter'))
    assert locked.locked                      # one count of a 4096-count encoder either way
    run.x[::2, 0] += np.radians(0.5)          # a joint that moves is free
    assert not load_run(write_run_bag(run, tmp_path / 'moving')).locked
