"""Regrasp pairs on issue 12's generated classes (flat tool, 7 cm sphere): every stated property of a
generated grasp checked with the exact mesh distance and an independent force-closure LP, and the
self-collision rule on the hand's sphere pairs. Slow (tens of seconds per class on a shared machine)."""

from __future__ import annotations

import numpy as np
import pytest
from grasp_checks import contact_normals, exact_checks, force_closure_lp

from regrasp_casadi.grasp_gen import generate_regrasp_pairs
from regrasp_casadi.objects import ObjectModel

pytestmark = pytest.mark.slow


@pytest.mark.parametrize(("make", "seed"), [(ObjectModel.flat_tool, 2),
                                           (lambda: ObjectModel.sphere(0.035), 2)])
def test_regrasp_pair_on_generated_class(hand, make, seed):
    obj = make()
    (g0, gg), = generate_regrasp_pairs(hand, obj, 1, seed=seed, max_seconds=300)
    for g in (g0, gg):
        q = np.asarray(g.q)
        assert np.all(q >= hand.q_lower) and np.all(q <= hand.q_upper)
        gap, clearance, _ = exact_checks(hand, obj, q, g.T_palm_object)
        assert np.max(np.abs(gap)) <= 1e-4
        assert np.min(clearance) >= 1e-3 - 1e-9
        assert np.min(hand.self_collision_distances(q)) >= 1e-3 - 1e-9
        normals = contact_normals(hand, obj, q, g.T_palm_object, g.contacts_object)
        assert force_closure_lp(g.contacts_object, normals, 0.5, obj.mesh.center_mass, 0.1)
    assert np.mean(np.linalg.norm(g0.contacts_object - gg.contacts_object, axis=1)) >= 0.03
