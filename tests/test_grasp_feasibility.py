"""The clear errors of grasp generation for objects that admit no precision grasp of the hand (too small,
too large, too thin), raised before any NLP is built, and the narrowest width against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from regrasp_casadi import grasp_gen
from regrasp_casadi.grasp_feasibility import UngraspableError, check_graspable, hand_reach, narrowest_width
from regrasp_casadi.objects import ObjectModel


@pytest.fixture()
def no_solve(monkeypatch):
    """Fail the test if grasp generation gets as far as building its NLP and samples."""
    def forbidden(*args, **kwargs):
        raise AssertionError("grasp generation started solving")
    monkeypatch.setattr(grasp_gen, "_search", forbidden)


@pytest.mark.parametrize(("obj", "reason", "words"), [
    (lambda: ObjectModel.sphere(0.003), "too_small", "too small"),
    (lambda: ObjectModel.box((0.4, 0.4, 0.4)), "too_large", "too large"),
    (lambda: ObjectModel.box((0.1, 0.1, 0.0005)), "too_thin", "too thin"),
])
def test_ungraspable_objects_raise_naming_the_reason(hand, no_solve, obj, reason, words):
    o = obj()
    for call in (lambda: grasp_gen.generate_grasps(hand, o, n=1, seed=0),
                 lambda: grasp_gen.generate_regrasp_pairs(hand, o, 1, seed=0)):
        with pytest.raises(UngraspableError, match=words) as info:
            call()
        assert info.value.reason == reason
        assert o.name in str(info.value)


def test_graspable_objects_pass(hand):
    # the shapes grasp generation is benchmarked on, and a box just inside the thumb-to-finger span
    for o in (ObjectModel.sphere(0.035), ObjectModel.box((0.05, 0.07, 0.12)), ObjectModel.flat_tool()):
        check_graspable(hand, o, 0.001)
    d = hand_reach(hand).max_thumb_finger - 2 * hand.tip_radius
    check_graspable(hand, ObjectModel.box((0.95 * d, 1.2 * d, 1.2 * d)), 0.001)
    with pytest.raises(UngraspableError):
        check_graspable(hand, ObjectModel.box((1.05 * d, 1.2 * d, 1.2 * d)), 0.001)


def test_too_thin_depends_on_the_self_clearance(hand):
    sheet = ObjectModel.box((0.1, 0.1, 0.0005))
    check_graspable(hand, sheet, None)  # no self-collision rule: two tips may pinch it
    check_graspable(hand, sheet, 0.0004)


def test_max_thumb_finger_distance_against_brute_force(hand):
    # independent: all pairs of 3000 other joint samples' tip centres (forward kinematics one by one)
    rng = np.random.default_rng(3)
    Q = rng.uniform(hand.q_lower, hand.q_upper, size=(3000, hand.n_joints))
    tips = np.array([np.asarray(hand.tip_positions(q)).reshape(-1, 3) for q in Q])  # (N, m, 3)
    thumb = hand.fingers.index(hand.thumb)
    best = max(float(np.max(np.linalg.norm(tips[:, thumb][:, None] - tips[:, i][None], axis=2)))
               for i in range(len(hand.fingers)) if i != thumb)
    bound = hand_reach(hand).max_thumb_finger
    assert bound - 0.02 <= best <= bound + 0.005


def test_narrowest_width_closed_forms():
    box = trimesh.creation.box(extents=(0.03, 0.05, 0.08))
    box.apply_transform(trimesh.transformations.random_rotation_matrix(np.random.default_rng(1).random(3)))
    assert narrowest_width(box.vertices) == pytest.approx(0.03, abs=1e-9)
    prism = trimesh.creation.cylinder(radius=0.04, height=0.2, sections=32)  # even n: flat to flat
    assert narrowest_width(prism.vertices) == pytest.approx(2 * 0.04 * np.cos(np.pi / 32), abs=1e-9)
