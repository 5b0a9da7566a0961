"""Grasp stability: the Ferrari–Canny force-closure margin of frictional point contacts.

Used by grasp generation (generated grasps must be in force closure), by `verify` (the margin of the
fingers that hold the object during each finger gait, reported as a metric) and by the planner's
stability-aware gait order. Pure numpy/scipy.

    >>> eps = force_closure_quality(contacts_object, normals_object, mu=0.5)   # > 0: force closure
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "FRICTION_EDGES", "force_closure_quality", "contact_normals", "holding_quality", "torque_reference",
]

FRICTION_EDGES = 8
"""Edges of the linearised friction cones."""


def force_closure_quality(
    contacts: NDArray[np.float64],
    normals: NDArray[np.float64],
    mu: float = 0.5,
    center: NDArray[np.float64] | None = None,
    length: float | None = None,
    n_edges: int = FRICTION_EDGES,
) -> float:
    """Ferrari–Canny ε of frictional point contacts (linearised cones); > 0 ⇔ force closure.

    Each contact i pushes along the inward normal −n_i within a Coulomb cone of half-angle atan μ,
    linearised by `n_edges` edge forces f_ij = −n_i + μ(cos φ_j t1_i + sin φ_j t2_i). Their wrenches
    w_ij = [f_ij; (c_i − center) × f_ij / L] are scaled by the characteristic length L so forces and
    torques are comparable. The grasp is in force closure iff the origin lies strictly inside the
    convex hull of the w_ij (their positive span is R⁶). ε is the signed distance from the origin to
    the hull boundary: the radius of the largest wrench ball the grasp resists with unit total normal
    force (> 0 inside, ≤ 0 outside; 0 when the wrenches span less than 6 dimensions).

    Args:
        contacts: (m, 3) contact points, object frame, m.
        normals: (m, 3) outward unit surface normals at the contacts, object frame.
        mu: friction coefficient.
        center: (3,) torque reference point, object frame, m (default: mean of the contacts).
        length: characteristic length L, m (default: max distance of a contact from `center`).
        n_edges: friction-cone edges.

    Returns:
        ε (dimensionless with L-scaled torques).
    """
    c = np.asarray(contacts, float).reshape(-1, 3)
    n = np.asarray(normals, float).reshape(-1, 3)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    center = c.mean(axis=0) if center is None else np.asarray(center, float)
    if length is None:
        length = float(np.max(np.linalg.norm(c - center, axis=1)))
    length = max(float(length), 1e-9)
    phi = 2.0 * np.pi * np.arange(n_edges) / n_edges
    wrenches = []
    for ci, ni in zip(c, n, strict=True):
        a = np.array([1.0, 0.0, 0.0]) if abs(ni[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t1 = np.cross(ni, a)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(ni, t1)
        for ph in phi:
            f = -ni + mu * (np.cos(ph) * t1 + np.sin(ph) * t2)
            wrenches.append(np.concatenate([f, np.cross(ci - center, f) / length]))
    from scipy.spatial import ConvexHull, QhullError  # imported here: `import regrasp_casadi` stays light

    W = np.array(wrenches)
    if np.linalg.matrix_rank(W - W.mean(axis=0), tol=1e-9) < 6:
        return 0.0
    try:
        hull = ConvexHull(W)
    except QhullError:
        return 0.0
    return float(-np.max(hull.equations[:, -1]))


def contact_normals(contacts: NDArray[np.float64], tip_centers: NDArray[np.float64]) -> NDArray[np.float64]:
    """Outward contact normals (m, 3) of sphere tips: the unit direction from each contact (m, 3) to its
    tip-sphere centre (m, 3), object frame."""
    d = np.asarray(tip_centers, float) - np.asarray(contacts, float)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def holding_quality(contacts: NDArray[np.float64], tip_centers: NDArray[np.float64], moving: int,
                    center: NDArray[np.float64], length: float, mu: float = 0.5) -> float:
    """Force-closure margin ε of the contacts that hold the object while finger `moving` (a row index)
    is lifted for a gait; contacts and tip centres (m, 3), object frame, m; torques about `center`
    (3,), scaled by `length` (m)."""
    keep = [i for i in range(len(contacts)) if i != moving]
    c = np.asarray(contacts, float)[keep]
    return force_closure_quality(c, contact_normals(c, np.asarray(tip_centers, float)[keep]), mu,
                                 center, length)


def torque_reference(mesh) -> tuple[NDArray[np.float64], float]:
    """Torque reference of an object's force-closure margins: its centre of mass (3,), object frame, m,
    and the characteristic length L = its largest vertex distance from that point, m."""
    com = np.asarray(mesh.center_mass, float)
    return com, float(np.max(np.linalg.norm(np.asarray(mesh.vertices) - com, axis=1)))
