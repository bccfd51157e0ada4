"""pam-calibration-bags --plan, run as a user runs it: the planned runs and the expected 1-sigma
of every parameter pam-identify would fit, before anything runs on a rig; nothing written."""

import subprocess

from pam_common.testing import executable

SHORT = ['--angles=-15,15', '--hold', '3', '--pair-hold', '2', '--free-duration', '20']


def run(*args, cwd):
    tool = str(executable('pam-calibration-bags', 'pam_estimator'))
    return subprocess.run([tool, *args], cwd=cwd, capture_output=True, text=True, timeout=300,
                          check=False)


def test_the_plan_prints_the_runs_and_the_expected_uncertainties(tmp_path):
    done = run('--plan', *SHORT, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert 'pam-calibration-bags --plan: 3 runs, 180 s of rig time' in out
    assert "read through the sensor of 'mild' (noise 2000 Pa, 12-bit ADC)" in out
    assert 'expected 1 sigma' in out
    line = next(x for x in out.splitlines() if x.strip().startswith('mu_s'))
    assert line.split()[-1].endswith('%')               # a relative 1-sigma
    assert 'not identifiable with this campaign' in out and 'k2' in out
    assert list(tmp_path.iterdir()) == []               # nothing written


def test_without_out_or_plan_it_says_what_is_missing(tmp_path):
    done = run(*SHORT, cwd=tmp_path)
    assert done.returncode == 2
    assert 'OUT is required (or --plan)' in done.stderr
