"""The planner refuses an in-grasp move whose reposing path fails its checks (`planner._Run.unrealisable`):
a reposing of bottle_regrasp's svd plan by the paper planner (tests/data/bottle_repose_into_the_bottle.yaml)
whose path puts a middle-finger link into the bottle, judged by the exact distance of the link's collision
spheres at verify's samples of the path (`verify_motion.sample_plan_motion`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from step_pairs import step_pair

from regrasp_casadi.planner import NLPCache, PlannerOptions, _Run
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.trajectory import plan_trajectories
from regrasp_casadi.verify_motion import sample_plan_motion

BOTTLE_REPOSE = Path(__file__).resolve().parent / "data" / "bottle_repose_into_the_bottle.yaml"


@pytest.fixture(scope="module")
def bottle_repose():
    return step_pair(BOTTLE_REPOSE, "repose")


def _deepest_non_tip(hand, obj, steps, path) -> float:
    """Deepest penetration (m, > 0 inside) of any non-tip collision sphere into the object at the samples
    verify takes of the path, by the exact mesh distance."""
    samples = sample_plan_motion([steps[0], replace(steps[1], path=path)], hand)
    radii = np.asarray(hand.sphere_radii(None, include_tip=False), dtype=float)
    worst = -np.inf
    for q, T in zip(samples.q, samples.T_palm_object, strict=True):
        c_palm = np.asarray(hand.sphere_centers(q, None, include_tip=False), dtype=float).reshape(-1, 3)
        _, sd = obj.closest_points((c_palm - T[:3, 3]) @ T[:3, :3])  # exact, m
        worst = max(worst, float(np.max(radii - np.asarray(sd, dtype=float))))
    return worst


def test_the_reposing_path_puts_a_link_into_the_bottle(bottle_repose):
    hand, obj, steps = bottle_repose
    path = plan_trajectories(steps, hand, obj)[1]
    assert not path.ok and "inside the object" in path.detail
    assert _deepest_non_tip(hand, obj, steps, path) > 5e-4


def test_the_planner_refuses_that_move_and_not_a_clear_one(bottle_repose):
    hand, obj, steps = bottle_repose
    problem = RegraspProblem.load(BOTTLE_REPOSE)
    run = _Run(problem.grasp0, problem.grasp_goal, PlannerOptions(stability="none"), NLPCache(max_size=4))
    why, refused = run.unrealisable(steps[1].q, steps[1].T_palm_object)
    assert "inside the object" in why and not refused.ok
    q_mid = 0.5 * (steps[0].q + steps[1].q)  # a tiny move whose path stays clear: accepted
    near = replace(steps[1], q=0.99 * steps[0].q + 0.01 * q_mid, T_palm_object=steps[0].T_palm_object)
    path = plan_trajectories([steps[0], near], hand, obj)[1]
    assert (run.unrealisable(near.q, near.T_palm_object)[0] == "") == path.ok
    off = _Run(problem.grasp0, problem.grasp_goal, PlannerOptions(stability="none", trajectories=False),
               NLPCache(max_size=4))
    assert off.unrealisable(steps[1].q, steps[1].T_palm_object) == ("", None)  # without trajectories
