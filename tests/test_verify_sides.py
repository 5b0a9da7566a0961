"""`verify`'s "goal_side" check: a plan that says "converged" with a fingertip across a thin wall from its
goal (the contact within ζ of the goal contact, on the wall's other face) is rejected; a tip on the inner
top of a rim whose goal is on the outer top is not.

Data: `tests/data/bowl_middle_on_the_rim_plan.json`, the last grasp of the generated bowl pair of seed 15
(SD), relabelled "converged" at its own pose. References: trimesh's ray casting (the wall's other face),
trimesh's closest points and face normals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from regrasp_casadi.plan import Plan
from regrasp_casadi.problem import plan_models
from regrasp_casadi.verify import verify
from regrasp_casadi.verify_sides import SIDE_DEPTH

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="module")
def rim():
    plan = Plan.load(DATA / "bowl_middle_on_the_rim_plan.json")
    hand, obj = plan_models(plan, None, None)
    step = plan.steps[-1]
    tips = (hand.tip_positions(step.q) - step.T_palm_object[:3, 3]) @ step.T_palm_object[:3, :3]
    return plan, hand, obj, tips


def _other_face(mesh: trimesh.Trimesh, contact: np.ndarray, tip: np.ndarray) -> np.ndarray:
    """Where a ray from just under `contact`, into the object against its outward normal (towards the tip
    centre `tip`), leaves the wall (trimesh)."""
    n = (tip - contact) / np.linalg.norm(tip - contact)
    origin = contact - 1e-5 * n
    hits, _, _ = mesh.ray.intersects_location(origin[None], -n[None])
    return hits[int(np.argmin(np.linalg.norm(hits - origin, axis=1)))]


def test_a_tip_on_the_inner_top_of_the_rim_whose_goal_is_on_the_outer_top_passes(rim):
    plan, hand, obj, tips = rim
    middle = plan.fingers.index("middle")
    (contact,), _, _ = trimesh.proximity.closest_point(obj.mesh, tips[[middle]])
    goal = plan.goal_contacts_object[middle]
    (goal_face,) = trimesh.proximity.closest_point(obj.mesh, goal[None])[2]
    n_contact = (tips[middle] - contact) / np.linalg.norm(tips[middle] - contact)
    angle = np.degrees(np.arccos(n_contact @ obj.mesh.face_normals[goal_face]))
    assert angle > 100.0 and np.linalg.norm(contact - goal) <= 6e-3  # within ζ, facing apart
    report = verify(plan, hand, obj)
    assert report.ok, report.summary()


def test_a_converged_claim_with_a_tip_across_the_wall_from_its_goal_is_rejected(rim):
    plan, hand, obj, tips = rim
    d = plan.to_dict()
    index = plan.fingers.index("index")
    contact = np.asarray(plan.steps[-1].contacts_object[index], float)
    across = _other_face(obj.mesh, contact, tips[index])
    wall = float(np.linalg.norm(across - contact))
    assert 2e-3 <= wall <= 6e-3  # the bowl's wall: within ζ
    d["goal_contacts_object"][index] = across.tolist()
    d["steps"][-1]["contact_error"][index] = wall  # the stored error as verify recomputes it
    report = verify(Plan.from_dict(d), hand, obj)
    rows = [(v.check, v.who) for v in report.violations]
    assert rows == [("goal_side", "index")], report.summary()
    (depth,) = [v.amount for v in report.violations]
    assert SIDE_DEPTH < depth <= wall + 1e-4  # through the wall, no deeper than it is thick
    assert verify(Plan.from_dict({**d, "status": "stalled"}), hand, obj).ok  # only a claim is judged
