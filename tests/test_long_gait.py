"""A stalled finger's gait started along the joint-space way to its goal (`long_gait`): the ring of the
generated mug pair of seed 2, stuck at an edge of the mug with the object at the desired pose (the paper
planner's sd plan stalled there before), gets out; the ring of seed 1 gets through only from its IK."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from regrasp_casadi.finger_gait import FingerGaitNLP
from regrasp_casadi.planner import PlannerOptions, plan_regrasp
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.stall_report import stalled_fingers
from regrasp_casadi.tip_ik import finger_reach_ik, tip_ik
from regrasp_casadi.verify import verify

STUCK = Path(__file__).resolve().parent / "data" / "mug_ring_stuck_at_edge.yaml"
CUP_PAIR = Path(__file__).resolve().parents[1] / "problems" / "cup_regrasp.yaml"  # seed 0's pair


@pytest.fixture(scope="module")
def problem():
    return RegraspProblem.load(STUCK)


def _exact_contact_error(problem, q, T, r):
    """Distance (m) of finger r's exact contact (trimesh's closest point of its tip centre) to its goal."""
    tip = (problem.hand.tip_positions(q)[r] - T[:3, 3]) @ T[:3, :3]
    contact = trimesh.proximity.closest_point(problem.obj.mesh, tip[None])[0][0]
    return float(np.linalg.norm(contact - problem.grasp_goal.contacts_object[r]))


@pytest.mark.parametrize("start", ["own joints", "part way"])
def test_the_ring_stuck_at_the_mug_edge_moves_on(problem, start):
    """The ring 17 mm from its goal where the plan stalled: OPT1 from part of the way to its IK at the goal
    (`long_gait`'s second start) gets it millimetres closer, within OPT1's constraints by trimesh's exact
    distances. So does OPT1 from its own joints since its non-tip spheres have local plane sets: with the
    object's coarse pieces (16 planes each, containing the mesh) it moved the ring less than 0.5 mm from
    there, a local minimum of the coarse model, not of the mug (from its own joints it now moves η,
    17.1 → 10.0 mm, links ≥ 3 mm clear)."""
    hand, obj, g0 = problem.hand, problem.obj, problem.grasp0
    r, T = hand.fingers.index("ring"), g0.T_palm_object
    goal_tip = problem.grasp_goal.tip_centers_object[r]
    options = PlannerOptions().finger_gait
    nlp = FingerGaitNLP(hand, obj, "ring", options)
    before = _exact_contact_error(problem, g0.q, T, r)
    assert before > 0.015  # 17 mm: the stalled plan's ring

    q_init = None
    if start == "part way":
        way = float(np.linalg.norm(goal_tip - g0.tip_centers_object[r]))
        q_goal, e = tip_ik(hand, g0.q, ["ring"], (T[:3, :3] @ goal_tip + T[:3, 3])[None],
                           np.asarray(hand.finger_joints["ring"]), g0.q)
        assert np.linalg.norm(e) < 1e-3  # the goal is within reach at this pose
        q_init = g0.q + min(1.0, options.eta / way) * (q_goal - g0.q)
    res = nlp.solve(g0.q, T, goal_tip, q_init=q_init)
    assert res.success
    assert _exact_contact_error(problem, res.q, T, r) < before - 0.003  # millimetres closer
    # OPT1's constraints, by trimesh's exact distances: the tip on the surface, the links outside, ≤ η
    def to_object(p_palm):
        return (np.reshape(p_palm, (-1, 3)) - T[:3, 3]) @ T[:3, :3]

    inside = trimesh.proximity.signed_distance  # > 0 inside the mesh
    tip_depth = inside(obj.mesh, to_object(hand.tip_positions(res.q)[r]))[0]
    assert abs(-tip_depth - hand.tip_radius) < 2e-4
    link_depth = inside(obj.mesh, to_object(hand.sphere_centers(res.q, "ring")))
    assert np.all(-link_depth - hand.sphere_radii("ring") > 0.0)
    assert np.linalg.norm(hand.tip_positions(res.q)[r] - hand.tip_positions(g0.q)[r]) <= options.eta + 1e-6
    others = np.setdiff1d(np.arange(hand.n_joints), hand.finger_joints["ring"])
    assert np.array_equal(res.q[others], g0.q[others])


@pytest.mark.slow  # a plan of the mug: in the slow run
def test_the_stalled_plan_now_reaches_the_ring_goal(problem):
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method="sd", stability="none")
    assert plan.status == "converged", plan.status_detail
    assert verify(plan, problem.hand, problem.obj).ok
    last = plan.steps[-1]
    r = problem.hand.fingers.index("ring")
    assert _exact_contact_error(problem, last.q, last.T_palm_object, r) <= plan.options["zeta"]


@pytest.fixture(scope="module")
def cup_ring_at_its_limits():
    """The cup pair of seed 0 with the object at its desired pose and the ring's joints at their upper
    limits: (problem, q (n,), goal tip centre of the ring (3,), palm frame, m)."""
    cup = RegraspProblem.load(CUP_PAIR)
    hand, goal = cup.hand, cup.grasp_goal
    joints = np.asarray(hand.finger_joints["ring"])
    q = np.array(cup.grasp0.q, dtype=float)
    q[joints] = hand.q_upper[joints]
    T = goal.T_palm_object
    return cup, q, T[:3, :3] @ goal.tip_centers_object[hand.fingers.index("ring")] + T[:3, 3]


def test_the_reach_ik_starts_again_where_the_fingers_own_joints_stop(cup_ring_at_its_limits):
    """From the ring's joints at their limits the local IK stops tens of millimetres short of a goal that
    the goal grasp's joints reach exactly; `finger_reach_ik` started from them too reaches it (by the FK
    of the joints it returns), within the limits, the other fingers' joints untouched."""
    cup, q, target = cup_ring_at_its_limits
    hand = cup.hand
    r, joints = hand.fingers.index("ring"), np.asarray(hand.finger_joints["ring"])
    _, e_local = tip_ik(hand, q, ["ring"], target[None], joints, q)
    assert np.linalg.norm(e_local) > 0.05
    q_reach, e = finger_reach_ik(hand, q, "ring", target, [cup.grasp_goal.q])
    assert np.linalg.norm(hand.tip_positions(q_reach)[r] - target) < 1e-6
    assert np.allclose(hand.tip_positions(q_reach)[r] + e, target, atol=1e-12)
    assert np.all(q_reach >= hand.q_lower) and np.all(q_reach <= hand.q_upper)
    others = np.setdiff1d(np.arange(hand.n_joints), joints)
    assert np.array_equal(q_reach[others], q[others])


def test_the_stall_report_calls_out_of_reach_only_what_no_start_reaches(cup_ring_at_its_limits):
    """The ring's goal reached by the goal grasp's joints is not reported out of reach (the report said
    so before, from the IK of the finger's own joints alone); a goal 20 cm off the palm still is."""
    cup, q, _ = cup_ring_at_its_limits
    hand, goal = cup.hand, cup.grasp_goal
    error = np.zeros(len(hand.fingers))
    error[hand.fingers.index("ring")] = 0.07
    text = stalled_fingers(hand, cup.obj, q, goal.T_palm_object, goal.tip_centers_object, error, 0.006,
                           q_goal=goal.q)
    assert "ring 70.0 mm" in text and "out of its reach" not in text
    far = np.array(goal.tip_centers_object)
    far[hand.fingers.index("ring")] += goal.T_palm_object[:3, :3].T @ np.array([0.0, 0.0, 0.2])
    text = stalled_fingers(hand, cup.obj, q, goal.T_palm_object, far, error, 0.006, q_goal=goal.q)
    assert "out of its reach" in text


JAMMED = Path(__file__).resolve().parent / "data" / "mug_ring_jammed.yaml"


def _transit_dip(problem, path, finger: str, beta: float) -> float:
    """How far (m) the finger's spheres keep above their transit floor over the path's transit knots, by
    trimesh's exact distances: per sphere (tip included) its clearance minus min(β, its clearance at
    the transit's two ends) — the rule of a transit (a sphere closer than β where the transit starts or
    ends keeps no worse); the least over spheres and knots (< 0: a sphere dips below its floor)."""
    hand, mesh = problem.hand, problem.obj.mesh
    knots = sorted({i + d for i, ph in enumerate(path.phases) if ph == "transit" for d in (0, 1)})
    radii = np.asarray(hand.sphere_radii(finger, include_tip=True))

    def clearance(k):
        T = path.T_palm_object[k]
        c = (hand.sphere_centers(path.q[k], finger, include_tip=True) - T[:3, 3]) @ T[:3, :3]
        return -trimesh.proximity.signed_distance(mesh, c) - radii

    floor = np.minimum(beta, np.minimum(clearance(knots[0]), clearance(knots[-1])))
    return float(min(np.min(clearance(k) - floor) for k in knots))


def test_a_gait_started_at_the_goal_ik_gets_through_where_the_others_graze_the_mug():
    """The ring of the generated mug pair of seed 1 (svd), 41.5 mm from its goal contact: OPT1 from its own
    joints or from part of the way to its IK at the goal gives no gait the hand can follow (since OPT1's
    local clearance planes: from its own joints IPOPT reports the problem infeasible; from part of the way
    it moves η but its transit brings a sphere 0.33 mm closer to the mug than β and than at the transit's
    ends; with the coarse pieces before, both moved with such a transit); OPT1 started at that IK (the
    first start `long_gait` tries) moves it η towards its goal with a transit that does not, by trimesh's
    exact distances."""
    from dataclasses import replace

    from regrasp_casadi.plan import PlanStep
    from regrasp_casadi.trajectory import motion_context, step_path

    problem = RegraspProblem.load(JAMMED)
    hand, obj, g0 = problem.hand, problem.obj, problem.grasp0
    r, T, q = hand.fingers.index("ring"), g0.T_palm_object, g0.q
    goal_tip = problem.grasp_goal.tip_centers_object[r]
    options = PlannerOptions().finger_gait
    nlp = FingerGaitNLP(hand, obj, "ring", options)
    ctx = motion_context(hand, obj)
    start = PlanStep("initial", None, q, T, g0.contacts_object, np.zeros(4), "", 0.0)
    before = _exact_contact_error(problem, q, T, r)
    assert before > 0.04

    q_goal, e = finger_reach_ik(hand, q, "ring", T[:3, :3] @ goal_tip + T[:3, 3], [problem.grasp_goal.q])
    assert np.linalg.norm(e) < 1e-3  # within reach at this pose
    way = float(np.linalg.norm(goal_tip - g0.tip_centers_object[r]))
    outcome = {}
    for name, q_init in (("own", None), ("part way", q + options.eta / way * (q_goal - q)), ("ik", q_goal)):
        res = nlp.solve(q, T, goal_tip, q_init=q_init)
        if not res.success:  # rejected by OPT1's exact checks
            outcome[name] = (False, None, None)
            continue
        assert np.linalg.norm(hand.tip_positions(res.q)[r] - hand.tip_positions(q)[r]) <= options.eta + 1e-6
        path = step_path(ctx, start, replace(start, kind="gait", finger="ring", q=res.q))
        outcome[name] = (path.ok, _transit_dip(problem, path, "ring", options.beta),
                         _exact_contact_error(problem, res.q, T, r))
    for name in ("own", "part way"):  # no gait, or one whose transit dips below its floor
        ok, dip, _ = outcome[name]
        assert not ok and (dip is None or dip < -5e-5), (name, outcome[name])
    ok, dip, after = outcome["ik"]
    assert ok and dip >= -1e-5, outcome["ik"]
    assert after < before - 0.005  # millimetres closer to its goal
