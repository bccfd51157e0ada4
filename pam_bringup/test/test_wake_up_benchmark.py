"""benchmarks/wake_up.c: the CPU one 1 kHz wake-up costs this machine in C, beside the same loop
in Python (pam_bringup.model_cost's wake_up), compiled and run as docs/benchmarks.md says."""

import re
import shutil
import subprocess
import time
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parents[2] / 'benchmarks' / 'wake_up.c'


@pytest.fixture(scope='module')
def wake_up(tmp_path_factory):
    if shutil.which('gcc') is None:
        pytest.skip('no gcc on this machine')
    binary = tmp_path_factory.mktemp('wake_up') / 'wake_up'
    subprocess.run(['gcc', '-O2', '-Wall', '-Werror', '-o', str(binary), str(SOURCE)],
                   check=True, capture_output=True, text=True)
    return binary


def test_it_sleeps_to_each_deadline_and_prints_the_cpu_per_wake_up(wake_up):
    start = time.monotonic()
    done = subprocess.run([str(wake_up), '300'], capture_output=True, text=True, timeout=30)
    took = time.monotonic() - start
    assert done.returncode == 0, done.stderr
    match = re.fullmatch(r'a 1 kHz wake-up in C: (\d+\.\d) us of CPU each \(300 deadlines\)\n',
                         done.stdout)
    assert match, done.stdout
    assert 0.0 < float(match.group(1)) < 1000.0     # CPU per wake-up, not the period
    assert took >= 0.299                             # 300 deadlines 1 ms apart: it slept


@pytest.mark.parametrize('args', [['0'], ['-5'], ['10', '20']])
def test_a_bad_count_is_refused(wake_up, args):
    done = subprocess.run([str(wake_up), *args], capture_output=True, text=True, timeout=10)
    assert done.returncode == 2 and 'usage:' in done.stderr
