"""The joint's URDF (package pam_description): where it is installed, and the name of its one
revolute joint, the default joint name of the stack's sensor_msgs/JointState messages.

Read with xml.etree (no URDF library at run time); found through the ament index
(AMENT_PREFIX_PATH: the venv, or a sourced colcon/apt install)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

URDF_FILE = 'pam_joint.urdf'        # in share/pam_description/urdf/


class JointDescriptionError(RuntimeError):
    """The URDF is not installed, does not parse, or does not hold exactly one revolute joint."""


def urdf_path() -> Path:
    """The installed URDF, share/pam_description/urdf/pam_joint.urdf."""
    try:
        share = Path(get_package_share_directory('pam_description'))
    except (PackageNotFoundError, OSError) as error:    # OSError: AMENT_PREFIX_PATH unset
        raise JointDescriptionError(
            f'package pam_description is not installed (not in the ament index of '
            f'AMENT_PREFIX_PATH): {error}') from error
    path = share / 'urdf' / URDF_FILE
    if not path.is_file():
        raise JointDescriptionError(f'pam_description is installed but has no {path}')
    return path


def revolute_joint_names(path: Path) -> list[str]:
    """The names of the revolute joints of the URDF at `path`, in file order."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as error:
        raise JointDescriptionError(f'{path}: cannot read the URDF: {error}') from error
    if root.tag != 'robot':
        raise JointDescriptionError(f'{path}: not a URDF (root element <{root.tag}>, not '
                                    '<robot>)')
    return [joint.get('name', '') for joint in root.findall('joint')
            if joint.get('type') == 'revolute']


def default_joint_name(path: Path | None = None) -> str:
    """The name of the one revolute joint of the URDF at `path` (default: the installed one,
    urdf_path()): 'seesaw_joint'."""
    path = urdf_path() if path is None else Path(path)
    names = revolute_joint_names(path)
    if len(names) != 1:
        raise JointDescriptionError(f'{path}: expected exactly one revolute joint, found '
                                    f'{len(names)}: {names}')
    if not names[0]:
        raise JointDescriptionError(f'{path}: the revolute joint has no name')
    return names[0]
