"""Force-closure margin (Ferrari–Canny ε) of frictional point contacts, on closed-form cases."""

from __future__ import annotations

import numpy as np
import pytest
from grasp_checks import force_closure_lp

from regrasp_casadi.stability import (
    FRICTION_EDGES,
    contact_normals,
    force_closure_quality,
    holding_quality,
    sliding_normal,
)

# two pinches on opposite faces (x = ±3 cm) of a box, spread along y and z
PINCHES = np.array([[0.03, 0.02, 0.02], [0.03, -0.02, -0.02], [-0.03, 0.02, -0.02], [-0.03, -0.02, 0.02]])


def test_contacts_on_one_face_are_not_in_force_closure():
    # every contact pushes along -n (+ friction ⊥ n): no force has a +n component, so no pull along +n
    rng = np.random.default_rng(0)
    contacts = np.column_stack([np.full(4, 0.03), rng.uniform(-0.02, 0.02, (4, 2))])
    normals = np.tile([1.0, 0.0, 0.0], (4, 1))
    assert force_closure_quality(contacts, normals, mu=0.5, center=np.zeros(3), length=0.05) <= 0.0


def test_opposed_pairs_with_friction_are_in_force_closure():
    # with μ = 0.5 the pinches resist every wrench
    contacts = PINCHES
    normals = np.sign(contacts[:, :1]) * np.array([[1.0, 0.0, 0.0]])
    eps = force_closure_quality(contacts, normals, mu=0.5, center=np.zeros(3), length=0.05)
    assert eps > 0.0
    # without friction four contacts along ±x cannot resist a force along y
    assert force_closure_quality(contacts, normals, mu=0.0, center=np.zeros(3), length=0.05) <= 0.0


def _two_opposed_pairs(offset_y: float) -> np.ndarray:
    """Two pinches across the x = ±3 cm faces at z = ±2 cm, the −x contacts shifted by `offset_y` along
    y, and a fifth contact on the +y face (y = 3.5 cm): (5, 3), object frame, m."""
    return np.array([[0.03, 0.0, 0.02], [-0.03, offset_y, 0.02], [0.03, 0.0, -0.02],
                     [-0.03, offset_y, -0.02], [0.0, 0.035, 0.0]])


def _tips(contacts: np.ndarray, radius: float = 0.014) -> np.ndarray:
    """Tip-sphere centres `radius` outside each contact along the face normal (±x, or +y)."""
    normals = np.where(np.abs(contacts[:, :1]) > 0.029, np.sign(contacts[:, :1]) * [[1.0, 0.0, 0.0]],
                       [[0.0, 1.0, 0.0]])
    return contacts + radius * normals


@pytest.mark.parametrize(("offset_y", "closure"), [(0.0, True), (0.009, True), (0.045, False),
                                                   (0.06, False)])
def test_holding_quality_follows_the_friction_cone_of_the_pinches(offset_y, closure):
    """Lifting the fifth finger leaves two opposed pinches. Their squeeze needs a tangential force
    F = s·B / 0.06 for a total normal force B (torque balance about z), within friction μB: force closure
    iff s / 0.06 < μ (μ = 0.5: s < 3 cm; checked well inside and well outside the cone)."""
    contacts = _two_opposed_pairs(offset_y)
    tips = _tips(contacts)
    eps = holding_quality(contacts, tips, 4, np.zeros(3), 0.05, mu=0.5)
    assert (eps > 1e-6) if closure else (eps <= 1e-9), eps
    assert force_closure_lp(contacts[:4], contact_normals(contacts[:4], tips[:4]), 0.5, np.zeros(3),
                            0.05) == closure
    # the lifted finger matters: with all five down the grasp is at least as good
    assert force_closure_quality(contacts, contact_normals(contacts, tips), 0.5, np.zeros(3), 0.05) >= eps


def test_holding_quality_without_the_opposing_finger_is_not_closure():
    """Lifting the only finger on the −x side leaves contacts that can all only push along −x."""
    contacts = np.array([[0.03, 0.02, 0.02], [0.03, -0.02, 0.0], [0.03, 0.0, -0.02], [-0.03, 0.0, 0.0]])
    tips = contacts + 0.014 * np.sign(contacts[:, :1]) * [[1.0, 0.0, 0.0]]
    assert holding_quality(contacts, tips, 3, np.zeros(3), 0.05) <= 0.0
    assert holding_quality(contacts, tips, 0, np.zeros(3), 0.05) > 0.0


def test_holding_quality_agrees_with_an_lp_on_random_grasps():
    """Random 4-finger grasps on a sphere (contacts and outward tips), every finger lifted in turn, judged
    by the LP test of the three remaining contacts (independent code, its own cone edges). The two
    linearise the cone of radius μ by different octagons, each between the cones of radius μ·cos(π/8)
    and μ, so: LP closure at μ·cos(π/8) ⇒ ε(μ) > 0 ⇒ LP closure at μ / cos(π/8)."""
    mu, shrink = 0.5, np.cos(np.pi / FRICTION_EDGES)
    rng = np.random.default_rng(11)
    closed = opened = 0
    for _ in range(15):
        n = rng.normal(size=(4, 3))
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        contacts, tips = 0.03 * n, 0.044 * n
        for moving in range(4):
            eps = holding_quality(contacts, tips, moving, np.zeros(3), 0.03, mu=mu)
            keep = [i for i in range(4) if i != moving]
            if force_closure_lp(contacts[keep], n[keep], mu * shrink, np.zeros(3), 0.03):
                assert eps > 0.0, (moving, eps)
                closed += 1
            if eps > 1e-9:
                assert force_closure_lp(contacts[keep], n[keep], mu / shrink, np.zeros(3), 0.03), moving
            else:
                opened += 1
    assert closed >= 20 and opened >= 10  # both outcomes are exercised (36 and 24 with this seed)


def test_sliding_normal_is_the_direction_of_the_push_and_the_drag():
    """A finger sliding in direction d over a surface of outward normal n pushes on the object with
    f ∝ −n + μ ŝ (ŝ: d's unit tangential part); the frictionless contact of normal n' = (n − μ ŝ)/|·|
    pushes along −n'. Only d's tangential part counts; without one the normal is unchanged."""
    n = np.array([0.0, 0.0, 1.0])
    expected = np.array([-0.5, 0.0, 1.0]) / np.sqrt(1.25)
    np.testing.assert_allclose(sliding_normal(n, np.array([2.0, 0.0, 0.0]), 0.5), expected, atol=1e-12)
    np.testing.assert_allclose(sliding_normal(n, np.array([2.0, 0.0, 7.0]), 0.5), expected, atol=1e-12)
    np.testing.assert_allclose(sliding_normal(n, np.array([0.0, 0.0, 3.0]), 0.5), n, atol=1e-12)
    np.testing.assert_allclose(sliding_normal(n, None, 0.5), n, atol=1e-12)


@pytest.mark.parametrize("direction", [(1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 1.0), (0.3, 0.0, -1.0)])
def test_a_finger_sliding_against_three_opposite_fingers_is_not_in_force_closure(direction):
    """Three fingers on the face y = +3 cm of a box (a triangle around the axis, μ = 0.5) and a thumb on
    y = −3 cm on that axis: with the thumb frictionless (the old slide model) the grasp is in force
    closure; sliding, its kinetic friction μ f_n along its motion must be taken by the others' friction
    (at most μ Σ f_n = μ f_n, equal to it) and the two make a couple 6 cm × μ f_n that the normal forces
    (lever ≤ 1.5 cm) cannot balance: no force closure in any direction of the face."""
    a, b = 0.03, 0.015
    contacts = np.array([[0.0, a, b], [-b * np.cos(np.pi / 6), a, -b / 2], [b * np.cos(np.pi / 6), a, -b / 2],
                         [0.0, -a, 0.0]])
    normals = np.array([[0.0, 1.0, 0.0]] * 3 + [[0.0, -1.0, 0.0]])
    mu = np.array([0.5, 0.5, 0.5, 0.0])
    assert force_closure_quality(contacts, normals, mu, np.zeros(3), 0.05) > 0.05
    normals[3] = sliding_normal(normals[3], np.array(direction), 0.5)
    assert force_closure_quality(contacts, normals, mu, np.zeros(3), 0.05) < -0.05
