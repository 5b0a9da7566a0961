"""Freeing a finger (`free_finger`): a stalled finger whose goal is reached only with a link in the object
has the object reposed until its goal is reached cleanly, then takes a gait. On the generated bowl pair
of seed 7 (SD, paper planner), which stalled with the thumb 28 mm from its goal, reached only with a link
in the bowl; and the re-posture gaits' search on the bowl pair of seed 19 (SVD).

References: yourdfpy's forward kinematics for the collision-sphere centres, trimesh's exact signed
distance and closest points, a closed-form rotation angle, the plan's `verify`."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from sphere_gaps import finger_spheres

from regrasp_casadi.final_moves import FinalMoves
from regrasp_casadi.final_rounds import EndRounds, Fallback
from regrasp_casadi.free_finger import FREE_SHIFT, FREE_TURN, free_finger, freeing_poses
from regrasp_casadi.planner import NLPCache, PlannerOptions, _Run, plan_regrasp
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.stall_report import REACH_TOL, reach_obstruction
from regrasp_casadi.tip_ik import finger_reach_ik
from regrasp_casadi.transforms import make_T
from regrasp_casadi.verify import verify

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="module")
def stalled():
    return RegraspProblem.load(DATA / "bowl_thumb_link_in_the_bowl.yaml")


def _link_depth_reference(problem, q, T, finger: str) -> float:
    """The least distance (m, < 0 inside) of `finger`'s collision spheres (yourdfpy FK) to the object
    (trimesh's exact signed distance, positive inside)."""
    centres, radii = finger_spheres(problem.hand, q, finger)
    centres_object = (centres - T[:3, 3]) @ T[:3, :3]
    return float(np.min(-trimesh.proximity.signed_distance(problem.obj.mesh, centres_object) - radii))


def _goal_reach(problem, q, T, finger: str):
    r = problem.hand.fingers.index(finger)
    goal = problem.grasp_goal.tip_centers_object[r]
    return finger_reach_ik(problem.hand, q, finger, T[:3, :3] @ goal + T[:3, 3], [problem.grasp_goal.q],
                           tol=REACH_TOL)


def test_the_poses_are_the_goal_then_turns_and_shifts_about_each_palm_axis():
    rng = np.random.default_rng(3)
    R0 = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    R0 *= np.sign(np.linalg.det(R0))  # a rotation
    T0, T_goal = np.eye(4), np.eye(4)
    T0[:3, :3], T0[:3, 3] = R0, [0.1, -0.02, 0.03]
    T_goal[:3, 3] = [0.09, 0.0, 0.05]
    poses = freeing_poses(T0, T_goal)
    np.testing.assert_array_equal(poses[0], T_goal)
    turned, shifted = set(), set()
    for T in poses[1:]:
        dR = T[:3, :3] @ R0.T
        angle = np.arccos(np.clip((np.trace(dR) - 1.0) / 2.0, -1.0, 1.0))
        axis = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
        if angle > 1e-9:  # a turn about a palm axis, the position kept
            np.testing.assert_allclose(T[:3, 3], T0[:3, 3], atol=1e-12)
            assert angle == pytest.approx(FREE_TURN, abs=1e-9)
            k = int(np.argmax(np.abs(axis)))
            np.testing.assert_allclose(np.delete(axis, k), 0.0, atol=1e-9)
            turned.add((k, float(np.sign(axis[k]))))
        else:  # a shift along a palm axis, the orientation kept
            shift = T[:3, 3] - T0[:3, 3]
            k = int(np.argmax(np.abs(shift)))
            assert abs(shift[k]) == pytest.approx(FREE_SHIFT, abs=1e-12)
            np.testing.assert_allclose(np.delete(shift, k), 0.0, atol=1e-12)
            shifted.add((k, float(np.sign(shift[k]))))
    assert turned == shifted == {(k, s) for k in range(3) for s in (-1.0, 1.0)}


def test_the_obstruction_names_a_link_in_the_bowl_as_the_references_see_it(stalled):
    g0, hand = stalled.grasp0, stalled.hand
    q, T = np.asarray(g0.q, float), np.asarray(g0.T_palm_object, float)
    thumb = hand.fingers.index("thumb")
    why = reach_obstruction(hand, stalled.obj, q, T, stalled.grasp_goal.tip_centers_object[thumb], "thumb",
                            stalled.grasp_goal.q)
    q_reach, e = _goal_reach(stalled, q, T, "thumb")
    assert np.linalg.norm(e) <= REACH_TOL
    assert why == "object" and _link_depth_reference(stalled, q_reach, T, "thumb") < -5e-4


def test_the_obstruction_is_none_at_the_goal_grasp_and_reach_for_a_goal_a_metre_away(stalled):
    goal, hand = stalled.grasp_goal, stalled.hand
    q, T = np.asarray(goal.q, float), np.asarray(goal.T_palm_object, float)
    for r, finger in enumerate(hand.fingers):
        assert reach_obstruction(hand, stalled.obj, q, T, goal.tip_centers_object[r], finger, goal.q) == ""
    far = goal.tip_centers_object[0] + np.array([1.0, 0.0, 0.0])
    assert reach_obstruction(hand, stalled.obj, q, T, far, hand.fingers[0], goal.q) == "reach"


@pytest.mark.slow  # 59 s in the default run, which must stay under 10 minutes (CI at 9 min 25 s with it)
def test_the_bowl_is_reposed_until_the_thumb_reaches_its_goal_cleanly_then_the_thumb_moves(stalled):
    hand, goal = stalled.hand, stalled.grasp_goal
    options = PlannerOptions(method="sd", stability="none")
    run = _Run(stalled.grasp0, goal, options, NLPCache(max_size=8))
    thumb = hand.fingers.index("thumb")
    error_before = run.steps[-1].contact_error[thumb]
    n_steps = len(run.steps)
    assert free_finger(run, "thumb")
    added = run.steps[n_steps:]
    assert [s.kind for s in added[:-1]] == ["repose"] * (len(added) - 1) and len(added) >= 2
    assert added[-1].kind == "gait" and added[-1].finger == "thumb"
    assert all(s.path is not None and s.path.ok for s in added)
    # at the pose the gait was taken from, the thumb's goal IK is clear of the bowl (references)
    T = added[-2].T_palm_object
    q_reach, e = _goal_reach(stalled, added[-2].q, T, "thumb")
    assert np.linalg.norm(e) <= REACH_TOL and _link_depth_reference(stalled, q_reach, T, "thumb") >= -1e-4
    # the thumb's contact (trimesh's closest point) is nearer its goal than at the stall
    tip = (hand.tip_positions(added[-1].q)[thumb] - T[:3, 3]) @ T[:3, :3]
    (contact,), (distance,), _ = trimesh.proximity.closest_point(stalled.obj.mesh, tip[None])
    assert abs(distance - hand.tip_radius) <= 5e-4
    assert np.linalg.norm(contact - goal.contacts_object[thumb]) < error_before - 5e-3


def test_nothing_is_reposed_for_a_finger_at_its_goal(stalled):
    run = _Run(stalled.grasp0, stalled.grasp_goal, PlannerOptions(method="sd", stability="none"),
               NLPCache(max_size=8))
    nearest = int(np.argmin(run.steps[-1].contact_error))
    assert run.steps[-1].contact_error[nearest] < 1e-3
    n_steps, T = len(run.steps), run.T_palm_object.copy()
    assert not free_finger(run, run.fingers[nearest])
    assert len(run.steps) == n_steps
    np.testing.assert_array_equal(run.T_palm_object, T)


def test_free_after_must_be_a_count_or_none(stalled):
    plan = plan_regrasp(stalled.grasp0, stalled.grasp_goal, stability="none", free_after=-1)
    assert plan.status == "invalid_input" and "free_after" in plan.status_detail


def test_going_back_to_the_branch_restores_the_run_and_its_warm_starts(stalled):
    options = PlannerOptions(method="sd", stability="none", free_after=None)  # the round itself: off
    run = _Run(stalled.grasp0, stalled.grasp_goal, options, NLPCache(max_size=8))
    rounds = EndRounds()
    q0, T0, n_steps = run.q.copy(), run.T_palm_object.copy(), len(run.steps)
    warm = [None] * len(run.warm_starts())
    rounds.branch = (Fallback(n_steps, q0, T0, FinalMoves("no_gain", 0, ()), run.iterations), 1, 2, warm)
    for _ in range(3):  # the steps, iterations and solves made since
        run.q = run.q + 0.01
        run.T_palm_object = run.T_palm_object @ make_T(np.eye(3), [0.001, 0.0, 0.0])
        run.add_step("repose", None, "", 0.0)
        run.iterations += 1
        run.errors.append(0.0)
    run.repose(escape=True)  # a solve: the SVD NLP's warm start is set when it succeeds
    assert any(w.is_warm for w in run.warm_starts())
    rounds.polished, rounds.repostured = 2, 3
    assert not rounds.free_from_branch(run, options)  # the round is off: the run stays at the branch
    assert len(run.steps) == n_steps and run.iterations == 0 and len(run.errors) == 1
    np.testing.assert_array_equal(run.q, q0)
    np.testing.assert_array_equal(run.T_palm_object, T0)
    assert not any(w.is_warm for w in run.warm_starts())
    assert (rounds.polished, rounds.repostured, rounds.freed, rounds.branch) == (1, 2, 1, None)
    rounds.branch = (Fallback(n_steps, q0, T0, FinalMoves("no_gain", 0, ()), 0), 1, 2, warm)
    assert not rounds.free_from_branch(run, options) and rounds.branch is not None  # once per plan


def test_a_plan_whose_retry_from_the_branch_fails_counts_the_retry_s_solves(stalled, monkeypatch):
    from regrasp_casadi import planner

    options = PlannerOptions(method="sd", stability="none")
    run = _Run(stalled.grasp0, stalled.grasp_goal, options, NLPCache(max_size=8))
    tries = []

    def stalls(grasp0, grasp_goal, options, t_start, run, progress, stop, *, rounds):
        run.solves["opt2"] += 5  # each try's solves
        tries.append(dict(run.solves))
        rounds.branch = (Fallback(len(run.steps), run.q, run.T_palm_object, FinalMoves("no_gain", 0, ()),
                                  0), 0, 0, [])
        return planner._make_plan(grasp0, grasp_goal, options, t_start, run, "stalled", "stalled")

    monkeypatch.setattr(planner, "_iterate_from", stalls)
    monkeypatch.setattr(EndRounds, "free_from_branch", lambda self, run, options: True)
    plan = planner._iterate(stalled.grasp0, stalled.grasp_goal, options, 0.0, run, None, SimpleNamespace(
        requested=False))
    assert len(tries) == 2 and plan.status == "stalled"
    assert "did not lead to convergence" in plan.status_detail
    assert plan.options["solves"]["opt2"] == tries[1]["opt2"] == tries[0]["opt2"] + 5


@pytest.mark.slow  # plans of the bowl and the flat tool: in the slow run
def test_the_pair_converges_with_the_search_and_not_without():
    pair = RegraspProblem.load(DATA / "bowl_pair_seed7.yaml")
    plan = plan_regrasp(pair.grasp0, pair.grasp_goal, method="sd", stability="none")
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok
    without = plan_regrasp(pair.grasp0, pair.grasp_goal, method="sd", stability="none", free_after=None,
                           restarts=0)
    if without.status == "converged":  # measured 2026-12-08 at 525e128 and since, on a kernel v1300 VM
        pytest.skip("without the search this pair converges on this machine (plans differ across CPUs)")


@pytest.mark.slow
def test_the_bowl_pair_of_seed_19_no_longer_needs_the_search():
    """Until 382901a the bowl pair of seed 19 (SVD) converged only with the freeing search: without it
    the plan did not converge (this test asserted so). Since then a routed finger's `long_gait` must
    bring it nearer along the surface (`surface_route.nearer_goal`), not in a straight line, and the
    pair converges without the search (and with it, in 26 iterations instead of 32: benchmarks README)."""
    pair = RegraspProblem.load(DATA / "bowl_pair_seed19.yaml")
    plan = plan_regrasp(pair.grasp0, pair.grasp_goal, method="svd", stability="none", free_after=None)
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok


@pytest.mark.slow
def test_a_plan_that_converges_without_the_freeing_round_does_not_make_it():
    """The flat tool pair of seed 8 (SVD) stalled when the freeing round was made where the re-posture
    rounds first moved no finger; made only for a plan that does not converge, it is not made here: the
    plan converges by re-gaiting."""
    pair = RegraspProblem.load(DATA / "flat_tool_pair_seed8.yaml")
    plan = plan_regrasp(pair.grasp0, pair.grasp_goal, method="svd", stability="none")
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok
