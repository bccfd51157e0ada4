"""A node or tool stopped while it is still importing (a Ctrl-C at start-up, or pam-bringup
stopping a node that has not started yet) exits at once and silently with 128 + the signal
number, which pam-bringup counts as a clean stop (it printed a 50-line KeyboardInterrupt
traceback from inside numba's or rclpy's import). Real console scripts, real signals, sent
while the process is inside its imports: once numpy's C extension is mapped, with rclpy, numba
and the project's modules still to come (0.5 s or more)."""

import signal
import subprocess
import time
from pathlib import Path

import pytest

from pam_bringup.supervisor import CLEAN_STOP_CODES
from pam_common.testing import child_env, executable
from pam_model.cli.startup import exit_code_for

IMPORTING = '_multiarray_umath'     # numpy's C extension: the imports are under way


def mapped(pid: int, name: str) -> bool:
    try:
        return name in Path(f'/proc/{pid}/maps').read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False


@pytest.mark.parametrize('name, package, sig', [
    ('ukf_node', 'pam_estimator', signal.SIGINT),
    ('ukf_node', 'pam_estimator', signal.SIGTERM),
    ('pi_node', 'pam_controller', signal.SIGINT),
    ('pam-evaluate', 'pam_estimator', signal.SIGINT),
])
def test_a_stop_during_the_imports_is_quiet(name, package, sig, ros_domain, tmp_path):
    proc = subprocess.Popen([executable(name, package)], env=child_env(ros_domain),
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 60.0
        while not mapped(proc.pid, IMPORTING):
            assert proc.poll() is None and time.monotonic() < end, 'never started importing'
            time.sleep(0.001)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=30.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert (proc.returncode, out, err) == (exit_code_for(sig), b'', b'')
    assert proc.returncode == 128 + sig and proc.returncode in CLEAN_STOP_CODES
