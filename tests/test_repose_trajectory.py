"""Reposing paths (issue 15): the held tips stay on the object's exact surface at the samples verify takes,
also where a finger held at two joint limits cannot follow the interpolated object pose (the object
follows the hand, `repose_trajectory`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from step_pairs import step_pair

from regrasp_casadi import repose_trajectory
from regrasp_casadi.grasp_metrics import object_contacts, tip_frames, tip_slip
from regrasp_casadi.stability import contact_normals
from regrasp_casadi.tip_ik import joints_at_limits
from regrasp_casadi.trajectory import plan_trajectories
from regrasp_casadi.verify_motion import sample_plan_motion

DATA = Path(__file__).resolve().parent / "data"
CYLINDER_REPOSE = DATA / "cylinder_repose_middle_at_limits.yaml"
"""Steps 60 -> 61 of cylinder_slide's svd plan (certified planner): a reposing with the middle finger's
joint_5.0 and joint_7.0 at their limits at both ends."""
HELD_TOL = 3e-4
"""The held tips' largest |exact distance − tip radius| at verify's samples, m (verify allows 0.5 mm)."""


@pytest.fixture(scope="module")
def cylinder_repose():
    return step_pair(CYLINDER_REPOSE, "repose")


def _held_surface_error(hand, obj, steps, path) -> float:
    """Largest |exact distance − tip radius| of every tip (all hold in a reposing) at the samples verify's
    motion rows take of the path (`verify_motion.sample_plan_motion`), m."""
    samples = sample_plan_motion([steps[0], replace(steps[1], path=path)], hand)
    tips = np.stack([hand.tip_positions(q) for q in samples.q])
    T = samples.T_palm_object
    p_object = np.einsum("kij,kmi->kmj", T[:, :3, :3], tips - T[:, None, :3, 3])
    _, sd = obj.closest_points(p_object.reshape(-1, 3))
    return float(np.max(np.abs(np.asarray(sd) - hand.tip_radius)))


def test_the_middle_finger_is_held_at_two_joint_limits(cylinder_repose):
    hand, _, steps = cylinder_repose
    for step in steps:
        assert joints_at_limits(hand, step.q, hand.finger_joints["middle"]) == ["joint_5.0", "joint_7.0"]


def _end_slides(hand, obj, steps):
    """How far each tip slides over the object between the step's two ends (m,), m (`tip_slip`)."""
    (pa, Ra), (pb, Rb) = (tip_frames(hand, s.q, s.T_palm_object) for s in steps)
    normals = contact_normals(object_contacts(obj, pa), pa) + contact_normals(object_contacts(obj, pb), pb)
    return tip_slip(pa, Ra, pb, Rb, normals, hand.tip_radius)


def test_a_reposing_path_keeps_the_held_tips_on_the_cylinder_at_verifys_samples(cylinder_repose):
    """The path keeps the tips on the surface. The step itself was planned with fixed contacts (before
    the rolling tips): its ends slide the tips 3.5-6.2 mm over the cylinder, and its path says so, as
    its only problem, with the slide of its ends (the path's tips roll, they add none)."""
    hand, obj, steps = cylinder_repose
    path = plan_trajectories(steps, hand, obj)[1]
    slides = _end_slides(hand, obj, steps)
    assert np.max(slides) > 3e-3
    assert path.detail == f"a tip slides {path.metrics['max_slip'] * 1e3:.3f} mm over the object (> 1.00 mm)"
    assert path.metrics["max_slip"] == pytest.approx(np.max(slides), abs=1e-4)
    assert path.metrics["max_pose_correction"] > 1e-4  # the object follows the hand here
    assert path.metrics["max_surface_error"] <= HELD_TOL
    assert _held_surface_error(hand, obj, steps, path) <= HELD_TOL
    assert np.array_equal(path.T_palm_object[0], steps[0].T_palm_object)
    assert np.array_equal(path.T_palm_object[-1], steps[1].T_palm_object)


def test_with_the_object_on_its_interpolated_pose_the_middle_tip_sinks(cylinder_repose, monkeypatch):
    """What the path was before the object followed the hand: the joints alone leave the middle tip more
    than verify's 0.5 mm inside the cylinder, and the path says so."""
    hand, obj, steps = cylinder_repose
    monkeypatch.setattr(repose_trajectory, "FOLLOW_TOL", np.inf)
    path = plan_trajectories(steps, hand, obj)[1]
    assert not path.ok and "off the surface" in path.detail
    assert path.metrics["max_pose_correction"] < 1e-12
    assert _held_surface_error(hand, obj, steps, path) > 5e-4
