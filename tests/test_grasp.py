"""Grasp validation: joints, rigid transforms and contacts against the exact mesh, errors named."""

from __future__ import annotations

import numpy as np
import pytest
import twofinger as tf

from regrasp_casadi.errors import GraspError
from regrasp_casadi.grasp import Grasp


# ------------------------------------------------------------------------------------ Grasp validation
@pytest.fixture(scope="module")
def two(tmp_path_factory):
    """Two-finger test hand and the box it holds (see twofinger.py)."""
    return tf.make_hand(tmp_path_factory.mktemp("hand")), tf.make_box()


def test_from_joints_valid_grasp_contacts_in_closed_form(two):
    hand, obj = two
    q = np.zeros(hand.n_joints)
    q[hand.joint_names.index("left_slide")] = -0.007
    g = Grasp.from_joints(hand, obj, q, tf.box_pose(dy=0.003))
    # tips at (∓0.04, 0, 0.11 + slide) palm; box centre (0, 0.003, 0.11): contacts on the ±x faces
    assert np.allclose(g.contacts_object, [[-0.03, -0.003, -0.007], [0.03, -0.003, 0.0]], atol=1e-12)
    assert np.allclose(g.tip_centers_object, [[-0.04, -0.003, -0.007], [0.04, -0.003, 0.0]], atol=1e-12)
    assert g.fingers == ("left", "right")


@pytest.mark.parametrize(
    "dx, finger, text",
    [(0.01, "left", "10.0 mm off"), (-0.01, "left", "10.0 mm inside"), (0.0004, None, None),
     (0.0006, "left", "0.6 mm off")],
)
def test_from_joints_tip_off_surface_names_finger_and_distance(two, dx, finger, text):
    hand, obj = two
    q = np.zeros(hand.n_joints)
    if finger is None:  # 0.4 mm is within the 0.5 mm tolerance
        Grasp.from_joints(hand, obj, q, tf.box_pose(dx=dx))
        return
    pattern = rf"^{finger} tip is {text} the object surface \(tolerance 0.5 mm\)$"
    with pytest.raises(GraspError, match=pattern):
        Grasp.from_joints(hand, obj, q, tf.box_pose(dx=dx))


def test_wrong_joint_count(hand, two):
    _, obj = two
    with pytest.raises(GraspError, match=r"^expected 16 joint angles for allegro_right, got 15$"):
        Grasp.from_joints(hand, obj, np.zeros(15), np.eye(4))


def test_joint_out_of_limits_names_joint_value_and_limits(hand, two):
    _, obj = two
    q = 0.5 * (hand.q_lower + hand.q_upper)
    i = hand.joint_names.index("joint_3.0")
    q[i] = hand.q_upper[i] + 0.1
    with pytest.raises(GraspError) as e:
        Grasp.from_joints(hand, obj, q, np.eye(4))
    msg = str(e.value)
    assert "joint_3.0" in msg and f"{q[i]:.6g}" in msg
    assert f"[{hand.q_lower[i]:.6g}, {hand.q_upper[i]:.6g}]" in msg
    # within 1e-6 rad of the limit is accepted by the joint check (fails later, on the geometry)
    q[i] = hand.q_upper[i] + 0.5e-6
    with pytest.raises(GraspError, match="object surface"):
        Grasp.from_joints(hand, obj, q, np.eye(4))


@pytest.mark.parametrize(
    "T, pattern",
    [
        (np.diag([1.0, 1.0, 1.001, 1.0]), "not orthonormal"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), "det -1"),
        (np.vstack([np.eye(4)[:3], [0.0, 0.0, 0.1, 1.0]]), "last row"),
        (np.eye(3), r"\(4, 4\)"),
    ],
)
def test_non_rigid_transform(two, T, pattern):
    hand, obj = two
    with pytest.raises(GraspError, match=rf"T_palm_object: .*{pattern}"):
        Grasp.from_joints(hand, obj, np.zeros(hand.n_joints), T)


def test_from_contacts(two):
    hand, obj = two
    c = np.array([[-0.03, 0.01, 0.005], [0.03, -0.01, 0.0]])
    g = Grasp.from_contacts(hand, obj, c, tf.box_pose())
    assert g.q is None
    # contact + tip radius × outward normal (−x and +x faces)
    assert np.allclose(g.tip_centers_object, c + [[-0.01, 0, 0], [0.01, 0, 0]], atol=1e-12)
    with pytest.raises(GraspError, match=r"^right contact is 2.0 mm off the object surface"):
        Grasp.from_contacts(hand, obj, c + [[0, 0, 0], [0.002, 0, 0]], tf.box_pose())
    with pytest.raises(GraspError, match=r"expected shape \(2, 3\)"):
        Grasp.from_contacts(hand, obj, c[:1], tf.box_pose())
    with pytest.raises(GraspError, match="expected 6 joint angles for twofinger, got 5"):
        Grasp.from_contacts(hand, obj, c, tf.box_pose(), q=np.zeros(5))


def test_a_goal_read_with_its_joints_targets_the_tips_of_those_joints():
    """A problem file's goal gives contacts and the joints that realise them: its tip centres (the
    planner's targets) are the tips of those joints, not each contact pushed out along the surface
    normal, which differs at a rim (the shipped cup pair: the ring's contact on the rim's edge, > 1 mm
    apart; with those targets the paper planner stalled on the file's pair, 74 mm from the ring's goal,
    and converged on the pair in memory). Joints that do not touch at the contacts leave the normals'
    centres (checked against trimesh's exact distance: a tip radius off the surface, over its contact)."""
    import pathlib

    import trimesh

    from regrasp_casadi.problem import RegraspProblem
    from regrasp_casadi.transforms import inv_T, transform_points

    cup = RegraspProblem.load(pathlib.Path(__file__).resolve().parents[1] / "problems" / "cup_regrasp.yaml")
    hand, obj, goal = cup.hand, cup.obj, cup.grasp_goal
    tips_of_q = transform_points(inv_T(goal.T_palm_object), hand.tip_positions(goal.q))
    assert np.allclose(goal.tip_centers_object, tips_of_q, atol=1e-12)
    pushed = goal.contacts_object + hand.tip_radius * np.asarray(obj.surface_normals(goal.contacts_object))
    assert np.max(np.linalg.norm(pushed - tips_of_q, axis=1)) > 1e-3
    # the initial grasp's joints do not touch at the goal's contacts: the normals' centres
    other = Grasp.from_contacts(hand, obj, goal.contacts_object, goal.T_palm_object, q=cup.grasp0.q)
    assert np.allclose(other.tip_centers_object, pushed, atol=1e-12)
    closest, distance, _ = trimesh.proximity.closest_point(obj.mesh, other.tip_centers_object)
    assert np.allclose(distance, hand.tip_radius, atol=1e-4)
    assert np.allclose(closest, goal.contacts_object, atol=1e-4)
