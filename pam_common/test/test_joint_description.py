"""pam_common.joint_description: the installed URDF of pam_description is found through the ament
index, and its one revolute joint names the JointState joint by default; a missing package, a
broken file, or a URDF with no or two revolute joints is a one-line error naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest
from ament_index_python.packages import get_package_share_directory

from pam_common.joint_description import (
    JointDescriptionError,
    default_joint_name,
    revolute_joint_names,
    urdf_path,
)

JOINT = '<joint name="{name}" type="{kind}"><parent link="a"/><child link="{child}"/></joint>'


def urdf(tmp_path: Path, *joints: tuple[str, str], root: str = 'robot') -> Path:
    """A small URDF in tmp_path with joints (name, type), each to a link of its own."""
    links = ''.join(f'<link name="l{i}"/>' for i in range(len(joints)))
    text = ''.join(JOINT.format(name=name, kind=kind, child=f'l{i}')
                   for i, (name, kind) in enumerate(joints))
    path = tmp_path / 'joint.urdf'
    path.write_text(f'<?xml version="1.0"?><{root} name="r"><link name="a"/>{links}{text}'
                    f'</{root}>')
    return path


def test_the_installed_urdf_is_found_through_the_ament_index():
    path = urdf_path()
    assert path == Path(get_package_share_directory('pam_description')) / 'urdf' / 'pam_joint.urdf'
    assert path.is_file()


def test_the_default_joint_name_is_the_urdfs_revolute_joint():
    assert default_joint_name() == 'seesaw_joint'
    assert default_joint_name(urdf_path()) == 'seesaw_joint'


def test_fixed_joints_do_not_count(tmp_path):
    path = urdf(tmp_path, ('anchor', 'fixed'), ('hinge', 'revolute'), ('other', 'continuous'))
    assert revolute_joint_names(path) == ['hinge']
    assert default_joint_name(path) == 'hinge'


@pytest.mark.parametrize(('joints', 'message'), [
    ((), 'expected exactly one revolute joint, found 0: []'),
    ((('a', 'revolute'), ('b', 'revolute')),
     "expected exactly one revolute joint, found 2: ['a', 'b']"),
    ((('', 'revolute'),), 'the revolute joint has no name'),
])
def test_no_or_two_revolute_joints_is_a_clear_error(tmp_path, joints, message):
    path = urdf(tmp_path, *joints)
    with pytest.raises(JointDescriptionError) as error:
        default_joint_name(path)
    assert str(error.value) == f'{path}: {message}'


def test_a_file_that_is_no_urdf_is_a_clear_error(tmp_path):
    with pytest.raises(JointDescriptionError, match=r'not a URDF \(root element <sdf>'):
        default_joint_name(urdf(tmp_path, ('hinge', 'revolute'), root='sdf'))
    broken = tmp_path / 'broken.urdf'
    broken.write_text('<robot name="r"><joint')
    with pytest.raises(JointDescriptionError, match=r'broken\.urdf: cannot read the URDF'):
        default_joint_name(broken)
    with pytest.raises(JointDescriptionError, match=r'missing\.urdf: cannot read the URDF'):
        default_joint_name(tmp_path / 'missing.urdf')


def test_pam_description_not_installed_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))      # an ament prefix without it
    with pytest.raises(JointDescriptionError, match='package pam_description is not installed'):
        urdf_path()
    with pytest.raises(JointDescriptionError, match='package pam_description is not installed'):
        default_joint_name()


def test_pam_description_without_its_urdf_is_a_clear_error(tmp_path, monkeypatch):
    marker = tmp_path / 'share' / 'ament_index' / 'resource_index' / 'packages'
    marker.mkdir(parents=True)
    (marker / 'pam_description').touch()
    (tmp_path / 'share' / 'pam_description').mkdir()
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    with pytest.raises(JointDescriptionError, match='pam_description is installed but has no '):
        urdf_path()
