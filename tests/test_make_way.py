"""Making way (`make_way`): a finger whose reach posture at its goal runs through a neighbour has the
neighbour moved aside, within ζ of its goal. On the generated mug pair of seed 16 (paper planner), where
the ring stalled 37 mm from its goal, 0.3 mm into the middle's collision spheres.

References: yourdfpy's forward kinematics for the sphere centres, trimesh's exact closest points for the
contacts, the plan's `verify`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from sphere_gaps import finger_gap

from regrasp_casadi.make_way import make_way
from regrasp_casadi.planner import NLPCache, PlannerOptions, _Run, plan_regrasp
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.stall_report import REACH_TOL
from regrasp_casadi.tip_ik import finger_reach_ik
from regrasp_casadi.verify import verify

DATA = Path(__file__).resolve().parent / "data"


def test_the_middle_moves_aside_within_zeta_and_clears_the_rings_reach():
    problem = RegraspProblem.load(DATA / "mug_ring_through_the_middle.yaml")
    hand, goal = problem.hand, problem.grasp_goal
    options = PlannerOptions(method="svd", stability="none")
    run = _Run(problem.grasp0, goal, options, NLPCache(max_size=8))
    T = run.T_palm_object
    ring = hand.fingers.index("ring")
    q_reach, e = finger_reach_ik(hand, run.q, "ring", T[:3, :3] @ run.goal_tips[ring] + T[:3, 3],
                                 [run.q_goal], tol=REACH_TOL)
    assert np.linalg.norm(e) <= REACH_TOL and finger_gap(hand, q_reach, "ring", "middle") < 0.0  # the stall

    n_steps = len(run.steps)
    make_way(run, "ring")
    step = run.steps[n_steps]
    assert step.kind == "gait" and step.finger == "middle" and step.path is not None and step.path.ok
    before = run.steps[n_steps - 1]
    moved = np.flatnonzero(np.abs(step.q - before.q) > 0)
    assert set(moved) <= set(hand.finger_joints["middle"])
    np.testing.assert_array_equal(step.T_palm_object, before.T_palm_object)

    middle = hand.fingers.index("middle")
    tip = (hand.tip_positions(step.q)[middle] - T[:3, 3]) @ T[:3, :3]
    (contact,), (distance,), _ = trimesh.proximity.closest_point(problem.obj.mesh, tip[None])
    assert abs(distance - hand.tip_radius) <= 5e-4  # on the mug
    assert np.linalg.norm(contact - goal.contacts_object[middle]) <= options.zeta
    q_both = q_reach.copy()
    q_both[hand.finger_joints["middle"]] = step.q[hand.finger_joints["middle"]]
    assert finger_gap(hand, q_both, "ring", "middle") >= options.finger_gait.self_clearance


def test_nothing_moves_for_a_finger_whose_reach_runs_through_no_other():
    problem = RegraspProblem.load(DATA / "mug_ring_through_the_middle.yaml")
    run = _Run(problem.grasp0, problem.grasp_goal, PlannerOptions(method="svd", stability="none"),
               NLPCache(max_size=8))
    n_steps = len(run.steps)
    assert not make_way(run, "index")  # 0.1 mm from its goal: its reach posture is its own
    assert len(run.steps) == n_steps


@pytest.mark.slow  # two plans of the mug: in the slow run
def test_the_pair_converges_with_make_way_and_stalls_without(monkeypatch):
    from regrasp_casadi import planner

    pair = RegraspProblem.load(DATA / "mug_pair_seed16.yaml")
    options = PlannerOptions(method="svd", stability="none")
    plan = plan_regrasp(pair.grasp0, pair.grasp_goal, options=options)
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok
    monkeypatch.setattr(planner, "make_way", lambda run, finger: False)
    stalled = plan_regrasp(pair.grasp0, pair.grasp_goal, options=options, restarts=0)
    assert stalled.status == "stalled" and "only through the middle finger" in stalled.status_detail
