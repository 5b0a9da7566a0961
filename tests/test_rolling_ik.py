"""The reposing path's IK of rolling tips (`rolling_ik`, issue 12) on a reposing of the generated mug pair
of seed 1 (`tests/data/mug_thumb_stretched_repose.yaml`): its thumb starts stretched to the edge of its
reach, where the tip-centre Jacobian loses a rank; the path, refused before for its IK's jumps and a tip
sliding 2.7 mm, now passes its own checks and verify's."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yourdfpy

from regrasp_casadi.grasp_metrics import tip_frames
from regrasp_casadi.plan import Plan, PlanStep
from regrasp_casadi.planner import PlannerOptions
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.rolling_ik import Rolling, _residual, rolling_tip_ik, tip_angular_jacobian
from regrasp_casadi.stability import contact_normals
from regrasp_casadi.trajectory import TrajectoryOptions, plan_trajectories
from regrasp_casadi.transforms import interpolate_pose
from regrasp_casadi.verify import verify

REPOSE = Path(__file__).resolve().parent / "data" / "mug_thumb_stretched_repose.yaml"


@pytest.fixture(scope="module")
def problem():
    return RegraspProblem.load(REPOSE)


def _step(grasp, kind: str) -> PlanStep:
    q, T, contacts = (np.asarray(x) for x in (grasp.q, grasp.T_palm_object, grasp.contacts_object))
    return PlanStep(kind=kind, finger=None, q=q, T_palm_object=T, contacts_object=contacts,
                    contact_error=np.zeros(len(contacts)), solver_status="", solve_time=0.0)


def _rolling(problem) -> Rolling:
    """The tips' rolling targets from grasp0, with no slide and grasp0's normals (object frame)."""
    hand, obj, g0 = problem.hand, problem.obj, problem.grasp0
    p, R = tip_frames(hand, g0.q, g0.T_palm_object)
    n = contact_normals(np.asarray(obj.closest_points(p)[0], float), p)
    return Rolling(p, R, n, np.zeros_like(p), hand.tip_radius)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_tip_angular_jacobian_is_the_derivative_of_the_urdf_tip_rotations(hand, seed):
    """Against central differences of yourdfpy's FK (another FK code): vee((R(q+h) − R(q−h)) R(q)ᵀ / 2h)
    for every tip link and joint, and zero for the joints of the other fingers."""
    ref = yourdfpy.URDF.load(str(hand.urdf_path), load_meshes=False, build_collision_scene_graph=False)

    def rotations(q):
        ref.update_cfg(q)
        return np.stack([ref.get_transform(hand.tip_links[f], ref.base_link)[:3, :3] for f in hand.fingers])

    q = np.random.default_rng(seed).uniform(hand.q_lower, hand.q_upper)
    joints = np.arange(hand.n_joints)
    J = tip_angular_jacobian(hand, q, joints)
    R0_t, h = np.transpose(rotations(q), (0, 2, 1)), 1e-6
    for j in joints:
        dq = np.zeros(hand.n_joints)
        dq[j] = h
        D = (rotations(q + dq) - rotations(q - dq)) @ R0_t / (2 * h)  # [ω_j]×
        omega = np.stack([D[:, 2, 1], D[:, 0, 2], D[:, 1, 0]], axis=1)
        np.testing.assert_allclose(J[:, :, j], omega, atol=1e-7)
    for i, finger in enumerate(hand.fingers):
        other = np.setdiff1d(joints, hand.finger_joints[finger])
        assert np.all(J[i][:, other] == 0.0) and np.abs(J[i]).max() > 0.5  # a unit axis per joint


def test_the_thumb_is_singular_for_its_centre_not_for_its_rolling_contact(problem):
    hand, g0 = problem.hand, problem.grasp0
    thumb = hand.fingers.index("thumb")
    joints = np.asarray(hand.finger_joints["thumb"])
    J_p = hand.tips_jacobian(g0.q)[thumb][:, joints]
    assert np.linalg.svd(J_p, compute_uv=False)[-1] < 1e-5  # the distal joint straight: rank 2
    _, J = _residual(hand, np.asarray(g0.q), np.asarray(g0.T_palm_object), _rolling(problem), [thumb],
                     joints)
    assert np.linalg.svd(J, compute_uv=False)[-1] > 1e-3  # m/rad: the rolling contact keeps all three


def test_the_residual_jacobian_is_the_derivative_of_the_tip_error(problem):
    hand, g0 = problem.hand, problem.grasp0
    q = np.asarray(g0.q) + 0.3 * (np.asarray(problem.grasp_goal.q) - np.asarray(g0.q))  # tips turned
    T, roll, rows = np.asarray(g0.T_palm_object), _rolling(problem), [0, 1, 2, 3]
    joints = np.arange(hand.n_joints)
    e0, J = _residual(hand, q, T, roll, rows, joints)
    h = 1e-6
    for j in (0, 5, 12, 13, 15):
        dq = q.copy()
        dq[j] += h
        e1, _ = _residual(hand, dq, T, roll, rows, joints)
        assert np.allclose(-(e1 - e0).ravel() / h, J[:, j], atol=1e-4 * max(1.0, np.abs(J[:, j]).max()))


def test_a_knot_puts_every_tip_where_it_rolls_to(problem):
    hand, g0, goal = problem.hand, problem.grasp0, problem.grasp_goal
    s = 0.05
    T = interpolate_pose(g0.T_palm_object, goal.T_palm_object, s)
    roll = _rolling(problem)
    q_lin = (1 - s) * np.asarray(g0.q) + s * np.asarray(goal.q)
    q, e = rolling_tip_ik(hand, np.asarray(g0.q), T, roll, np.arange(hand.n_joints), q_lin)
    assert np.max(np.abs(e)) < 1e-6
    p, R = tip_frames(hand, q, T)
    assert np.allclose(p, roll.targets(R)[0], atol=1e-6)  # the targets of its own turn
    assert np.max(np.abs(q - g0.q)) > 0.01  # the tips turned: the targets moved with them


def test_the_stretched_thumbs_reposing_path_passes_its_checks_and_verify(problem):
    hand, obj = problem.hand, problem.obj
    a, b = _step(problem.grasp0, "initial"), _step(problem.grasp_goal, "repose")
    gait = PlannerOptions().finger_gait
    options = TrajectoryOptions(beta=gait.beta, self_clearance=gait.self_clearance)
    path = plan_trajectories([a, b], hand, obj, options)[1]
    assert path.ok, path.detail
    assert path.metrics["max_point_step"] <= options.max_point_step
    assert path.metrics["max_slip"] < 0.5e-3  # 2.68 mm before
    thumb = np.asarray(hand.finger_joints["thumb"])
    assert abs(b.q[thumb[0]] - a.q[thumb[0]]) > 0.6  # the thumb's swing, rad
    plan = Plan(steps=(a, replace(b, path=path)), goal_contacts_object=b.contacts_object,
                goal_T_palm_object=b.T_palm_object, fingers=tuple(hand.fingers),
                hand_spec={"model": "allegro_right"}, object_spec=dict(obj.spec), method="svd",
                status="iteration_limit", status_detail="", iterations=1, iteration_errors=np.zeros(2),
                timing={"total": 0.0}, options={})
    report = verify(plan, hand, obj)
    motion = [v for v in report.violations if v.check.startswith("motion_")]
    assert not motion, report.summary()
    assert report.metrics["motion_max_slip"] < 1e-3
