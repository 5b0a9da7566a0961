"""plan_regrasp end to end on the shipped problems; every plan is judged by the exact verifier."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from regrasp_casadi import nlp_cache
from regrasp_casadi.finger_gait import FingerGaitOptions
from regrasp_casadi.grasp import Grasp
from regrasp_casadi.plan import Plan
from regrasp_casadi.planner import NLPCache, PlannerOptions, gait_pattern, plan_regrasp
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.transforms import inv_T, transform_points
from regrasp_casadi.verify import verify

PROBLEMS = sorted((Path(__file__).resolve().parents[1] / "problems").glob("*.yaml"))
BOX_PROBLEM = Path(__file__).resolve().parents[1] / "problems" / "box_rotate.yaml"


@pytest.fixture(scope="module")
def box():
    return RegraspProblem.load(BOX_PROBLEM)


CERTIFIED_CONVERGE: set[tuple[str, str]] = set()
"""The shipped problems the certified planner (the default, stability "force_closure") solves: none
(measured, benchmarks/stability.py, 2026-12-02). Since a sliding finger drags the object with kinetic
friction in its certificate, the thumb can no longer slide against three fingers on the opposite face,
and every plan stops before every contact is within ζ (stalled, or a reposing that brings nothing:
status "solver_failure"), with every step certified."""

KNOWN_MOTION_FAILURES: dict[tuple[str, str], str] = {}
"""Plans whose only violations are verify's sampled checks between the steps (`motion_*`; measured). None
since the object follows the hand in reposings (cylinder_slide svd: `test_repose_trajectory`) and
lifts also lean at 2/5 height (bottle_regrasp sd's thumb touch-down: `test_gait_touch_down`)."""
PAPER_STOPS: dict[tuple[str, str], str] = {}
"""Shipped problems on which the paper planner (stability "none") stops before converging (measured);
their plans must still verify. None since the reposing paths' rolling-contact IK (`rolling_ik`, issue 12):
box_shift sd, refused before at step 18 for a path whose IK jumped (knots 15 mm apart) and slid a tip
1.9 mm, converges (4 iterations, max error 5.93 mm; measured 2026-12-03)."""
SD_SLOW = pytest.mark.slow  # the sd half of the shipped problems: in the slow run (time of the default run)
DEFAULT_RUN = ("box_shift",)
"""The shipped problems whose svd plan the default run checks (box_shift's certified plan, ~25 s, is
planned once for the session and shared with test_import_boundaries; the others, 17-32 s each on a 2-core
VM — box_rotate's 24 → 32 s since OPT2's linearised clearance, 2026-12-03 — and every sd plan are in the
slow run, so the default run stays within its 10 minutes)."""


@pytest.mark.parametrize("method", ["svd", pytest.param("sd", marks=SD_SLOW)])
@pytest.mark.parametrize("path", [pytest.param(p, marks=() if p.stem in DEFAULT_RUN else SD_SLOW)
                                  for p in PROBLEMS], ids=[p.stem for p in PROBLEMS])
def test_shipped_problem_plans_hold_the_object_and_verify(path, method, shipped_plan):
    problem, plan = shipped_plan(path.stem, method)
    report = verify(plan, problem.hand, problem.obj)
    if (path.stem, method) in KNOWN_MOTION_FAILURES and report.violations and all(
            v.check.startswith("motion_") for v in report.violations):
        pytest.xfail(KNOWN_MOTION_FAILURES[path.stem, method])
    assert report.ok, report.summary()  # every step certified (unstable_gait) whether converged or not
    assert report.metrics["stability_checked"] and report.metrics["stability"] == "force_closure"
    assert all(s.certificate is not None and s.certificate["ok"] for s in plan.steps)
    kinds = [s.kind for s in plan.steps]
    assert kinds[0] == "initial" and "gait" in kinds
    if (path.stem, method) in CERTIFIED_CONVERGE:
        assert plan.status == "converged", plan.status_detail
        assert np.max(plan.steps[-1].contact_error) <= plan.options["zeta"]
    else:
        assert plan.status in ("converged", "stalled", "iteration_limit", "solver_failure"), \
            plan.status_detail


@pytest.mark.slow  # 8 more plans; the default run checks the paper planner in test_stable_planner
@pytest.mark.parametrize("method", ["svd", "sd"])
@pytest.mark.parametrize("path", PROBLEMS, ids=[p.stem for p in PROBLEMS])
def test_the_paper_planner_converges_on_the_shipped_problems(path, method):
    problem = RegraspProblem.load(path)
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method, stability="none")
    report = verify(plan, problem.hand, problem.obj)
    assert report.ok, report.summary()  # "unstable_gait" is a metric for the paper's plans
    if (path.stem, method) in PAPER_STOPS:
        assert plan.status in ("converged", "stalled", "solver_failure", "iteration_limit"), plan.status
        return
    assert plan.status == "converged", plan.status_detail
    assert np.max(plan.steps[-1].contact_error) <= plan.options["zeta"]


def _count_nlpsol(monkeypatch) -> list[str]:
    """Record the name of every `casadi.nlpsol` call (every NLP built) from now on."""
    calls: list[str] = []
    real = ca.nlpsol

    def counting(name, *args, **kwargs):
        calls.append(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(ca, "nlpsol", counting)
    return calls


def test_no_rebuild_inside_a_plan(monkeypatch):
    fresh = RegraspProblem.load(BOX_PROBLEM)  # a new hand and object: nothing of theirs is cached yet
    nlp_cache.clear_built_solvers()  # nor a solver of the same expressions, built by an earlier test
    built = _count_nlpsol(monkeypatch)
    first = plan_regrasp(fresh.grasp0, fresh.grasp_goal, method="svd", max_iters=4)  # a short plan
    # one OPT1 per finger of the gait and one OPT2 (the svd method reposes with the pose NLP)
    assert len(built) == len(set(first.options["gait_used"])) + 1, built
    assert first.timing["build"] > 0.0
    n_first = len(built)
    second = plan_regrasp(fresh.grasp0, fresh.grasp_goal, method="svd", max_iters=4)
    assert len(second.steps) > 5
    assert len(built) == n_first, f"the second plan built {built[n_first:]}"
    assert second.timing["build"] == 0.0


def test_a_plan_keeps_its_nlps_in_the_cache_it_is_given(box):
    cache, m = NLPCache(), len(box.hand.fingers)
    plan_regrasp(box.grasp0, box.grasp_goal, method="sd", max_iters=1, cache=cache, restarts=0)
    assert cache.builds == m + 2  # OPT1 per finger, OPT2 "sd" and "svd" (final move)
    plan = plan_regrasp(box.grasp0, box.grasp_goal, method="sd", max_iters=1, cache=cache, restarts=0)
    assert cache.builds == m + 2 and plan.timing["build"] == 0.0
    # with its restarts (the plan is cut short): the shorter gaits' OPT1 once per finger, then none
    plan_regrasp(box.grasp0, box.grasp_goal, method="sd", max_iters=1, cache=cache, restarts=3)
    assert cache.builds == 2 * m + 2
    plan = plan_regrasp(box.grasp0, box.grasp_goal, method="sd", max_iters=1, cache=cache, restarts=3)
    assert plan.options["attempts"] == 4 and cache.builds == 2 * m + 2 and plan.timing["build"] == 0.0


def test_same_input_same_plan(box):
    a = plan_regrasp(box.grasp0, box.grasp_goal, method="svd", max_iters=8)
    b = plan_regrasp(box.grasp0, box.grasp_goal, method="svd", max_iters=8)
    assert len(a.steps) == len(b.steps) > 8
    for sa, sb in zip(a.steps, b.steps, strict=True):
        assert np.array_equal(sa.q, sb.q) and np.array_equal(sa.T_palm_object, sb.T_palm_object)


_PLAN_IN_A_FRESH_PROCESS = """
import sys
from regrasp_casadi.planner import plan_regrasp
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.transforms import inv_T, transform_points
problem = RegraspProblem.load(sys.argv[1])
plan_regrasp(problem.grasp0, problem.grasp_goal, method="svd", max_iters=3).save(sys.argv[2])
"""


@pytest.mark.slow  # 13 s in the default run (2026-12-03): the suite over its 10-minute budget
def test_same_plan_in_a_fresh_process(box, tmp_path):
    """The plan depends on its input only: not on the NLP cache and warm starts of this process (which
    has planned before), nor on hash randomisation."""
    out = tmp_path / "plan.json"
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    subprocess.run([sys.executable, "-c", _PLAN_IN_A_FRESH_PROCESS, str(BOX_PROBLEM), str(out)],
                   check=True, env=env, timeout=300)
    plan_regrasp(box.grasp0, box.grasp_goal, method="sd", max_iters=1)  # other warm starts in the cache
    here = plan_regrasp(box.grasp0, box.grasp_goal, method="svd", max_iters=3)
    there = Plan.load(out)
    assert (there.status, there.iterations) == (here.status, here.iterations)
    assert len(there.steps) == len(here.steps) > 3
    for a, b in zip(here.steps, there.steps, strict=True):
        assert (a.kind, a.finger) == (b.kind, b.finger)
        assert np.array_equal(a.q, b.q) and np.array_equal(a.T_palm_object, b.T_palm_object)
    assert np.array_equal(here.iteration_errors, there.iteration_errors)


def test_iteration_limit_is_a_status_with_a_partial_plan(box):
    plan = plan_regrasp(box.grasp0, box.grasp_goal, method="svd", max_iters=1, restarts=0)
    assert plan.status == "iteration_limit"
    assert plan.iterations == 1 and len(plan.iteration_errors) == 2
    assert len(plan.steps) >= 2  # the initial grasp and what the iteration did
    assert verify(plan, box.hand, box.obj).ok  # what was planned is still valid


def _box_contact_errors(problem, step) -> np.ndarray:
    """Closed-form contact errors (m,) of a step on the box problem: the closest point of a tip centre
    outside an origin-centred box is the centre clipped to the box."""
    half = np.asarray(problem.obj.spec["extents"]) / 2
    tips_object = transform_points(inv_T(step.T_palm_object), problem.hand.tip_positions(step.q))
    assert np.all(np.max(np.abs(tips_object) - half, axis=1) > 0)  # every tip centre is outside
    contacts = np.clip(tips_object, -half, half)
    return np.linalg.norm(contacts - problem.grasp_goal.contacts_object, axis=1)


def test_recorded_errors_are_the_contact_distances_and_fall_below_zeta(box):
    plan = plan_regrasp(box.grasp0, box.grasp_goal, method="svd", stability="none")  # the paper's planner
    assert plan.status == "converged", plan.status_detail
    initial = np.linalg.norm(box.grasp0.contacts_object - box.grasp_goal.contacts_object, axis=1)
    assert plan.iteration_errors[0] == pytest.approx(np.mean(initial), abs=1e-12)
    for k, step in enumerate(plan.steps):
        np.testing.assert_allclose(step.contact_error, _box_contact_errors(box, step), atol=1e-12,
                                   err_msg=f"step {k}")
    # every iteration's error is the mean error of one of the plan's steps (the last of the iteration)
    step_means = np.array([np.mean(s.contact_error) for s in plan.steps])
    for e in plan.iteration_errors:
        assert np.min(np.abs(step_means - e)) <= 1e-15
    assert plan.iterations == len(plan.iteration_errors) - 1
    # the problem asks to move the contacts by ≥ 3 cm on average; the plan ends below ζ
    assert plan.iteration_errors[0] >= 0.03
    assert plan.iteration_errors[-1] <= plan.options["zeta"]
    assert np.max(plan.steps[-1].contact_error) <= plan.options["zeta"]


def test_invalid_input_is_a_status(box):
    goal_without_joints = box.grasp_goal
    plan = plan_regrasp(goal_without_joints if goal_without_joints.q is None else
                        Grasp.from_contacts(box.hand, box.obj, box.grasp0.contacts_object,
                                            box.grasp0.T_palm_object),
                        box.grasp_goal)
    assert plan.status == "invalid_input" and "joint angles" in plan.status_detail
    plan = plan_regrasp(box.grasp0, box.grasp_goal, gait=("index", "pinky"))
    assert plan.status == "invalid_input" and "pinky" in plan.status_detail
    plan = plan_regrasp(box.grasp0, box.grasp_goal, sd_escape_gain=-1e-3)
    assert plan.status == "invalid_input" and "sd_escape_gain" in plan.status_detail
    for bad in ({"final_max_iterations": -1}, {"final_max_iterations": 2.5}, {"final_time_budget": -1.0}):
        plan = plan_regrasp(box.grasp0, box.grasp_goal, **bad)
        assert plan.status == "invalid_input" and next(iter(bad)) in plan.status_detail


def test_plan_round_trips_through_json(box, tmp_path):
    plan = plan_regrasp(box.grasp0, box.grasp_goal, method="svd", max_iters=2)
    plan.save(tmp_path / "plan.json")
    loaded = Plan.load(tmp_path / "plan.json")
    assert loaded == plan


def test_gait_pattern_rule(box):
    hand = box.hand
    contacts = np.array(box.grasp0.contacts_object)
    goal = np.array(contacts)
    i, m = hand.fingers.index("index"), hand.fingers.index("middle")
    goal[i] = contacts[i] + 0.1 * (contacts[i] - contacts[m])  # beyond the index finger: far from middle
    assert gait_pattern(hand, contacts, goal) == ("index", "middle", "ring", "thumb")
    goal[i] = contacts[m] + 0.001 * (contacts[m] - contacts[i])  # next to the middle finger
    assert gait_pattern(hand, contacts, goal) == ("thumb", "ring", "middle", "index")


def _gait_step_lengths(hand, plan) -> list[float]:
    """Palm-frame displacement (m) of the moving fingertip in each gait step."""
    lengths = []
    for before, step in zip(plan.steps[:-1], plan.steps[1:], strict=True):
        if step.kind == "gait":
            r = hand.fingers.index(step.finger)
            moved = hand.tip_positions(step.q)[r] - hand.tip_positions(before.q)[r]
            lengths.append(float(np.linalg.norm(moved)))
    return lengths


def test_overrides_reach_the_nlp_options():
    o = PlannerOptions().with_overrides(eta=0.008, beta=0.002, k_pos=50.0, method="sd", gait=["index"])
    assert (o.finger_gait.eta, o.finger_gait.beta, o.in_grasp.beta, o.in_grasp.k_pos) == (0.008, 0.002,
                                                                                          0.002, 50.0)
    assert o.in_grasp.k_orient == 10.0 and o.method == "sd" and o.gait == ("index",)
    assert PlannerOptions().finger_gait == FingerGaitOptions(eta=0.01, beta=0.001)  # the paper's η, β
    assert (PlannerOptions().zeta, PlannerOptions().in_grasp.k_pos) == (0.006, 1000.0)  # ζ, k1
    with pytest.raises(TypeError, match="max_iter"):
        PlannerOptions().with_overrides(max_iter=3)


def test_options_are_recorded_by_value_and_take_effect(box, tmp_path):
    # the paper's planner (no certificate: the thumb lifts first, off three fingers on one face)
    given = PlannerOptions(zeta=0.005, gait=("thumb", "index", "middle", "ring"),
                           stability="none").with_overrides(eta=0.008)
    plan = plan_regrasp(box.grasp0, box.grasp_goal, options=given, max_iters=1)
    expected = {**given.to_dict(), "max_iters": 1}
    assert expected["finger_gait"]["eta"] == 0.008
    assert expected["gait"] == ["thumb", "index", "middle", "ring"]
    plan.save(tmp_path / "plan.json")
    for recorded in (plan.options, Plan.load(tmp_path / "plan.json").options):
        assert {k: recorded[k] for k in expected} == expected
        assert recorded["gait_used"] == ["thumb", "index", "middle", "ring"]
    # the recorded η is the one used: every gait step is bounded by 8 mm, and the far goals make the
    # bound active (with the default η = 10 mm the same gaits step 10 mm)
    lengths = _gait_step_lengths(box.hand, plan)
    assert len(lengths) == 4
    assert max(lengths) <= 0.008 + 1e-6
    assert min(lengths) >= 0.008 - 1e-5
    assert [s.finger for s in plan.steps if s.kind == "gait"] == ["thumb", "index", "middle", "ring"]


def test_package_level_verify_accepts_valid_and_rejects_planted_violations(box):
    import regrasp_casadi

    plan = plan_regrasp(box.grasp0, box.grasp_goal, method="svd", max_iters=1)
    report = regrasp_casadi.verify(plan, box.hand, box.obj)
    assert report.ok, report.summary()
    # plant a joint-limit violation: step 1's first joint 0.1 rad beyond its upper limit
    hand = box.hand
    q = np.array(plan.steps[1].q)
    q[0] = hand.q_upper[0] + 0.1
    bad = replace(plan, steps=(plan.steps[0], replace(plan.steps[1], q=q), *plan.steps[2:]))
    report = regrasp_casadi.verify(bad, box.hand, box.obj)
    assert not report.ok
    limit = [v for v in report.violations if v.check == "joint_limit"]
    assert [(v.step, v.who) for v in limit] == [(1, hand.joint_names[0])]
    assert limit[0].amount == pytest.approx(0.1, abs=1e-12)


def test_stability_gait_order_plans_and_verifies(box):
    """The paper's planner with the gait order of largest force-closure margin converges and verifies."""
    plan = plan_regrasp(box.grasp0, box.grasp_goal, method="sd", gait_order="stability", stability="none")
    assert plan.status == "converged", plan.status_detail
    assert verify(plan, box.hand, box.obj).ok
    bad = plan_regrasp(box.grasp0, box.grasp_goal, gait_order="random")
    assert bad.status == "invalid_input" and "gait_order" in bad.status_detail


@pytest.mark.reference_data
def test_a_ycb_regrasp_converges_and_verifies(reference_dir):
    """One of the benchmark's YCB pairs (the sugar box, a coacd-decomposed scanned mesh), with the paper's
    planner (stability "none"): catches what the generated objects cannot, e.g. a distance model that is
    accurate on primitives only. (The certified planner stalls on sugar-box_0 25 mm short since a sliding
    finger drags the object in its certificates; measured.)"""
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "problems" / "sugar-box_0.yaml"
    problem = RegraspProblem.load(path)
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method="svd", stability="none")
    assert plan.status == "converged", plan.status_detail
    report = verify(plan, problem.hand, problem.obj)
    assert report.ok, report.summary()


def test_unreachable_goal_ends_with_a_status_and_a_valid_partial_plan(box):
    """Goal contacts mirrored through the box centre (the opposite faces: every finger on the far side)
    and a desired pose 30 cm away: no plan reaches it; the planner says so and what it did is valid."""
    mirrored = -np.asarray(box.grasp0.contacts_object)  # the box is centred at its origin
    T_far = np.array(box.grasp0.T_palm_object)
    T_far[:3, 3] += [0.3, 0.0, 0.0]
    goal = Grasp.from_contacts(box.hand, box.obj, mirrored, T_far)
    plan = plan_regrasp(box.grasp0, goal, method="svd", max_iters=6, restarts=0)
    assert plan.status in ("iteration_limit", "stalled", "solver_failure")
    assert plan.iterations <= 6 and np.max(plan.steps[-1].contact_error) > plan.options["zeta"]
    assert verify(plan, box.hand, box.obj).ok
