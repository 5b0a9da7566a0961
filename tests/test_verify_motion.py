"""verify's motion rows (`regrasp_casadi.verify_motion`, issue 15 item 5): planted faults between two valid
steps (a finger swung through another, a tip pushed into the object) fail verify with the step, the time
and the links named; the sampling rule against an independent FK; a plan's motion judged whole."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from regrasp_casadi.motion import StepPath, time_stamps
from regrasp_casadi.plan import Plan, PlanStep
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.transforms import inv_T, transform_points
from regrasp_casadi.verify import CHECKS, verify
from regrasp_casadi.verify_motion import MAX_POINT_STEP, lever_arms, sample_plan_motion

REPO = Path(__file__).resolve().parents[1]
VENDOR = REPO.parent / "shared" / "reference" / "allegro_right" / "allegro_hand_right.urdf"
MOTION_CHECKS = ("motion_penetration", "motion_self_collision", "motion_joint_limit", "motion_held_contact",
                 "motion_slip")


@pytest.fixture(scope="module")
def box():
    """problems/box_rotate.yaml (a 0.05 × 0.07 × 0.12 m box; its grasps keep the fingers apart): hand,
    object, half extents (m), initial joints and pose."""
    problem = RegraspProblem.load(REPO / "problems" / "box_rotate.yaml")
    half = np.asarray(problem.obj.spec["extents"], dtype=float) / 2.0
    q0, T0 = np.asarray(problem.grasp0.q), np.asarray(problem.grasp0.T_palm_object)
    return problem.hand, problem.obj, half, q0, T0


def _box_sd(p: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Closed-form signed distance of points (..., 3) to the box |x_i| ≤ half_i (object frame), m."""
    d = np.abs(p) - half
    return np.linalg.norm(np.maximum(d, 0.0), axis=-1) + np.minimum(np.max(d, axis=-1), 0.0)


def _step(hand, half, kind: str, finger: str | None, q, T, path: StepPath | None = None) -> PlanStep:
    tips = transform_points(inv_T(T), hand.tip_positions(q))
    return PlanStep(kind=kind, finger=finger, q=np.asarray(q, float), T_palm_object=T,
                    contacts_object=np.clip(tips, -half, half), contact_error=np.zeros(len(tips)),
                    solver_status="", solve_time=0.0, path=path)


def _plan(steps: list[PlanStep]) -> Plan:
    return Plan(steps=tuple(steps), goal_contacts_object=steps[-1].contacts_object,
                goal_T_palm_object=steps[-1].T_palm_object, fingers=("index", "middle", "ring", "thumb"),
                hand_spec={"model": "allegro_right"},
                object_spec={"primitive": "box", "extents": [0.05, 0.07, 0.12]}, method="svd",
                status="iteration_limit", status_detail="", iterations=1, iteration_errors=np.zeros(2),
                timing={"total": 0.0}, options={})


def _out_and_back(hand, half, finger: str, q0, q_far, T) -> tuple[Plan, float]:
    """A gait of `finger` that goes from q0 to q_far and back (both steps at q0): the plan and the time
    of the far knot (s, 1 rad/s)."""
    Q = np.stack([q0, q_far, q0])
    t = time_stamps(Q)
    path = StepPath(t=t, q=Q, T_palm_object=np.repeat(T[None], 3, axis=0), phases=("lift", "touch_down"),
                    ok=True, detail="")
    steps = [_step(hand, half, "initial", None, q0, T), _step(hand, half, "gait", finger, q0, T, path)]
    return _plan(steps), t[1]


def _time_in(message: str) -> float:
    return float(re.search(r"t = ([0-9.]+) s into its motion", message).group(1))


def test_the_motion_rows_are_registered():
    assert set(MOTION_CHECKS) <= set(CHECKS)


# ------------------------------------------------------------------------------------ planted faults
def test_a_finger_swung_through_another_fails_with_step_time_and_links(box):
    hand, obj, half, q0, T = box
    q_far = q0.copy()
    q_far[hand.finger_joints["middle"][0]] = 0.0  # the middle finger's abduction, across the index finger
    plan, t_far = _out_and_back(hand, half, "middle", q0, q_far, T)
    report = verify(plan, hand, obj)
    assert not [v for v in report.violations if not v.check.startswith("motion_")]  # both steps are fine
    hits = [v for v in report.violations if v.check == "motion_self_collision"]
    assert hits and {v.step for v in hits} == {1}
    finger_of = {s.link: s.finger for s in hand.spheres}
    pairs = {tuple(sorted(finger_of[link] for link in v.who.split("|"))) for v in hits}
    assert pairs == {("index", "middle")}
    worst = min(hits, key=lambda v: v.amount)
    assert _time_in(worst.message) == pytest.approx(t_far, abs=1e-3)  # deepest where the swing turns back
    for link in worst.who.split("|"):
        assert link in worst.message
    assert "step 1" in worst.message and worst.amount < -5e-3
    if VENDOR.is_file():  # the real link meshes intersect there too (independent of the spheres)
        from regrasp_casadi.link_meshes import LinkMeshes

        meshes, note = LinkMeshes.from_urdf(VENDOR, hand)
        if meshes is None:
            pytest.skip(note)
        crossed = {tuple(sorted((meshes.finger_of[a], meshes.finger_of[b])))
                   for a, b, _ in meshes.intersections(q_far)}
        assert ("index", "middle") in crossed


def _pushed_in(hand, q0, T, finger: str, depth: float, half) -> np.ndarray:
    """Joints putting `finger`'s tip centre `depth` m further into its face than it is at q0 (scipy IK,
    the other tips where they are)."""
    i = hand.fingers.index(finger)
    tip = transform_points(inv_T(T), hand.tip_positions(q0))[i]
    face = int(np.argmax(np.abs(tip) - half))
    target = tip.copy()
    target[face] -= np.sign(tip[face]) * depth
    joints = hand.finger_joints[finger]

    def residual(x):
        q = q0.copy()
        q[joints] = x
        return transform_points(T, target[None])[0] - hand.tip_positions(q)[i]

    sol = least_squares(residual, q0[joints], bounds=(hand.q_lower[joints], hand.q_upper[joints]),
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    q = q0.copy()
    q[joints] = sol.x
    assert np.max(np.abs(residual(sol.x))) < 1e-6
    return q


def test_a_penetrating_interpolation_fails_with_step_time_and_link(box):
    hand, obj, half, q0, T = box
    q_in = _pushed_in(hand, q0, T, "ring", 0.003, half)
    plan, t_in = _out_and_back(hand, half, "ring", q0, q_in, T)
    report = verify(plan, hand, obj)
    assert not [v for v in report.violations if not v.check.startswith("motion_")]
    hits = {v.who: v for v in report.violations if v.check == "motion_penetration"}
    tip_link = next(s.link for s in hand.spheres if s.is_tip and s.finger == "ring")
    assert tip_link in hits
    v = hits[tip_link]
    assert v.step == 1 and tip_link in v.message and "ring" in v.message
    p_tip = transform_points(inv_T(T), hand.tip_positions(q_in))[hand.fingers.index("ring")]
    expected = float(_box_sd(p_tip, half)) - hand.tip_radius  # closed form: −3 mm
    assert expected == pytest.approx(-0.003, abs=1e-5)
    assert v.amount == pytest.approx(expected, abs=1e-6)
    assert _time_in(v.message) == pytest.approx(t_in, abs=1e-3)


def test_a_holding_tip_that_leaves_the_surface_fails_held_contact(box):
    hand, obj, half, q0, T = box
    q_in = _pushed_in(hand, q0, T, "ring", -0.002, half)  # lifted 2 mm off the face
    Q = np.stack([q0, q_in, q0])
    path = StepPath(t=time_stamps(Q), q=Q, T_palm_object=np.repeat(T[None], 3, axis=0),
                    phases=("repose", "repose"), ok=True, detail="")
    plan = _plan([_step(hand, half, "initial", None, q0, T), _step(hand, half, "repose", None, q0, T, path)])
    found = {(v.check, v.who): v.amount for v in verify(plan, hand, obj).violations}
    p_tip = transform_points(inv_T(T), hand.tip_positions(q_in))[hand.fingers.index("ring")]
    expected = float(_box_sd(p_tip, half)) - hand.tip_radius  # closed form: 2 mm
    assert expected == pytest.approx(0.002, abs=1e-5)
    assert found[("motion_held_contact", "ring")] == pytest.approx(expected, abs=1e-6)
    assert ("motion_slip", "ring") not in found  # lifted straight off its face: its closest point stays
    assert all(who == "ring" for _, who in found)


# ----------------------------------------------------------------------------------- sampling rule
def _surface_points(hand, q: np.ndarray) -> np.ndarray:
    """(6·S, 3) points on every collision sphere (centre ± radius along the link axes), palm frame."""
    frames = hand.fk(q)
    pts = []
    for s in hand.spheres:
        T = frames[s.link]
        for u in np.vstack([np.eye(3), -np.eye(3)]):
            pts.append(T[:3, :3] @ (s.center_link + s.radius * u) + T[:3, 3])
    return np.array(pts)


def test_lever_arm_bounds_the_motion_of_every_sphere_point(box):
    hand = box[0]
    levers = lever_arms(hand)
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(hand.q_lower, hand.q_upper)
        dq = rng.normal(size=hand.n_joints) * 0.01
        moved = np.linalg.norm(_surface_points(hand, q + dq) - _surface_points(hand, q), axis=1)
        bound = max(levers[f] * np.sum(np.abs(dq[hand.finger_joints[f]])) for f in hand.fingers)
        assert np.max(moved) <= bound


def test_samples_move_no_sphere_point_more_than_1_mm(box):
    hand, obj, half, q0, T = box
    q_far = q0.copy()
    q_far[hand.finger_joints["ring"]] += [0.2, -0.3, -0.3, -0.2]
    plan, _ = _out_and_back(hand, half, "ring", q0, hand.clip(q_far), T)
    samples = sample_plan_motion(plan.steps, hand)
    points = np.stack([_surface_points(hand, q) for q in samples.q])
    moved = np.max(np.linalg.norm(np.diff(points, axis=0), axis=2), axis=1)
    assert np.max(moved) <= MAX_POINT_STEP and samples.max_point_step <= MAX_POINT_STEP + 1e-12
    assert np.array_equal(samples.q[0], q0) and np.array_equal(samples.q[-1], q0)


def test_a_straight_line_between_steps_without_paths_is_judged(box):
    """Steps without a path move in a straight line (as `Plan.sample` replays them): a repose that turns
    the object while the hand holds still sweeps the box through the tips."""
    hand, obj, half, q0, T = box
    from regrasp_casadi.transforms import make_T, rot_axis_angle

    T_b = make_T(rot_axis_angle([0.0, 0.0, 1.0], np.radians(10.0)) @ T[:3, :3], T[:3, 3])
    plan = _plan([_step(hand, half, "initial", None, q0, T), _step(hand, half, "repose", None, q0, T_b)])
    report = verify(plan, hand, obj)
    assert {v.check for v in report.violations} & {"motion_held_contact", "motion_penetration"}
    assert report.metrics["motion_samples"] > 2
