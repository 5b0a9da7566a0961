"""The object-pose feedback of `simulate` (`sim_feedback`): its rigid correction against a closed form, and
in physics, a planted plan whose object pose the joints alone do not realise."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sim_plans import BOX_SHIFT, make_plan

from regrasp_casadi.mujoco_model import SimOptions, build_model
from regrasp_casadi.sim_feedback import ObjectPoseFeedback, rigid_tip_corrections
from regrasp_casadi.simulate import simulate


def _pose(rotvec, p) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = p
    return T


def test_rigid_correction_carries_attached_points_onto_the_plan():
    """Points fixed in the object (p = T_sim c) moved by δ land where the planned pose puts them
    (T_plan c); the correction is zero when the poses agree."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        T_sim = _pose(rng.normal(size=3), rng.normal(size=3) * 0.05)
        T_plan = _pose(rng.normal(size=3), rng.normal(size=3) * 0.05)
        c = rng.normal(size=(4, 3)) * 0.04
        p_sim = c @ T_sim[:3, :3].T + T_sim[:3, 3]
        p_plan = c @ T_plan[:3, :3].T + T_plan[:3, 3]
        np.testing.assert_allclose(p_sim + rigid_tip_corrections(T_plan, T_sim, p_sim), p_plan, atol=1e-12)
        np.testing.assert_allclose(rigid_tip_corrections(T_sim, T_sim, p_sim), 0.0, atol=1e-12)


@pytest.fixture(scope="module")
def shifted_plan(hand):
    """box_shift's grasp0, then a "repose" step with the same joints and the box 3 mm further along the
    palm's +y (a pose the joints alone do not give: only the feedback can move the box there)."""
    from regrasp_casadi import RegraspProblem

    problem = RegraspProblem.load(BOX_SHIFT)
    g0 = problem.grasp0
    T1 = g0.T_palm_object.copy()
    T1[:3, 3] += [0.0, 0.003, 0.0]
    plan = make_plan(hand, problem.obj, [("initial", None, g0.q, g0.T_palm_object),
                                         ("repose", None, g0.q, T1)])
    return plan, problem


@pytest.mark.parametrize("feedback", ["none", "object_pose"])
def test_feedback_moves_the_object_onto_its_planned_pose(hand, shifted_plan, feedback):
    """Open loop the box stays where the joints hold it, 3 mm from the plan's second pose; with the
    object-pose feedback it is carried there (within 0.5 mm at the end of a 1 s hold), still held."""
    plan, problem = shifted_plan
    report = simulate(plan, hand, problem.obj, SimOptions(feedback=feedback, hold_time=1.0))
    final = report.steps[-1]
    assert not report.dropped, report.summary()
    if feedback == "none":
        assert final.deviation_mm > 2.5, report.summary()
    else:
        assert final.deviation_mm < 0.5 and final.deviation_deg < 1.0, report.summary()
        assert len(final.fingers_touching) == 4, report.summary()


def _law(hand, q, T_plan, T_sim, holding, dt, *, offset, opts) -> np.ndarray:
    """The module docstring's law, finger by finger, with the project's CasADi tip centres and Jacobians at
    q (not MuJoCo's): (m, n) offsets after one update of ``offset`` (m, n)."""
    E = T_plan @ np.linalg.inv(T_sim)
    p_palm_tips = hand.tip_positions(q)
    out = np.array(offset, dtype=float)
    for m, finger in enumerate(hand.fingers):
        if holding[m] <= 0.0:
            out[m] *= max(0.0, 1.0 - opts.feedback_gain * dt)
            continue
        J = hand.tip_jacobian(q, finger)
        delta = E[:3, :3] @ p_palm_tips[m] + E[:3, 3] - p_palm_tips[m]
        step = J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(3), delta)
        out[m] += opts.feedback_gain * dt * holding[m] * step
        reach = np.linalg.norm(J @ out[m])
        if reach > opts.feedback_limit:
            out[m] *= opts.feedback_limit / reach
    return out


def test_feedback_update_is_the_law_with_the_projects_jacobians(hand, shifted_plan):
    """Two updates of `ObjectPoseFeedback` (the palm turned in the world, the box 5 mm and 3° off its
    planned pose) equal the law written per finger with the project's kinematics: a holding finger moves
    by k_I dt w J⁺ δ, its tip displacement capped at `feedback_limit` (some fingers capped, some not), a
    finger that stops holding decays by (1 − k_I dt)."""
    _, problem = shifted_plan
    opts = SimOptions(palm_wxyz=(np.cos(0.4), np.sin(0.4) * 0.6, 0.0, np.sin(0.4) * 0.8),
                      feedback_limit=0.003)
    sim = build_model(hand, problem.obj, opts)
    data = mujoco.MjData(sim.model)
    q = problem.grasp0.q
    data.qpos[sim.qpos_hand] = q
    mujoco.mj_forward(sim.model, data)  # the Jacobians need the com-based quantities too
    T_sim = np.asarray(problem.grasp0.T_palm_object, dtype=float)
    T_plan = _pose([0.02, -0.03, 0.04], [0.004, -0.003, 0.0]) @ T_sim
    feedback = ObjectPoseFeedback(sim, hand.fingers, opts)
    expected = np.zeros((len(hand.fingers), hand.n_joints))
    for holding, dt in (([1.0, 0.3, 1.0, 0.6], 0.1), ([1.0, 0.0, 0.5, 1.0], 0.05)):
        previous = expected
        expected = _law(hand, q, T_plan, T_sim, holding, dt, offset=previous, opts=opts)
        offset = feedback.update(data, T_plan, T_sim, np.array(holding), dt)
        np.testing.assert_allclose(feedback.offset, expected, atol=1e-9)
        np.testing.assert_allclose(offset, expected.sum(axis=0), atol=1e-9)
    np.testing.assert_allclose(expected[1], 0.5 * previous[1], atol=1e-15)  # decayed: k_I dt = 0.5
    reach = np.array([np.linalg.norm(hand.tip_jacobian(q, f) @ expected[m])
                      for m, f in enumerate(hand.fingers)])
    assert np.isclose(reach, opts.feedback_limit).any() and (reach < 0.9 * opts.feedback_limit).any(), reach


def test_grip_force_update_is_the_law_with_the_projects_jacobians(hand, shifted_plan):
    """Two updates of `GripForceFeedback` (palm turned in the world) equal its law written per finger with
    the project's kinematics: a holding finger short of its planned normal force f* moves by
    k_F dt w Jᵀ(−n)(f* − f)/kp, one at or above it does not move, one that stops holding (or has no
    planned force) decays by (1 − k_F dt); the tip displacement is capped at `force_limit_offset`."""
    from regrasp_casadi.sim_grip_feedback import GripForceFeedback

    _, problem = shifted_plan
    opts = SimOptions(palm_wxyz=(np.cos(0.4), np.sin(0.4) * 0.6, 0.0, np.sin(0.4) * 0.8), force_gain=4.0,
                      force_limit_offset=0.0015)
    sim = build_model(hand, problem.obj, opts)
    data = mujoco.MjData(sim.model)
    q = problem.grasp0.q
    data.qpos[sim.qpos_hand] = q
    mujoco.mj_forward(sim.model, data)
    n_palm = np.array([[0.0, -1.0, 0.0], [0.0, -0.8, 0.6], [0.6, -0.8, 0.0], [0.0, 1.0, 0.0]])
    feedback = GripForceFeedback(sim, hand.fingers, opts)
    expected = np.zeros((len(hand.fingers), hand.n_joints))
    updates = (([0.2, 0.5, 0.0, 0.9], [1.0, 1.0, 2.0, 1.0], [1.0, 1.0, 1.0, 0.5], 0.1),
               ([0.2, 1.5, 0.0, 0.9], [30.0, 1.0, 0.0, 1.0], [1.0, 1.0, 1.0, 0.0], 0.05))
    for f_measured, f_target, holding, dt in updates:
        previous = expected.copy()
        for m, finger in enumerate(hand.fingers):
            if holding[m] <= 0.0 or f_target[m] <= 0.0:
                expected[m] *= 1.0 - opts.force_gain * dt
                continue
            J = hand.tip_jacobian(q, finger)
            short = max(f_target[m] - f_measured[m], 0.0)
            expected[m] += opts.force_gain * dt * holding[m] * J.T @ (-n_palm[m] * short) / opts.kp
            reach = np.linalg.norm(J @ expected[m])
            if reach > opts.force_limit_offset:
                expected[m] *= opts.force_limit_offset / reach
        offset = feedback.update(data, np.array(f_measured), np.array(f_target), n_palm, np.array(holding),
                                 dt)
        np.testing.assert_allclose(feedback.offset, expected, atol=1e-9)
        np.testing.assert_allclose(offset, expected.sum(axis=0), atol=1e-9)
    assert np.abs(previous[1]).max() > 0  # short of its target at the first update: it moved
    np.testing.assert_allclose(expected[1], previous[1], atol=1e-15)  # above it at the second: unchanged
    np.testing.assert_allclose(expected[3], 0.8 * previous[3], atol=1e-15)  # stopped holding: k_F dt = 0.2
    reach = np.linalg.norm(hand.tip_jacobian(q, "index") @ expected[0])
    assert np.isclose(reach, opts.force_limit_offset)  # 30 N short: capped
