"""The installed URDF (share/pam_description/urdf/pam_joint.urdf, found through the ament index
as robot_state_publisher's users find it) parsed by yourdfpy (a URDF parser from PyPI), its
numbers held against Table II of shared/MODEL.md as pam_model loads it
(load_parameters('default')), so a change on either side shows: M, J, c_s, r, r_p, L0, the
+/-25 degree range; and its kinematics against MODEL.md's geometry (2) and torque (8), the sign
convention included, through pam_model's own functions."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from ament_index_python.packages import get_package_share_directory

from pam_model.parameters import load_parameters
from pam_model.physics_vectorised import joint_torque, muscle_lengths

P = load_parameters('default')
RANGE = math.radians(25.0)          # rad, MODEL.md section 1: psi in +/-25 deg
TORQUE_RANGE = 3.0                  # N m, MODEL.md section 1: tau in +/-3 N m
SOURCE = Path(__file__).resolve().parents[1] / 'urdf' / 'pam_joint.urdf'
JOINT = 'seesaw_joint'
MUSCLES = {'pam1': -1.0, 'pam2': +1.0}      # link -> side: attached at y = side * r
ANGLES = np.radians([-25.0, -12.5, -3.0, 0.0, 3.0, 12.5, 25.0])


def close(a, b) -> bool:
    return np.allclose(a, b, rtol=1e-12, atol=1e-15)


@pytest.fixture(scope='module')
def installed() -> Path:
    return Path(get_package_share_directory('pam_description')) / 'urdf' / 'pam_joint.urdf'


@pytest.fixture(scope='module')
def urdf(installed) -> yourdfpy.URDF:
    return yourdfpy.URDF.load(str(installed), build_scene_graph=True, load_meshes=False)


def cylinders(link) -> list:
    """(visual, cylinder) of each cylinder visual of a yourdfpy link."""
    return [(v, v.geometry.cylinder) for v in link.visuals if v.geometry.cylinder is not None]


def test_the_installed_file_is_the_source(installed):
    """The test reads what is installed: an edit of urdf/ without `make setup` would show here."""
    assert installed.read_text() == SOURCE.read_text()


def test_it_is_a_valid_urdf_of_four_links_and_one_moving_joint(urdf):
    assert urdf.validate(), urdf.errors
    assert urdf.robot.name == 'pam_joint'
    assert set(urdf.link_map) == {'base', 'seesaw', 'pam1', 'pam2'}
    assert urdf.base_link == 'base'
    assert urdf.actuated_joint_names == [JOINT]
    joint = urdf.joint_map[JOINT]
    assert (joint.type, joint.parent, joint.child) == ('revolute', 'base', 'seesaw')
    assert {(j.type, j.parent, j.child) for j in urdf.robot.joints if j.name != JOINT} == {
        ('fixed', 'base', 'pam1'), ('fixed', 'base', 'pam2')}


def test_the_range_is_the_papers_in_radians(urdf):
    limit = urdf.joint_map[JOINT].limit
    assert close([limit.lower, limit.upper], [-RANGE, RANGE])
    assert close(limit.effort, TORQUE_RANGE)
    assert limit.velocity > 0.0


def test_the_seesaw_has_mass_M_and_inertia_J_about_the_joint_axis(urdf):
    inertial = urdf.link_map['seesaw'].inertial
    assert close(inertial.mass, P.M)
    assert close(inertial.origin, np.eye(4))        # centre of mass on the axis: no gravity torque
    axis = urdf.joint_map[JOINT].axis
    assert close(axis @ inertial.inertia @ axis, P.J)
    moments = np.linalg.eigvalsh(inertial.inertia)   # a physical tensor
    assert np.all(moments > 0.0) and 2.0 * moments.max() <= moments.sum()
    assert urdf.link_map['base'].inertial is None    # the fixed root link


def test_the_joint_damping_is_c_s(urdf):
    # yourdfpy 0.0.60 keeps the <dynamics> attributes as strings
    assert close(float(urdf.joint_map[JOINT].dynamics.damping), P.c_s)


def test_the_shaft_has_radius_r_p_along_the_joint_axis(urdf):
    (visual, shaft), = cylinders(urdf.link_map['seesaw'])
    assert close(shaft.radius, P.r_p)
    along = visual.origin[:3, 2]                     # a cylinder's axis is its frame's z
    assert close(abs(along @ urdf.joint_map[JOINT].axis), 1.0)
    assert close(visual.origin[1:3, 3], [0.0, 0.0])  # centred on the axis


def test_the_seesaw_bar_spans_2r(urdf):
    bars = [v.geometry.box.size for v in urdf.link_map['seesaw'].visuals
             if v.geometry.box is not None]
    assert len(bars) == 1 and close(bars[0][1], 2.0 * P.r)


@pytest.mark.parametrize('muscle', sorted(MUSCLES))
def test_each_muscle_is_drawn_L0_long_at_r_from_the_axis(urdf, muscle):
    (visual, cylinder), = cylinders(urdf.link_map[muscle])
    assert close(cylinder.length, P.L0)
    assert cylinder.radius > 0.0
    assert close(visual.origin[:3, :3], np.eye(3))   # upright, from its anchor up to L0
    assert close(visual.origin[:3, 3], [0.0, 0.0, P.L0 / 2.0])
    anchor = urdf.get_transform(muscle, 'base')
    assert close(anchor[:3, 3], [0.0, MUSCLES[muscle] * P.r, 0.0])
    axis_height = urdf.joint_map[JOINT].origin[2, 3]
    assert close(axis_height, P.L0)                  # at psi = 0 the muscles have length L0


def seesaw_end(urdf, psi: float, side: float) -> np.ndarray:
    """Where the seesaw's end at y = side * r is in the base frame at angle psi."""
    urdf.update_cfg({JOINT: psi})
    return (urdf.get_transform('seesaw', 'base') @ [0.0, side * P.r, 0.0, 1.0])[:3]


@pytest.mark.parametrize('psi', ANGLES)
def test_the_muscle_lengths_follow_MODEL_md_2(urdf, psi):
    """l1 = L0 - r sin psi, l2 = L0 + r sin psi: the heights of the seesaw's ends above the
    muscles' anchors (the model counts the muscles' vertical extent), psi > 0 shortening PAM1."""
    l1, l2 = muscle_lengths(psi, P)
    heights = [seesaw_end(urdf, psi, MUSCLES[m])[2] - urdf.get_transform(m, 'base')[2, 3]
               for m in ('pam1', 'pam2')]
    assert close(heights, [l1, l2])
    if psi > 0.0:
        assert l1 < P.L0 < l2


@pytest.mark.parametrize('psi', ANGLES)
def test_the_muscles_pull_with_the_torque_of_MODEL_md_8(urdf, psi):
    """F1 > F2 pulling the ends down towards the anchors gives tau = r cos(psi) (F1 - F2) about
    the joint axis: tau > 0 drives psi up, as MODEL.md's sign convention says."""
    F1, F2 = 60.0, 45.0                                 # N
    urdf.update_cfg({JOINT: psi})
    to_base = urdf.get_transform('seesaw', 'base')
    pivot, axis = to_base[:3, 3], to_base[:3, :3] @ urdf.joint_map[JOINT].axis
    tau = sum(np.cross(seesaw_end(urdf, psi, MUSCLES[m]) - pivot, [0.0, 0.0, -force]) @ axis
              for m, force in (('pam1', F1), ('pam2', F2)))
    assert close(tau, joint_torque(psi, F1, F2, P))
    assert tau > 0.0
