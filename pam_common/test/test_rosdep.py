"""rosdep resolves every key of every package.xml for ROS 2 Jazzy on Ubuntu 24.04 (noble), as
`rosdep install --from-paths src --ignore-src` does on an apt install: the real rosdep (PyPI),
pointed at the copy of the rosdistro files in ../shared/rosdistro (the Jazzy distribution file,
the base and python rosdep keys; skipped when the copy is not there) plus the repository's own
rosdep/pam.yaml, with file:// URLs only (a proxy that goes nowhere stops any other access).
Building and running the stack needs no key of rosdep/pam.yaml but pam-foxglove's (RUN_TIME_OWN):
its other build and exec dependencies resolve without it (only the tests' do not)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
import rosdep2

ROOT = Path(__file__).resolve().parents[2]
ROSDISTRO = ROOT.parent / 'shared' / 'rosdistro'
OWN_KEYS = ROOT / 'rosdep' / 'pam.yaml'
PACKAGES = sorted(p.parent for p in ROOT.glob('*/package.xml'))
TARGET = ['--rosdistro', 'jazzy', '--os', 'ubuntu:noble']
TIMEOUT = 120       # s per rosdep command (about 3 s each on an idle machine)
#: The run-time keys of rosdep/pam.yaml: foxglove-sdk (PyPI), pam_bringup's pam-foxglove.
RUN_TIME_OWN = ['python3-foxglove-sdk-pip']

pytestmark = pytest.mark.skipif(
    not (ROSDISTRO / 'jazzy' / 'distribution.yaml').is_file(),
    reason=f'no rosdistro copy at {ROSDISTRO} (jazzy/distribution.yaml, rosdep/*.yaml)')

INDEX = """%YAML 1.1
---
distributions:
  jazzy:
    distribution: [{url}]
    distribution_status: active
    distribution_type: ros2
    python_version: 3
type: index
version: 4
"""


def rosdep_home(folder: Path, own_keys: bool) -> dict:
    """The environment of a rosdep whose sources are the rosdistro copy (+ rosdep/pam.yaml if
    `own_keys`), its cache in `folder`, after its `rosdep update`."""
    sources = folder / 'sources.list.d'
    sources.mkdir(parents=True)
    (sources / '20-default.list').write_text(
        ''.join(f'yaml {(ROSDISTRO / "rosdep" / name).as_uri()}\n'
                for name in ('base.yaml', 'python.yaml')))
    if own_keys:
        (sources / '50-pam.list').write_text(f'yaml {OWN_KEYS.as_uri()}\n')
    index = folder / 'index.yaml'
    index.write_text(INDEX.format(url=(ROSDISTRO / 'jazzy' / 'distribution.yaml').as_uri()))
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(('ROS', 'AMENT_', 'COLCON_'))}   # the venv's ament index would
    env.update(ROSDEP_SOURCE_PATH=str(sources), ROS_HOME=str(folder / 'ros_home'),   # hide keys
               ROSDISTRO_INDEX_URL=index.as_uri(), ROS_DISTRO='jazzy', ROS_PYTHON_VERSION='3',
               http_proxy='http://127.0.0.1:9', https_proxy='http://127.0.0.1:9',
               HTTP_PROXY='http://127.0.0.1:9', HTTPS_PROXY='http://127.0.0.1:9',
               no_proxy='', NO_PROXY='')
    rosdep(env, 'update', '--rosdistro', 'jazzy')
    return env


def rosdep(env: dict, *args: str) -> str:
    """stdout of `rosdep <args>`; fails the test with rosdep's output if it fails."""
    run = subprocess.run([sys.executable, '-m', 'rosdep2', *args], env=env, text=True,
                         capture_output=True, timeout=TIMEOUT)
    assert run.returncode == 0, f'rosdep {" ".join(args)}: exit {run.returncode}\n' \
                                f'{run.stdout}{run.stderr}'
    return run.stdout


def resolve(env: dict, keys) -> dict:
    """key -> (installer, [packages]) for Jazzy on noble, through `rosdep resolve`."""
    out = rosdep(env, 'resolve', *keys, *TARGET)
    found, key = {}, None
    for line in out.splitlines():
        if line.startswith('#ROSDEP['):
            key = line[len('#ROSDEP['):-1]
        elif line.startswith('#') and key:
            found[key] = (line[1:], [])
        elif line.strip() and key:
            found[key][1].extend(line.split())
    return found


def keys(env: dict, *options: str) -> list[str]:
    """The keys of every package.xml but the workspace's own packages (`rosdep keys`)."""
    out = rosdep(env, 'keys', '--from-paths', *map(str, PACKAGES), '--ignore-src', *options)
    return sorted(out.split())


@pytest.fixture(scope='module')
def with_own_keys(tmp_path_factory):
    return rosdep_home(tmp_path_factory.mktemp('rosdep'), own_keys=True)


@pytest.fixture(scope='module')
def public_only(tmp_path_factory):
    return rosdep_home(tmp_path_factory.mktemp('rosdep'), own_keys=False)


def test_rosdep_install_simulates_every_package(with_own_keys):
    """The apt user's command, simulated: every key resolves (it exits 1 naming the packages
    and keys it cannot resolve otherwise)."""
    out = rosdep(with_own_keys, 'install', '--from-paths', *map(str, PACKAGES), '--ignore-src',
                 '--simulate', '--reinstall', '-y', *TARGET)
    assert 'apt-get install' in out and 'ros-jazzy-rclpy' in out, out


def test_every_key_resolves_to_apt_or_pip(with_own_keys):
    wanted = keys(with_own_keys)
    assert 'rclpy' in wanted and 'python3-numpy' in wanted
    assert not {p.name for p in PACKAGES} & set(wanted), 'workspace packages are not keys'
    found = resolve(with_own_keys, wanted)
    assert sorted(found) == wanted
    bad = {k: v for k, v in found.items() if v[0] not in ('apt', 'pip') or not v[1]}
    assert not bad, bad
    # ROS packages resolve to Jazzy's apt packages, *-pip keys to PyPI
    assert found['rclpy'] == ('apt', ['ros-jazzy-rclpy'])
    assert all(v[0] == 'pip' for k, v in found.items() if k.endswith('-pip'))


BUILD_AND_RUN = [f'--dependency-types={kind}' for kind in
                 ('buildtool', 'build', 'buildtool_export', 'build_export', 'exec')]


def test_building_and_running_needs_no_key_of_our_own(public_only):
    """Build and exec dependencies resolve with the public rosdistro alone, but for the run-time
    keys of rosdep/pam.yaml (RUN_TIME_OWN: pam-foxglove's foxglove-sdk): building and running
    the rest of the stack needs no rosdep/pam.yaml (only the tests do)."""
    wanted = keys(public_only, *BUILD_AND_RUN)
    assert 'ament_cmake' in wanted and 'rclpy' in wanted
    assert set(RUN_TIME_OWN) <= set(wanted)
    public = [key for key in wanted if key not in RUN_TIME_OWN]
    assert sorted(resolve(public_only, public)) == public
    rosdep(public_only, 'install', '--from-paths', *map(str, PACKAGES), '--ignore-src',
           '--simulate', '--reinstall', '-y', *BUILD_AND_RUN, '--skip-keys',
           ' '.join(RUN_TIME_OWN), *TARGET)


def test_without_our_keys_rosdep_names_what_is_missing(public_only):
    """The check is real: a key nobody defines makes `rosdep resolve` fail, naming it."""
    run = subprocess.run([sys.executable, '-m', 'rosdep2', 'resolve', 'python3-mcap-pip',
                          *TARGET], env=public_only, text=True, capture_output=True,
                         timeout=TIMEOUT)
    assert run.returncode != 0
    assert 'python3-mcap-pip' in run.stdout + run.stderr


def test_rosdep_is_the_pinned_one():
    assert rosdep2.__version__ == '0.27.0'
