"""The staging search (`regrasp_casadi.staging`): a support configuration that certifies a pinned finger's
slide, judged by the LP certificate of `certificates` (not the planner's Ferrari–Canny ε that the search
uses), on the shipped box_shift problem, whose thumb opposes the other three fingers."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from regrasp_casadi.certificates import certify_step
from regrasp_casadi.planner import NLPCache, PlannerOptions, _Run
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.resources import package_data_dir
from regrasp_casadi.staging import _path, find_staging, pinned_finger


@pytest.fixture(scope="module")
def run():
    problem = RegraspProblem.load(package_data_dir("problems") / "box_shift.yaml")
    return _Run(problem.grasp0, problem.grasp_goal, PlannerOptions(trajectories=False), NLPCache(max_size=8))


def _lp_ok(contacts, normals, hold, sliding) -> bool:
    """The LP force-closure verdict (μ 0.5, the sliding fingers frictionless)."""
    return certify_step(contacts, normals, hold, "force_closure", 0.5, sliding=sliding, solver="lp").ok


def _slide_ok(contacts, normals, finger: int, path_c, path_n) -> list[bool]:
    m = len(contacts)
    out = []
    for c_k, n_k in zip(path_c, path_n, strict=True):
        c, n = contacts.copy(), normals.copy()
        c[finger], n[finger] = c_k, n_k
        out.append(_lp_ok(c, n, np.ones(m, bool), np.arange(m) == finger))
    return out


def _pinned_by_lp(run, finger: str) -> bool:
    """Neither the lift of `finger` nor its frictionless slide to its goal is in force closure (LP)."""
    m, i = len(run.fingers), run.fingers.index(finger)
    contacts, normals = run.holding.contacts(run.q, run.T_palm_object)
    path_c, path_n = _path(run, contacts, normals, i)
    return (not _lp_ok(contacts, normals, np.arange(m) != i, np.zeros(m, bool))
            and not all(_slide_ok(contacts, normals, i, path_c, path_n)))


def test_the_thumb_of_box_shift_is_pinned(run):
    """The thumb cannot lift (three fingers on one face) and its frictionless slide to its goal is not
    certified with the others where they are: the case the staging exists for. The finger
    `pinned_finger` names (the farthest pinned one) is pinned by the LP too."""
    assert _pinned_by_lp(run, "thumb")
    finger = pinned_finger(run)
    assert finger is not None and _pinned_by_lp(run, finger)


def test_staging_certifies_the_whole_slide_and_can_be_reached(run):
    """With the other fingers at the staging's contacts, every sample of the pinned finger's slide to its
    goal is in force closure by the LP (that finger frictionless), and the moved fingers get there one
    by one with LP-certified lifts in some order; the pinned finger's row is its goal."""
    finger = pinned_finger(run)
    stage = find_staging(run, finger)
    assert stage is not None and stage.finger == finger
    m, i = len(run.fingers), run.fingers.index(finger)
    np.testing.assert_allclose(stage.tips[i], run.goal_tips[i])
    contacts_now, normals_now = run.holding.contacts(run.q, run.T_palm_object)
    tips = stage.tips.copy()
    tips[i] = contacts_now[i] + run.hand.tip_radius * normals_now[i]
    contacts, sd = run.obj.closest_points(tips)
    assert np.all(np.abs(np.asarray(sd) - run.hand.tip_radius) < 1e-6)  # the targets are on the surface
    normals = (tips - contacts) / np.linalg.norm(tips - contacts, axis=1, keepdims=True)
    path_c, path_n = _path(run, contacts, normals, i)
    assert all(_slide_ok(contacts, normals, i, path_c, path_n))
    moved = [j for j in range(m) if j != i and np.linalg.norm(contacts[j] - contacts_now[j]) > 1e-9]
    assert moved

    def reachable(order) -> bool:
        c, n = contacts_now.copy(), normals_now.copy()
        for j in order:
            if not _lp_ok(c, n, np.arange(m) != j, np.zeros(m, bool)):
                return False
            c[j], n[j] = contacts[j], normals[j]
        return True

    assert any(reachable(order) for order in itertools.permutations(moved))


def test_staging_is_reproducible(run):
    """The same run and seed give the same staging (plans are deterministic)."""
    a, b = (find_staging(run, pinned_finger(run), seed=3) for _ in range(2))
    assert a is not None and b is not None
    np.testing.assert_array_equal(a.tips, b.tips)
