"""Every shipped problem file (problems/*.yaml) loads and holds a valid regrasp pair, checked with exact
mesh distances and an independent LP force-closure test (μ = 0.5)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from grasp_checks import contact_normals, exact_checks, force_closure_lp

from regrasp_casadi.problem import RegraspProblem

PROBLEMS = sorted((Path(__file__).resolve().parents[1] / "problems").glob("*.yaml"))


def test_required_problems_are_shipped():
    names = {p.stem for p in PROBLEMS}
    assert "box_rotate" in names
    for prefix in ("box_", "cylinder_", "bottle_", "flat_tool_", "cup_"):
        assert any(n.startswith(prefix) for n in names), prefix


@pytest.fixture(scope="module", params=PROBLEMS, ids=[p.stem for p in PROBLEMS])
def problem(request):
    return RegraspProblem.load(request.param)


def test_joints_within_limits(problem):
    hand = problem.hand
    for q in (problem.grasp0.q, problem.grasp_goal.q):
        if q is None:
            continue
        assert len(q) == hand.n_joints
        assert np.all(q >= hand.q_lower) and np.all(q <= hand.q_upper)


def test_initial_grasp_touches_only_with_tips(problem):
    hand, obj, g0 = problem.hand, problem.obj, problem.grasp0
    gap, clearance, labels = exact_checks(hand, obj, g0.q, g0.T_palm_object)
    assert np.max(np.abs(gap)) <= 0.5e-3
    assert np.min(clearance) >= 0.0, labels[int(np.argmin(clearance))]


def test_goal_contacts_on_surface_and_far(problem):
    obj, g0, gg = problem.obj, problem.grasp0, problem.grasp_goal
    assert np.max(np.abs(obj.exact_signed_distance(gg.contacts_object))) <= 0.5e-3
    assert np.mean(np.linalg.norm(gg.contacts_object - g0.contacts_object, axis=1)) >= 0.03


def test_goal_joints_realise_goal_contacts(problem):
    hand, obj, gg = problem.hand, problem.obj, problem.grasp_goal
    if gg.q is None:
        pytest.skip("goal without reference joints")
    gap, _, _ = exact_checks(hand, obj, gg.q, gg.T_palm_object)
    assert np.max(np.abs(gap)) <= 0.5e-3


def test_both_grasps_force_closure(problem):
    hand, obj = problem.hand, problem.obj
    for g in (problem.grasp0, problem.grasp_goal):
        if g.q is not None:
            normals = contact_normals(hand, obj, g.q, g.T_palm_object, g.contacts_object)
        else:
            normals = obj.surface_normals(g.contacts_object)
        assert force_closure_lp(g.contacts_object, normals, 0.5, obj.mesh.center_mass, 0.1)
