"""pam-evaluate as a user runs it on a run written by pam-simulate, and the params files."""

import subprocess

from pam_common.testing import executable, installed_config


def run(*args):
    return subprocess.run(list(args), capture_output=True, text=True, timeout=300)


def test_pam_evaluate_prints_the_table_and_writes_figures(tmp_path):
    simulate = executable('pam-simulate', 'pam_model')
    evaluate = executable('pam-evaluate', 'pam_estimator')
    runs = []
    for name, extra in (('free', []), ('locked', ['--locked'])):
        path = tmp_path / f'{name}.npz'
        result = run(simulate, '-o', str(path), '--duration', '8', '--mismatch', 'mild', *extra)
        assert result.returncode == 0, result.stderr
        runs.append(str(path))
    result = run(evaluate, *runs, '--plots', str(tmp_path / 'plots'), '--compare-models')
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert 'angle (deg)' in out and 'torque (N m)' in out
    assert out.count('model alone') >= 2 and '6.13 %' in out and '4.94 %' in out
    assert 'friction tondu' in out and 'force no_offset' in out
    for png in ('free_angle.png', 'locked_torque.png'):
        assert (tmp_path / 'plots' / png).stat().st_size > 10_000


def test_pam_evaluate_rejects_a_missing_file(tmp_path):
    result = run(executable('pam-evaluate', 'pam_estimator'), str(tmp_path / 'none.npz'))
    assert result.returncode == 2 and 'error:' in result.stderr


def test_shipped_params_files_are_accepted(node_process):
    for name in ('ukf_node.yaml', 'ukf_node_paper.yaml'):
        ukf = node_process('ukf_node', 'pam_estimator', '--params-file',
                           installed_config(name, 'pam_estimator'))
        ukf.wait_for(lambda ukf=ukf: 'estimating:' in ukf.stderr + ukf.stdout, 60.0,
                     f'start with {name}')
        assert ukf.alive()
