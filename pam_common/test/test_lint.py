"""The repository passes its linter: `ruff check` with the root ruff.toml (rule selection and
each deliberate exception, with its reason, are there) over every Python file of the repository:
the packages and their tests, launch files, benchmarks/, scripts/ and conftest.py.

ruff is a test dependency of pam_common (rosdep key python3-ruff-pip); the venv pins it in
requirements.txt. Not installed, these tests fail and say how to install it: they do not skip.
The repository is found from this file, so the tests run the same from the venv (pytest) and
from colcon test (which runs them in the source tree). No cache is written (--no-cache).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / 'ruff.toml'
#: Top-level folders ruff.toml excludes (data, output, the venv and builds).
NOT_LINTED = {'.venv', 'build', 'bags', 'out', 'install', 'log'}
TIMEOUT = 120       # s (a whole-repository check takes well under a second)


def pinned_version() -> str:
    """The ruff version requirements.txt pins ('' if it pins none)."""
    found = re.search(r'^ruff==(\S+)', (ROOT / 'requirements.txt').read_text(), re.MULTILINE)
    return found.group(1) if found else ''


def ruff_executable() -> str:
    """The ruff binary: the one of the `ruff` Python package (pip, the venv, python3-ruff-pip),
    else a `ruff` on PATH; fails the test with how to install it if there is none."""
    try:
        from ruff import find_ruff_bin
        return str(find_ruff_bin())
    except (ImportError, FileNotFoundError):
        found = shutil.which('ruff')
    if found is None:
        pytest.fail(f'ruff is not installed: it is a test dependency of pam_common (rosdep key '
                    f'python3-ruff-pip: rosdep install --from-paths <src> installs it; or pip '
                    f'install ruff=={pinned_version()}, the version requirements.txt pins)',
                    pytrace=False)
    return found


def ruff(*args: str) -> subprocess.CompletedProcess:
    """`ruff <args>` with the repository's configuration, run from the repository root."""
    return subprocess.run([ruff_executable(), *args, '--no-cache', '--config', str(CONFIG)],
                          cwd=ROOT, text=True, capture_output=True, timeout=TIMEOUT)


def findings(*paths: Path) -> list[str]:
    """One line per `ruff check` finding in `paths` (file:line:col: code message)."""
    run = ruff('check', '--output-format', 'concise', '--quiet', *map(str, paths))
    assert run.returncode in (0, 1), f'ruff check: exit {run.returncode}\n{run.stderr}'
    assert run.returncode == 0 or run.stdout.strip(), f'ruff check failed silently\n{run.stderr}'
    return run.stdout.splitlines()


def version() -> str:
    return ruff('--version').stdout.split()[-1]


def test_the_repository_passes_ruff():
    problems = findings(ROOT)
    pinned = pinned_version()
    assert not problems, (
        f'{len(problems)} ruff finding(s): fix them (`ruff check --fix` applies the safe fixes) '
        'or, if the code is right, add a `# noqa: <code> - <reason>` on the line or an entry '
        f'with its reason in ruff.toml\n' + '\n'.join(problems)
        + ('' if version() == pinned else
           f'\n(ruff {version()} ran; requirements.txt pins {pinned}: other versions may differ)'))


def test_ruff_lints_every_python_file_of_the_repository():
    """A misplaced exclude would pass every check above by looking at nothing."""
    listed = ruff('check', '--show-files', str(ROOT))
    assert listed.returncode == 0, listed.stderr
    linted = {Path(line).relative_to(ROOT) for line in listed.stdout.splitlines()
              if line.endswith('.py')}
    present = {path.relative_to(ROOT)
               for top in ROOT.iterdir() if top.name not in NOT_LINTED and top.name[0] != '.'
               for path in ([top] if top.is_file() else top.rglob('*.py'))
               if path.suffix == '.py' and '__pycache__' not in path.parts}
    assert not present - linted, f'not linted: {sorted(map(str, present - linted))}'
    parts = {p.parts[0] for p in linted}
    assert {'benchmarks', 'scripts', 'conftest.py', 'pam_common', 'pam_bringup'} <= parts
    assert Path('pam_common/test/test_lint.py') in linted
    assert any(p.match('pam_bringup/launch/*.launch.py') for p in linted)


def test_the_check_reports_a_finding(tmp_path):
    """A bad source fails it: an unused import (F401), imports out of order (I001), a bare
    zip() (B905), each named with its file and line."""
    bad = tmp_path / 'bad.py'
    bad.write_text('import sys\nimport os\n\nprint(list(zip(os.sep, os.sep)))\n')
    found = findings(bad)
    assert any(f'{bad}:1:8: F401' in line for line in found), found
    assert any(f'{bad}:1:1: I001' in line for line in found), found
    assert any(f'{bad}:4:12: B905' in line for line in found), found
    (tmp_path / 'good.py').write_text('import os\n\nprint(list(zip(os.sep, os.sep, '
                                      'strict=True)))\n')
    assert findings(tmp_path / 'good.py') == []
