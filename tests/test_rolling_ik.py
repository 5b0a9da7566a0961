"""The reposing path's IK of rolling tips (`rolling_ik`, issue 12) on a reposing of the generated mug pair
of seed 1 (`tests/data/mug_thumb_stretched_repose.yaml`): its thumb starts stretched to the edge of its
reach, where the tip-centre Jacobian loses a rank; the path, refused before for its IK's jumps and a tip
sliding 2.7 mm, now passes its own checks and verify's."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from regrasp_casadi.grasp_metrics import tip_frames
from regrasp_casadi.plan import Plan, PlanStep
from regrasp_casadi.planner import PlannerOptions
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.rolling_ik import Rolling, _residual, rolling_tip_ik
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


@pytest.mark.parametrize("turn", [0.0, 0.3, 1.0])
def test_the_residual_is_the_tip_error_to_the_rolled_targets(problem, turn):
    """The symbolic residual against the numpy one: T · `Rolling.targets` (its log of SO(3) in numpy) of
    the tip frames, minus the tip centres; turn 0 is grasp0 itself, where the tips have not turned
    (θ = 0 up to rounding)."""
    hand, g0 = problem.hand, problem.grasp0
    q = np.asarray(g0.q) + turn * (np.asarray(problem.grasp_goal.q) - np.asarray(g0.q))
    T = interpolate_pose(g0.T_palm_object, problem.grasp_goal.T_palm_object, turn)
    base = _rolling(problem)
    roll = replace(base, offset=np.random.default_rng(1).normal(0.0, 1e-3, base.offset.shape))
    p_palm, R_palm = tip_frames(hand, q, np.eye(4))
    e_ref = roll.targets(T[:3, :3].T @ R_palm)[0] @ T[:3, :3].T + T[:3, 3] - p_palm
    for rows in ([0, 1, 2, 3], [3, 1]):
        e, _ = _residual(hand, q, T, roll, rows, np.arange(hand.n_joints))
        np.testing.assert_allclose(e, e_ref[rows], atol=1e-12)
    assert turn == 0.0 or np.abs(e_ref).max() > 1e-3  # a turn moves the targets


def test_the_thumb_is_singular_for_its_centre_not_for_its_rolling_contact(problem):
    hand, g0 = problem.hand, problem.grasp0
    thumb = hand.fingers.index("thumb")
    joints = np.asarray(hand.finger_joints["thumb"])
    J_p = hand.tips_jacobian(g0.q)[thumb][:, joints]
    assert np.linalg.svd(J_p, compute_uv=False)[-1] < 1e-5  # the distal joint straight: rank 2
    _, J = _residual(hand, np.asarray(g0.q), np.asarray(g0.T_palm_object), _rolling(problem), [thumb],
                     joints)
    assert np.linalg.svd(J, compute_uv=False)[-1] > 1e-3  # m/rad: the rolling contact keeps all three


@pytest.mark.parametrize("turn", [0.0, 0.3])
def test_the_residual_jacobian_is_the_derivative_of_the_tip_error(problem, turn):
    hand, g0 = problem.hand, problem.grasp0
    q = np.asarray(g0.q) + turn * (np.asarray(problem.grasp_goal.q) - np.asarray(g0.q))  # tips turned
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
