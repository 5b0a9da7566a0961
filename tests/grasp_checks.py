"""Independent grasp checks for the tests (exact mesh distances, an LP force-closure test).

Nothing here imports `regrasp_casadi.grasp_gen`: the tests judge generated grasps with these.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from regrasp_casadi.transforms import inv_T, transform_points


def friction_wrenches(contacts, normals, mu, center, length, n_edges=8):
    """(m·n_edges, 6) primitive wrenches of linearised Coulomb cones; torques / `length`."""
    rows = []
    for c, n in zip(np.asarray(contacts, float), np.asarray(normals, float), strict=True):
        n = n / np.linalg.norm(n)
        a = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        t1 = np.cross(n, a)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        for k in range(n_edges):
            phi = 2 * np.pi * (k + 0.5) / n_edges
            f = -n + mu * (np.cos(phi) * t1 + np.sin(phi) * t2)
            rows.append(np.concatenate([f, np.cross(c - center, f) / length]))
    return np.array(rows)


def force_closure_lp(contacts, normals, mu=0.5, center=None, length=None) -> bool:
    """Force closure ⇔ rank W = 6 and 0 = Σ λ_i w_i with Σ λ_i = 1 and every λ_i > 0 (LP: max min λ)."""
    contacts = np.asarray(contacts, float)
    center = contacts.mean(axis=0) if center is None else np.asarray(center, float)
    if length is None:
        length = float(np.max(np.linalg.norm(contacts - center, axis=1)))
    W = friction_wrenches(contacts, normals, mu, center, length)
    if np.linalg.matrix_rank(W, tol=1e-9) < 6:
        return False
    k = len(W)
    # variables (λ_1..λ_k, t); maximise t s.t. Wᵀλ = 0, Σλ = 1, λ_i − t ≥ 0
    c = np.zeros(k + 1)
    c[-1] = -1.0
    A_eq = np.zeros((7, k + 1))
    A_eq[:6, :k] = W.T
    A_eq[6, :k] = 1.0
    b_eq = np.zeros(7)
    b_eq[6] = 1.0
    A_ub = np.hstack([-np.eye(k), np.ones((k, 1))])
    res = linprog(c, A_ub=A_ub, b_ub=np.zeros(k), A_eq=A_eq, b_eq=b_eq,
                  bounds=[(0, None)] * k + [(None, 1.0)], method="highs")
    return bool(res.status == 0 and -res.fun > 1e-9)


def exact_checks(hand, obj, q, T_palm_object):
    """(tip gap (m,) = exact distance of tip centres − r_tip, clearance (k,) of non-tip spheres, labels)."""
    T_object_palm = inv_T(np.asarray(T_palm_object, float))
    tips = transform_points(T_object_palm, np.asarray(hand.tip_positions(q)).reshape(-1, 3))
    spheres = transform_points(T_object_palm, np.asarray(hand.sphere_centers(q)).reshape(-1, 3))
    gap = obj.exact_signed_distance(tips) - hand.tip_radius
    clearance = obj.exact_signed_distance(spheres) - hand.sphere_radii()
    return gap, clearance, list(hand.sphere_labels())


def contact_normals(hand, obj, q, T_palm_object, contacts):
    """Outward contact normals (m, 3): from each contact to its tip sphere centre, object frame."""
    p_palm = np.asarray(hand.tip_positions(q)).reshape(-1, 3)
    tips = transform_points(inv_T(np.asarray(T_palm_object, float)), p_palm)
    d = tips - np.asarray(contacts, float)
    return d / np.linalg.norm(d, axis=1, keepdims=True)
