"""pam-evaluate and pam-identify on a damaged bag: 8 bytes flipped in chunk 1 where zstd still
decompresses (only the chunk's CRC shows it; before bags carried CRCs, pam-evaluate printed
`model alone inf` and pam-identify wrote a parameter file). Each refuses with one error line
naming the chunk, exit code 2 (docs/stopping.md, Exit codes), and writes nothing."""

import subprocess

import numpy as np
import pytest

from pam_bag.testing import damage_chunk
from pam_common.testing import executable

BAD_INPUT = 2


def run(*args):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope='module')
def damaged(tmp_path_factory):
    """A bag of 8 s of a simulated free run (pressures, commands, truth: 24000 messages in at
    least two chunks) with chunk 1 damaged."""
    from pam_estimator.bag_runs import write_run_bag
    from pam_model.model import PamModel
    from pam_model.profiles import validation_profile
    from pam_model.simulate import simulate
    model = PamModel()
    profile = validation_profile(1, 8.0, model.h)
    result = simulate(model, profile.u, np.array([0.0, 0.0, 4.5e5, 4.5e5]))
    bag = write_run_bag(result, tmp_path_factory.mktemp('damaged') / 'run')
    damage_chunk(bag / 'run.mcap', 1)
    return bag


def assert_refused(out, bag):
    assert out.returncode == BAD_INPUT, out.stdout + out.stderr
    lines = out.stderr.splitlines()
    assert len(lines) == 1 and 'Traceback' not in out.stderr, out.stderr
    assert lines[0].startswith(f'error: {bag / "run.mcap"}: corrupt data after '), lines[0]
    assert 'run.mcap: chunk 1 at byte ' in lines[0] and 'CRC mismatch' in lines[0], lines[0]


def test_pam_evaluate_refuses_a_damaged_bag(damaged):
    out = run(executable('pam-evaluate', 'pam_estimator'), damaged)
    assert_refused(out, damaged)
    assert 'model alone' not in out.stdout


def test_pam_identify_refuses_a_damaged_bag_and_writes_nothing(damaged, tmp_path):
    out = run(executable('pam-identify', 'pam_estimator'), damaged, '-o', tmp_path / 'result')
    assert_refused(out, damaged)
    assert not (tmp_path / 'result').exists()
