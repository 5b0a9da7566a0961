"""verify(): a valid hand-built plan passes; each planted violation is reported with step, check and who.

The plans use the two-finger test hand of `twofinger.py` holding a box between its tips, so every
expected distance has a closed form (box contacts are clipped tip centres).
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import twofinger as tf

from regrasp_casadi.plan import Plan, PlanStep
from regrasp_casadi.verify import verify

GOAL = np.array([[-0.03, 0.0, -0.01], [0.03, 0.0, 0.01]])
HALF = np.array(tf.BOX_EXTENTS) / 2
OPTIONS = {"eta": 0.01, "zeta": 0.006, "beta": 0.001}


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    return tf.make_hand(tmp_path_factory.mktemp("hand")), tf.make_box()


def _q(hand, **joints) -> np.ndarray:
    q = np.zeros(hand.n_joints)
    for name, v in joints.items():
        q[hand.joint_names.index(name)] = v
    return q


def _box_contacts(hand, q, T):
    """Closed-form closest points on the (axis-aligned, object-frame) box of the tip centres."""
    R, p = T[:3, :3], T[:3, 3]
    centers = (hand.tip_positions(q) - p) @ R
    return np.clip(centers, -HALF, HALF)


def _plan(hand, obj, specs, status=None) -> Plan:
    """specs: list of (kind, finger, q, T). Contacts and errors are computed in closed form."""
    steps = []
    for kind, finger, q, T in specs:
        c = _box_contacts(hand, q, T)
        steps.append(PlanStep(kind, finger, q, T, c, np.linalg.norm(c - GOAL, axis=1),
                              "" if kind == "initial" else "Solve_Succeeded", 0.001))
    if status is None:
        status = "converged" if np.max(steps[-1].contact_error) <= OPTIONS["zeta"] else "iteration_limit"
    return Plan(steps=tuple(steps), goal_contacts_object=GOAL, goal_T_palm_object=tf.box_pose(dz=0.002),
                fingers=tuple(hand.fingers), hand_spec=hand.spec(), object_spec=obj.spec, method="svd",
                status=status, status_detail="", iterations=1,
                iteration_errors=np.array([0.01, 0.005]), timing={"total": 0.01}, options=dict(OPTIONS))


def _valid_specs(hand, gait_left=-0.005, lift_right=0.0, roll0=0.0, follow=True):
    """initial → gait left → gait right → repose (+4 mm in z) → final (−2 mm in z)."""
    s1 = _q(hand, left_slide=gait_left)
    s2 = _q(hand, left_slide=gait_left, right_slide=0.005, right_base=lift_right)
    d3 = 0.004 if follow else 0.0
    s3 = _q(hand, left_slide=gait_left + d3, right_slide=0.005 + d3)
    s4 = _q(hand, left_slide=gait_left + d3 - 0.002, right_slide=0.005 + d3 - 0.002)
    return [
        ("initial", None, _q(hand, left_roll=roll0), tf.box_pose()),
        ("gait", "left", s1, tf.box_pose()),
        ("gait", "right", s2, tf.box_pose()),
        ("repose", None, s3, tf.box_pose(dz=0.004)),
        ("final", None, s4, tf.box_pose(dz=0.002)),
    ]


def _found(report):
    """The static rows' findings (step, check, who); the motion rows (``motion_*``, see
    tests/test_verify_motion.py) also see a planted fault of a step along the straight line to it."""
    return {(v.step, v.check, v.who) for v in report.violations if not v.check.startswith("motion_")}


def test_valid_plan_is_ok_with_closed_form_metrics(models):
    hand, obj = models
    plan = _plan(hand, obj, _valid_specs(hand))
    report = verify(plan, hand, obj)
    assert report.ok, report.summary()
    m = report.metrics
    # nearest non-tip sphere: left_1#0 at (-0.04, 0, 0.05), r = 12 mm, box corner edge at (-0.03, ·, 0.09)
    assert m["min_clearance"] == pytest.approx(np.hypot(0.01, 0.04) - 0.012, abs=1e-9)
    assert m["min_clearance_at"] == {"step": 0, "who": "left_1#0"}
    assert m["max_gait_step"] == pytest.approx(0.005, abs=1e-12)
    assert m["max_slip"] == pytest.approx(0.0, abs=1e-9)
    assert m["max_surface_error"] == pytest.approx(0.0, abs=1e-9)
    # final contacts: left z = -0.005, right z = +0.005, goal ∓0.01 -> 5 mm each
    assert m["final_avg_error"] == pytest.approx(0.005, abs=1e-9)
    assert m["final_max_error"] == pytest.approx(0.005, abs=1e-9)
    assert m["n_steps"] == 5
    assert "verify: OK" in report.summary()


def test_valid_plan_passes_after_json_round_trip_and_default_models(models, tmp_path):
    hand, obj = models
    plan = Plan.load(_plan(hand, obj, _valid_specs(hand)).save(tmp_path / "p.json"))
    report = verify(plan)  # hand and object rebuilt from the plan's specs
    assert report.ok, report.summary()
    assert report.to_dict()["ok"] is True


def test_joint_limit(models):
    hand, obj = models
    report = verify(_plan(hand, obj, _valid_specs(hand, roll0=1.2)), hand, obj)
    assert _found(report) == {(0, "joint_limit", "left_roll")}
    assert report.violations[0].amount == pytest.approx(0.2, abs=1e-12)
    assert not report.ok


def test_penetration(models):
    hand, obj = models
    specs = _valid_specs(hand)
    kind, finger, q, _ = specs[3]
    specs[3] = (kind, finger, q, tf.box_pose(dz=-0.05))  # box z in [0.04, 0.08]: link spheres at z = 0.05
    report = verify(_plan(hand, obj, specs), hand, obj)
    clear = {(v.step, v.who): v.amount for v in report.violations if v.check == "clearance"}
    # sphere centre 10 mm from the ±x faces, radius 12 mm -> 2 mm penetration, both fingers
    assert clear == pytest.approx({(3, "left_1#0"): -0.002, (3, "right_1#0"): -0.002}, abs=1e-9)
    assert (3, "tip_surface", "left") in _found(report)


def test_lifted_tip(models):
    hand, obj = models
    a = 0.05
    report = verify(_plan(hand, obj, _valid_specs(hand, lift_right=a)), hand, obj)
    assert _found(report) == {(2, "tip_surface", "right")}
    # tip centre x = 0.04 + (0.09 + 0.005) sin a; box face at 0.03; radius 0.01
    expected = 0.04 + 0.095 * np.sin(a) - 0.03 - 0.01
    assert report.violations[0].amount == pytest.approx(expected, abs=1e-9)
    assert "right tip is" in report.violations[0].message


def test_too_long_gait(models):
    hand, obj = models
    report = verify(_plan(hand, obj, _valid_specs(hand, gait_left=-0.015)), hand, obj)
    assert _found(report) == {(1, "gait_step", "left")}
    assert report.violations[0].amount == pytest.approx(0.015, abs=1e-12)
    assert report.violations[0].limit == 0.01
    # the plan's own eta does not loosen the bound; the caller's does
    loose = Plan.from_dict({**_plan(hand, obj, _valid_specs(hand, gait_left=-0.015)).to_dict(),
                            "options": {**OPTIONS, "eta": 0.02}})
    assert _found(verify(loose, hand, obj)) == {(1, "gait_step", "left")}
    assert verify(loose, hand, obj).metrics["plan_options"]["eta"] == 0.02
    assert verify(_plan(hand, obj, _valid_specs(hand, gait_left=-0.015)), hand, obj, eta=0.02).ok


def test_slip_during_repose(models):
    hand, obj = models
    report = verify(_plan(hand, obj, _valid_specs(hand, follow=False)), hand, obj)
    slips = {(v.step, v.check, v.who): v.amount for v in report.violations
             if not v.check.startswith("motion_")}
    assert slips == pytest.approx({(3, "slip", "left"): 0.004, (3, "slip", "right"): 0.004}, abs=1e-9)


def test_gait_moving_other_finger_or_object(models):
    hand, obj = models
    specs = _valid_specs(hand)
    kind, finger, q, T = specs[1]
    q = q.copy()
    q[hand.joint_names.index("right_roll")] = 0.3
    specs[1] = (kind, finger, q, tf.box_pose(dy=0.001))
    specs[2] = (specs[2][0], specs[2][1], specs[2][2], tf.box_pose(dy=0.001))
    found = _found(verify(_plan(hand, obj, specs), hand, obj))
    assert (1, "gait_other_joints", "right_roll") in found
    assert (1, "gait_object_moved", "left") in found


def test_false_claims_and_inconsistent_contacts(models):
    hand, obj = models
    plan = _plan(hand, obj, _valid_specs(hand, follow=False), status="converged")
    d = plan.to_dict()
    d["steps"][1]["contacts_object"][0][2] += 0.002  # stored left contact 2 mm off its tip
    d["steps"][2]["contact_error"][1] += 0.001  # stored right error 1 mm off
    found = _found(verify(Plan.from_dict(d), hand, obj))
    assert (4, "converged_claim", "") in found
    assert (1, "contact_consistency", "left") in found
    assert (2, "contact_error", "right") in found


def test_verify_does_not_use_smooth_distance_or_nlps(models, monkeypatch):
    hand, obj = models

    def boom(*args, **kwargs):
        raise AssertionError("verify used the smooth distance")

    monkeypatch.setattr(type(obj), "signed_distance", boom)
    monkeypatch.setattr(type(obj), "signed_distance_function", boom)
    assert verify(_plan(hand, obj, _valid_specs(hand)), hand, obj).ok
    code = ("import sys, regrasp_casadi.verify; "
            "bad = [m for m in ('finger_gait', 'in_grasp', 'planner', 'terms') "
            "if 'regrasp_casadi.' + m in sys.modules]; print(bad); sys.exit(1 if bad else 0)")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, check=False).returncode == 0


def test_checks_are_a_table_of_named_functions(models):
    """Every check name in the table reports under that name, and a check added to the table runs."""
    from regrasp_casadi import verify as verify_module

    hand, obj = models
    names = [c.name for c in verify_module.CHECK_TABLE]
    assert tuple(names) == verify_module.CHECKS and len(set(names)) == len(names)
    extra = verify_module.Check("always", lambda ctx, k, step: [verify_module.Finding("", k, 0, "x")])
    table = verify_module.CHECK_TABLE
    try:
        verify_module.CHECK_TABLE = (*table, extra)
        report = verify(_plan(hand, obj, _valid_specs(hand)), hand, obj)
    finally:
        verify_module.CHECK_TABLE = table
    assert [(v.step, v.check, v.amount) for v in report.violations] == [(k, "always", k) for k in range(5)]


def test_two_point_contacts_never_hold_a_plan_that_claims_force_closure(models):
    # two antipodal point contacts cannot resist a torque about the line through them: every step of
    # the two-finger plan (both tips, or one alone during a gait) is unstable when the plan asks for it
    hand, obj = models
    plan = _plan(hand, obj, _valid_specs(hand))
    paper = verify(plan, hand, obj)
    assert paper.ok and paper.metrics["stability_checked"] is False
    assert paper.metrics["uncertified_steps"] == [0, 1, 2, 3, 4]  # a metric for a plan made without
    claimed = replace(plan, options={**plan.options, "stability": "force_closure"})
    report = verify(claimed, hand, obj)
    who = ["", "left", "right", "", ""]
    assert _found(report) == {(k, "unstable_gait", who[k]) for k in range(5)}
    assert all(v.amount <= 0.0 for v in report.violations)


def test_slide_steps_are_judged_along_their_path(models):
    hand, obj = models
    slide = _q(hand, left_slide=-0.006)  # the left tip moves 6 mm down the −x face, on it throughout
    specs = [("initial", None, _q(hand), tf.box_pose()), ("slide", "left", slide, tf.box_pose())]
    report = verify(_plan(hand, obj, specs), hand, obj)
    assert report.ok, report.summary()
    assert report.metrics["max_slide_path_error"] == pytest.approx(0.0, abs=1e-9)
    assert report.metrics["max_gait_step"] == pytest.approx(0.006, abs=1e-12)
    # a "slide" that swings the finger off the face, and one that moves the other finger and the object
    off = _q(hand, left_base=0.1)
    moved = _q(hand, left_slide=-0.006, right_slide=0.002)
    bad = [("initial", None, _q(hand), tf.box_pose()), ("slide", "left", off, tf.box_pose()),
           ("slide", "left", moved, tf.box_pose(dx=0.001))]
    found = _found(verify(_plan(hand, obj, bad), hand, obj))
    assert (1, "slide_path", "left") in found and (1, "tip_surface", "left") in found
    assert (2, "gait_other_joints", "right_slide") in found and (2, "gait_object_moved", "left") in found
    assert not any(check == "slip" for _, check, _ in found)  # a slide's own contact moves by design


@pytest.fixture(scope="module")
def forged_plan(tmp_path_factory):
    """A real one-iteration plan of problems/box_shift.yaml (valid but far from the goal), relabelled
    "converged" and claiming ζ = 1 m in its options."""
    from pathlib import Path

    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem

    problem = RegraspProblem.load(Path(__file__).resolve().parents[1] / "problems" / "box_shift.yaml")
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method="svd", max_iters=1, restarts=0)
    assert plan.status == "iteration_limit" and verify(plan, problem.hand, problem.obj).ok
    d = plan.to_dict()
    d["status"], d["options"] = "converged", {**d["options"], "zeta": 1.0}
    path = Plan.from_dict(d).save(tmp_path_factory.mktemp("forged") / "forged.json")
    return problem, Plan.load(path), path


def test_a_forged_converged_claim_is_rejected_whatever_the_plan_says(forged_plan):
    problem, plan, _ = forged_plan
    error = float(np.max(plan.steps[-1].contact_error))
    assert error > 0.02  # one iteration leaves the contacts centimetres from the goal
    report = verify(plan, problem.hand, problem.obj)
    rows = [(v.step, v.check, v.who, v.amount, v.limit) for v in report.violations]
    assert (len(plan.steps) - 1, "converged_claim", "", pytest.approx(error, abs=1e-12), 0.006) in rows
    assert report.metrics["plan_options"]["zeta"] == 1.0 and report.metrics["tolerances"]["zeta"] == 0.006
    dp, dr = _pose_error_by_scipy(plan)
    assert dp > 2e-3 and dr > np.radians(2.0)  # one iteration: the object far from the desired pose too
    assert (len(plan.steps) - 1, "converged_claim", "object", pytest.approx(dp, abs=1e-9), 2e-3) in rows
    assert (len(plan.steps) - 1, "converged_claim", "object", pytest.approx(dr, abs=1e-6),
            pytest.approx(np.radians(2.0))) in rows
    assert len(rows) == 3
    loose = {"zeta": error + 1e-3, "pose_tol_position": dp + 1e-3, "pose_tol_rotation": dr + 1e-3}
    assert verify(plan, problem.hand, problem.obj, **loose).ok  # the caller may loosen them


def _pose_error_by_scipy(plan) -> tuple[float, float]:
    """(m, rad) of the last step's object pose from the desired one: translation distance and the
    rotation vector's norm of R_lastᵀ R_goal (scipy)."""
    from scipy.spatial.transform import Rotation

    T, G = plan.steps[-1].T_palm_object, plan.goal_T_palm_object
    angle = np.linalg.norm(Rotation.from_matrix(T[:3, :3].T @ G[:3, :3]).as_rotvec())
    return float(np.linalg.norm(T[:3, 3] - G[:3, 3])), float(angle)


def test_cli_verify_judges_with_its_own_zeta(forged_plan, capsys):
    from regrasp_casadi.cli import main

    _, plan, path = forged_plan
    error_mm = float(np.max(plan.steps[-1].contact_error)) * 1e3
    assert main(["verify", str(path)]) == 1
    assert "converged_claim" in capsys.readouterr().out
    dp, dr = _pose_error_by_scipy(plan)
    pose = ["--pose-tol-position", f"{dp * 1e3 + 1:.3f}", "--pose-tol-rotation", f"{np.degrees(dr) + 1:.3f}"]
    assert main(["verify", str(path), "--zeta", f"{error_mm + 1:.3f}", *pose]) == 0
    assert main(["verify", str(path), "--zeta", f"{error_mm + 1:.3f}"]) == 1  # the pose rows remain
    assert main(["verify", str(path), "--zeta", f"{error_mm - 1:.3f}", *pose]) == 1
    assert main(["verify", str(path), "--zeta", "-1"]) == 2


def test_a_slide_held_only_by_its_drag_is_uncertified(models):
    """The left tip slides 6 mm along −z on the box's −x face; gravity g (cos 60° x̂ + sin 60° ẑ) presses
    the box onto the right tip and pulls it up, against the left tip's drag. With the contacts on the x
    axis through the centre of mass, the torque about y asks for equal tangential forces at the two tips,
    so the weight's z part W_z needs a drag μ a_L = W_z / 2 from the left tip (held: the right one's
    friction W_z / 2 ≤ μ a_R, a_R = a_L + W_x), while a frictionless left tip, as at the slide's start
    and end, carries no W_z at all. verify certifies a slide with the drag and without, so the slide is
    an `unstable_gait`; with gravity along +x only (the right tip carries the box, the left need not
    press, so it drags nothing) it passes."""
    hand, obj = models
    q0, q1 = _q(hand), _q(hand, left_slide=-0.006)
    specs = [("initial", None, q0, tf.box_pose()), ("slide", "left", q1, tf.box_pose())]
    plan = _plan(hand, obj, specs)
    d = hand.tip_positions(q1)[0] - hand.tip_positions(q0)[0]
    np.testing.assert_allclose(d / np.linalg.norm(d), [0.0, 0.0, -1.0], atol=1e-12)
    tilted = 9.81 * np.array([np.cos(np.pi / 3), 0.0, np.sin(np.pi / 3)])
    for g, uncertified in ((tilted, True), (np.array([9.81, 0.0, 0.0]), False)):
        options = {**OPTIONS, "stability": "gravity", "gravity_palm": g.tolist(), "object_mass": 0.1}
        report = verify(replace(plan, options=options), hand, obj)
        assert ((1, "unstable_gait", "left") in _found(report)) == uncertified, report.summary()
        assert report.metrics["uncertified_steps"] == ([1] if uncertified else [])
