"""A gait's touch-down keeps the moving finger clear of the palm (issue 15): the thumb touch-down of an
earlier bottle_regrasp plan, judged by the exact sphere distances at the samples verify takes."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from step_pairs import step_pair

from regrasp_casadi.plan import PlanStep
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.self_collision import pair_distances
from regrasp_casadi.trajectory import plan_trajectories
from regrasp_casadi.verify_motion import sample_plan_motion, sphere_centres

BOTTLE_THUMB = Path(__file__).resolve().parent / "data" / "bottle_thumb_touch_down.yaml"
"""Steps 23 -> 24 of bottle_regrasp's sd plan by the paper planner at 0e26b1d: a thumb gait whose
touch-down (the thumb 1.06 mm from palm sphere palm_link#6 at its contact) passed 0.007 mm through that
sphere: the straight lift from the new contact and every lean at full or 3/5 height swing link_15.0 into
the palm."""


@pytest.fixture(scope="module")
def thumb_gait():
    return step_pair(BOTTLE_THUMB, "gait", "thumb")


def test_the_thumb_touch_down_stays_clear_of_the_palm_at_verifys_samples(thumb_gait):
    hand, obj, steps = thumb_gait
    path = plan_trajectories(steps, hand, obj)[1]
    assert path.metrics["min_self_clearance"] >= 0.0, path.detail
    assert "overlaps" not in path.detail
    samples = sample_plan_motion([steps[0], replace(steps[1], path=path)], hand)
    gaps = pair_distances(hand, sphere_centres(hand, samples.q), hand.self_collision_pairs())  # (N, P), m
    assert float(np.min(gaps)) >= 1e-4  # verify requires ≥ 0; measured 0.32 mm (was −0.007 mm)
    down = np.array([ph == "touch_down" for ph in samples.phase])
    palm = [k for k, (a, b) in enumerate(hand.self_collision_pairs())
            if hand.spheres[a].finger is None or hand.spheres[b].finger is None]
    assert down.any() and float(np.min(gaps[down][:, palm])) >= 1e-4


BOTTLE_MIDDLE = Path(__file__).resolve().parent / "data" / "bottle_middle_lift_at_limits.yaml"
"""Steps 4 -> 5 of bottle_regrasp's sd plan by the certified planner (a0822ef): a middle gait whose
lift-off, the finger held at two joint limits, reaches no candidate height; the 40° lean at 2/5 height
keeps it farthest from the other fingers but drives the tip 0.70 mm into the bottle."""


def test_a_lift_off_that_reaches_no_height_still_rises_off_the_surface():
    problem = RegraspProblem.load(BOTTLE_MIDDLE)
    hand, obj = problem.hand, problem.obj
    steps = [PlanStep(kind=kind, finger=finger, q=g.q, T_palm_object=g.T_palm_object,
                      contacts_object=g.contacts_object, contact_error=np.zeros(len(g.contacts_object)),
                      solver_status="", solve_time=0.0)
             for kind, finger, g in (("initial", None, problem.grasp0),
                                     ("gait", "middle", problem.grasp_goal))]
    path = plan_trajectories(steps, hand, obj)[1]
    assert "lift-off" in path.detail  # the limits keep every lift short of its height
    assert path.metrics["lift_height"] >= 1e-3  # but the tip rises β off the bottle
    assert path.metrics["min_transit_clearance"] >= 1e-3
    assert path.metrics["min_tip_clearance"] >= -5e-4
