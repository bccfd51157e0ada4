"""pam_common.executables: an executable is found where the ament index says its package is
installed (colcon/apt: <prefix>/lib/<package>/; pip into the venv: <prefix>/bin/), as `ros2 run`
finds it. Real prefixes on disk, found through a real AMENT_PREFIX_PATH."""

from pathlib import Path

from pam_common.executables import executable_candidates, find_executable


def make_prefix(root: Path, package: str, executable: str | None, where: str) -> Path:
    """An install prefix indexing `package`, with `executable` in lib/<package>/ or bin/."""
    marker = root / 'share' / 'ament_index' / 'resource_index' / 'packages' / package
    marker.parent.mkdir(parents=True)
    marker.write_text('')
    if executable is not None:
        folder = root / 'lib' / package if where == 'lib' else root / 'bin'
        folder.mkdir(parents=True)
        path = folder / executable
        path.write_text('#!/bin/sh\nexit 0\n')
        path.chmod(0o755)
    return root


def test_the_indexed_prefix_wins_over_this_interpreters_bin(tmp_path, monkeypatch):
    # pam-simulate is also in the venv's bin (make setup): a colcon overlay's copy is the one
    # `ros2 run pam_model pam-simulate` runs
    overlay = make_prefix(tmp_path / 'install' / 'pam_model', 'pam_model', 'pam-simulate', 'lib')
    monkeypatch.setenv('AMENT_PREFIX_PATH', f'{overlay}:{tmp_path / "venv"}')
    assert find_executable('pam-simulate', 'pam_model') == str(
        overlay / 'lib' / 'pam_model' / 'pam-simulate')


def test_a_pip_install_has_its_executables_in_the_prefix_bin(tmp_path, monkeypatch):
    venv = make_prefix(tmp_path / 'venv', 'pam_fake', 'fake_node', 'bin')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(venv))
    assert find_executable('fake_node', 'pam_fake') == str(venv / 'bin' / 'fake_node')


def test_an_executable_asked_of_the_wrong_package_is_not_found(tmp_path, monkeypatch):
    # sim_node belongs to pam_driver: asked of pam_fake, whose prefix does not hold it, it is not
    # taken from elsewhere (this interpreter's bin, PATH) as it was
    prefix = make_prefix(tmp_path / 'install' / 'pam_fake', 'pam_fake', None, 'lib')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(prefix))
    assert find_executable('sim_node', 'pam_fake') is None
    assert executable_candidates('sim_node', 'pam_fake') == [
        str(prefix / 'lib' / 'pam_fake' / 'sim_node'), str(prefix / 'bin' / 'sim_node')]


def test_a_package_not_in_the_index_is_looked_for_on_path(tmp_path, monkeypatch):
    tool = make_prefix(tmp_path / 'tools', 'unused', 'pam_fake_tool', 'bin') / 'bin'
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    monkeypatch.setenv('PATH', str(tool))
    assert find_executable('pam_fake_tool', 'pam_fake') == str(tool / 'pam_fake_tool')
    assert 'is AMENT_PREFIX_PATH set?' in executable_candidates('nothing_here', 'pam_fake')[-1]
