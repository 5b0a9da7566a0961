"""In-grasp reposing of a 7 cm sphere (issue 12): the object turns about its centre with the fingers
instead of spinning under them, and the planner's SVD reposings do not carry it away from the desired
pose while the contacts converge (`in_grasp.svd_target`'s goal pull on round objects)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from regrasp_casadi.grasp_metrics import tip_frames, tip_slip
from regrasp_casadi.in_grasp import ROUND_GOAL_PULL, InGraspNLP, is_round
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.planner import PlannerOptions, plan_regrasp
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.transforms import make_T, rot_axis_angle
from regrasp_casadi.verify import verify

SPHERE_PAIR = Path(__file__).resolve().parent / "data" / "sphere_pair_seed8.yaml"


@pytest.fixture(scope="module")
def problem():
    return RegraspProblem.load(SPHERE_PAIR)


@pytest.fixture(scope="module")
def svd_nlp(problem):
    return InGraspNLP(problem.hand, problem.obj, "svd")


def _contacts(problem, q, T) -> np.ndarray:
    """The tips' closest points on the mesh (m, 3), object frame, by trimesh's exact query."""
    tips = (problem.hand.tip_positions(q) - T[:3, 3]) @ T[:3, :3]
    return trimesh.proximity.closest_point(problem.obj.mesh, tips)[0]


def _slides(problem, q0, T0, q1, T1) -> np.ndarray:
    """Each tip's slide over the sphere (m,), m (`grasp_metrics.tip_slip`; `test_rolling` checks it), the
    normals radial from the mesh's centre (closed form for a ball)."""
    (p0, R0), (p1, R1) = tip_frames(problem.hand, q0, T0), tip_frames(problem.hand, q1, T1)
    centre = np.mean(problem.obj.mesh.bounds, axis=0)
    normals = (p0 - centre) / np.linalg.norm(p0 - centre, axis=1, keepdims=True) + \
        (p1 - centre) / np.linalg.norm(p1 - centre, axis=1, keepdims=True)
    return tip_slip(p0, R0, p1, R1, normals, problem.hand.tip_radius)


def _angle(R_a, R_b) -> float:
    return float((Rotation.from_matrix(R_a).inv() * Rotation.from_matrix(R_b)).magnitude())


def test_only_the_sphere_is_round():
    """A ball's vertices and face centres are all about one radius from its centre; a cube's corners are
    √3 times its face centres' distance, and a 20 % elongated ball is not round either."""
    ball = trimesh.creation.icosphere(3, 0.05)
    egg = trimesh.creation.icosphere(3, 0.05).apply_scale([1.0, 1.0, 1.2])
    assert is_round(ObjectModel.sphere(0.035))
    assert is_round(SimpleNamespace(mesh=ball))
    assert not is_round(SimpleNamespace(mesh=egg))
    assert not is_round(SimpleNamespace(mesh=trimesh.creation.box([0.05, 0.05, 0.05])))
    for obj in (ObjectModel.box(), ObjectModel.cylinder(), ObjectModel.capsule(), ObjectModel.bottle()):
        assert not is_round(obj), obj.name


def test_the_round_goal_pull_is_the_svd_nlps_default_only_on_round_objects(problem, svd_nlp):
    assert svd_nlp.goal_pull == ROUND_GOAL_PULL > 0
    assert InGraspNLP(problem.hand, ObjectModel.box(), "svd").goal_pull == 0.0


@pytest.mark.parametrize("axis", np.eye(3))
def test_a_rotation_about_the_centre_turns_the_sphere_without_slip(problem, svd_nlp, axis):
    """A 15° target rotation of the sphere about its centre (palm axes) could be met by spinning the
    sphere under fixed fingertips (the tips stay on the surface, their material sliding over it); each
    move must instead turn it with the tips rolling, not sliding: every move is accepted with no tip
    sliding more than `max_slip` (radial normals), the three bring the orientation at least 30 % closer
    to the target (scipy's rotation angle; measured 43-77 %, then the rolling hand stops: a move from
    there that would not lower OPT2's objective keeps the grasp), and the contacts stay within a few
    millimetres of the start's (trimesh closest points: rolled, not spun)."""
    g = problem.grasp0
    q, T = np.asarray(g.q, float), np.asarray(g.T_palm_object, float)
    T_target = make_T(rot_axis_angle(axis, np.radians(15.0)) @ T[:3, :3], T[:3, 3])
    start = _contacts(problem, q, T)
    for _ in range(3):
        tips = (problem.hand.tip_positions(q) - T[:3, 3]) @ T[:3, :3]
        res = svd_nlp.solve(q, T, tips, T_target=T_target)
        assert res.success, res.status
        assert np.max(_slides(problem, q, T, res.q, res.T_palm_object)) <= svd_nlp.options.max_slip
        q, T = res.q, res.T_palm_object
    assert _angle(T[:3, :3], T_target[:3, :3]) < np.radians(15.0) * 0.7  # turned at least 30 % of it
    # spun under the tips, a contact would move 35 mm × 15° ≈ 9 mm over the sphere
    assert np.max(np.linalg.norm(_contacts(problem, q, T) - start, axis=1)) <= 4e-3


def test_a_rotation_about_the_palm_y_axis_comes_near_the_target(problem, svd_nlp):
    """About the palm's y axis the rolling fingers follow most of the 15°: within 6° (scipy) and 5 mm of
    the target after five moves, no tip sliding more than `max_slip` in any move (radial normals). Measured
    4.9° and 4.2 mm: three joints (3, 7, 12) and a pair of fingers at their bounds from the first move on,
    the later moves creep by 0.3-0.7°. With the tips held where they were instead of where they touch the
    surface (before c216641): 3.5° and 2.5 mm, every move after the second at the same pose; with the
    paper's fixed contacts the tips slid over the ball instead. The planner (stability "none", the slow
    test below) reaches the desired pose on this pair either way."""
    g = problem.grasp0
    q, T = np.asarray(g.q, float), np.asarray(g.T_palm_object, float)
    T_target = make_T(rot_axis_angle([0.0, 1.0, 0.0], np.radians(15.0)) @ T[:3, :3], T[:3, 3])
    for _ in range(5):
        tips = (problem.hand.tip_positions(q) - T[:3, 3]) @ T[:3, :3]
        res = svd_nlp.solve(q, T, tips, T_target=T_target)
        assert np.max(_slides(problem, q, T, res.q, res.T_palm_object)) <= svd_nlp.options.max_slip
        q, T = res.q, res.T_palm_object
    assert _angle(T[:3, :3], T_target[:3, :3]) < np.radians(6.0)
    assert np.linalg.norm(T[:3, 3] - T_target[:3, 3]) < 5e-3


@pytest.mark.slow
def test_the_paper_planner_reaches_the_desired_pose_on_the_sphere(problem):
    """The paper planner (stability "none", SVD reposings) with the round objects' goal pull converges,
    verifies, and its last object pose is within 2° (scipy) and 2 mm of the desired one. (On bbff089 the
    paper's target, goal_pull 0, carried the sphere 101° away on this pair; since gaits whose path fails
    its checks are refused, it converges on this pair too, 0.10° away: measured, so not asserted.) From
    2ed9322 or earlier to b243608 it failed (the final moves refused for a tip 0.37-0.72 mm off the
    faceted sphere; the object 10.4 mm / 14.4° off): this file's goal tips were its contacts pushed out
    along the facets' blended normals, up to 2.05 mm from the goal joints' tips; since the goal's tips are
    its joints' (`Grasp.from_contacts`) it passes again (measured 2026-12-04, AMD EPYC)."""
    options = PlannerOptions(method="svd", stability="none")
    T_goal = np.asarray(problem.grasp_goal.T_palm_object, float)
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, options=options)
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok
    T_end = np.asarray(plan.steps[-1].T_palm_object, float)
    assert _angle(T_end[:3, :3], T_goal[:3, :3]) < np.radians(2.0)
    assert np.linalg.norm(T_end[:3, 3] - T_goal[:3, 3]) < 2e-3


@pytest.mark.slow
def test_an_sd_escape_blocked_by_another_finger_reposes_towards_the_desired_pose(monkeypatch):
    """Generated sphere pair 19, method SD: at the pose where the escapes stall, the middle reaches its
    goal only through the index. Without the SVD-target reposing that then follows an escape
    (`planner._repose`), the plan stalls 10.2 mm short; with it, it converges and verifies."""
    from regrasp_casadi import planner

    pair = RegraspProblem.load(SPHERE_PAIR.with_name("sphere_pair_seed19.yaml"))
    options = PlannerOptions(method="sd", stability="none")
    plan = plan_regrasp(pair.grasp0, pair.grasp_goal, options=options)
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok
    monkeypatch.setattr(planner, "reached_through_others", lambda *args, **kwargs: False)
    stalled = plan_regrasp(pair.grasp0, pair.grasp_goal, options=options, restarts=0)
    if stalled.status == "converged":  # measured 2026-12-08 at 525e128 and since, on a kernel v1300 VM
        pytest.skip("without the reposing this pair converges on this machine (plans differ across CPUs)")
    assert stalled.status == "stalled" and "only through the index finger" in stalled.status_detail
