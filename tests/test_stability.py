"""Force-closure margin (Ferrari–Canny ε) of frictional point contacts, on closed-form cases."""

from __future__ import annotations

import numpy as np

from regrasp_casadi.stability import contact_normals, force_closure_quality, holding_quality

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


def test_holding_quality_is_the_quality_of_the_other_contacts():
    contacts = PINCHES
    tips = contacts + 0.014 * np.sign(contacts[:, :1]) * np.array([[1.0, 0.0, 0.0]])
    normals = contact_normals(contacts, tips)
    np.testing.assert_allclose(normals, np.sign(contacts[:, :1]) * np.array([[1.0, 0.0, 0.0]]), atol=1e-12)
    for moving in range(4):
        keep = [i for i in range(4) if i != moving]
        expected = force_closure_quality(contacts[keep], normals[keep], 0.5, np.zeros(3), 0.05)
        assert holding_quality(contacts, tips, moving, np.zeros(3), 0.05) == expected
