"""Grasp stability: the Ferrari–Canny force-closure margin of frictional point contacts.

Used by grasp generation (generated grasps must be in force closure), by `verify` (the margin of the
fingers that hold the object during each finger gait, reported as a metric) and by the planner's
stability-aware gait order; its primitive wrenches and friction per contact (μ_i = 0 for a sliding,
frictionless contact) also serve the convex certificates of `regrasp_casadi.certificates`. Pure
numpy/scipy.

    >>> eps = force_closure_quality(contacts_object, normals_object, mu=0.5)   # > 0: force closure
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.constants import MU

__all__ = [
    "FRICTION_EDGES", "contact_mu", "sliding_normal", "tangent_basis", "tangent_bases", "primitive_wrenches",
    "torque_scale", "force_closure_quality", "ferrari_canny", "contact_normals", "holding_quality",
    "torque_reference",
]

FRICTION_EDGES = 8
"""Edges of the linearised friction cones."""


def contact_mu(mu: float | NDArray[np.float64], m: int, sliding: NDArray[np.bool_] | None = None
               ) -> NDArray[np.float64]:
    """(m,) friction coefficient of each contact: `mu` (a scalar or (m,) array), 0 where `sliding` (m,)
    is True (a sliding finger is a frictionless contact: normal force only)."""
    mu_i = np.broadcast_to(np.asarray(mu, float), (m,)).copy()
    if np.any(mu_i < 0) or not np.all(np.isfinite(mu_i)):
        raise ValueError(f"mu: expected finite values >= 0, got {mu_i}")
    if sliding is not None:
        mu_i[np.broadcast_to(np.asarray(sliding, bool), (m,))] = 0.0
    return mu_i


def sliding_normal(normal: NDArray[np.float64], direction: NDArray[np.float64] | None,
                   mu: float) -> NDArray[np.float64]:
    """The normal n' (3,) that makes a SLIDING contact a frictionless one: a finger sliding over the
    surface (outward unit normal n (3,)) in `direction` (3,) (its tip's motion over the object, any
    length; only the tangential part ŝ counts) pushes on the object with f = f_n (−n + μ ŝ), kinetic
    friction μ dragging the object along the slide; n' = (n − μ ŝ) / |n − μ ŝ|, so that f ∝ −n'. Without a
    tangential direction (None or normal to the surface): n."""
    n = np.asarray(normal, float)
    if direction is None:
        return n
    d = np.asarray(direction, float)
    d = d - (d @ n) * n
    norm = float(np.linalg.norm(d))
    if norm < 1e-9:
        return n
    tilted = n - mu * d / norm
    return tilted / np.linalg.norm(tilted)


def tangent_basis(normal: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two unit tangents (t1, t2) (3,) with (n, t1, t2) orthonormal, for a unit normal n (3,)."""
    t = tangent_bases(np.asarray(normal, float).reshape(1, 3))[0]
    return t[0], t[1]


def tangent_bases(normals: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit tangents (m, 2, 3): rows t1, t2 with (n, t1, t2) orthonormal, for unit normals n (m, 3);
    t1 = n × a / |n × a| with a = x̂ (ŷ where |n_x| ≥ 0.9), t2 = n × t1."""
    n = np.asarray(normals, float).reshape(-1, 3)
    a = np.zeros_like(n)
    a[np.abs(n[:, 0]) < 0.9, 0] = 1.0
    a[np.abs(n[:, 0]) >= 0.9, 1] = 1.0
    t1 = _cross(n, a)
    t1 /= np.array([[np.linalg.norm(row)] for row in t1]).reshape(-1, 1)  # per row: as a (3,) vector's norm
    return np.stack([t1, _cross(n, t1)], axis=1)


def _cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """a × b over the last axis (3), broadcast; the same products and differences as `np.cross`, without
    its overhead (this runs thousands of times per plan)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def primitive_wrenches(
    contacts: NDArray[np.float64],
    normals: NDArray[np.float64],
    mu: float | NDArray[np.float64],
    center: NDArray[np.float64],
    length: float,
    n_edges: int = FRICTION_EDGES,
) -> NDArray[np.float64]:
    """(k, 6) primitive wrenches [f; (c − center) × f / L] of linearised Coulomb cones.

    Contact i (c_i (3,), outward unit normal n_i (3,), object frame, m) with μ_i > 0 contributes the
    `n_edges` edge forces f_ij = −n_i + μ_i(cos φ_j t1_i + sin φ_j t2_i), each of unit normal force;
    a frictionless contact (μ_i = 0) contributes the single force −n_i. `mu` is a scalar or (m,).
    """
    c = np.asarray(contacts, float).reshape(-1, 3)
    n = np.asarray(normals, float).reshape(-1, 3)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    mu_i = contact_mu(mu, len(c))
    phi = 2.0 * np.pi * np.arange(n_edges) / n_edges
    cos, sin = np.cos(phi)[None, :, None], np.sin(phi)[None, :, None]
    t = tangent_bases(n)  # (m, 2, 3)
    f = -n[:, None, :] + mu_i[:, None, None] * (cos * t[:, None, 0, :] + sin * t[:, None, 1, :])  # (m, e, 3)
    torque = _cross(c[:, None, :] - center, f) / length
    keep = np.ones((len(c), n_edges), bool)
    keep[mu_i == 0, 1:] = False  # a frictionless contact: the one force −n_i
    return np.concatenate([f, torque], axis=2)[keep].reshape(-1, 6)


def torque_scale(contacts: NDArray[np.float64], center: NDArray[np.float64] | None,
                 length: float | None) -> tuple[NDArray[np.float64], float]:
    """Torque reference (3,) and characteristic length L, m: the given ones, else the mean of the
    contacts (m, 3) and their largest distance from it (at least 1e-9 m)."""
    c = np.asarray(contacts, float).reshape(-1, 3)
    center = c.mean(axis=0) if center is None else np.asarray(center, float)
    if length is None:
        length = float(np.max(np.linalg.norm(c - center, axis=1))) if len(c) else 0.0
    return center, max(float(length), 1e-9)


def force_closure_quality(
    contacts: NDArray[np.float64],
    normals: NDArray[np.float64],
    mu: float | NDArray[np.float64] = MU,
    center: NDArray[np.float64] | None = None,
    length: float | None = None,
    n_edges: int = FRICTION_EDGES,
) -> float:
    """Ferrari–Canny ε of frictional point contacts (linearised cones); > 0 ⇔ force closure.

    Each contact i pushes along the inward normal −n_i within a Coulomb cone of half-angle atan μ_i,
    linearised by `n_edges` edge forces (see `primitive_wrenches`; one force −n_i when μ_i = 0). Their
    wrenches w_ij = [f_ij; (c_i − center) × f_ij / L] are scaled by the characteristic length L so
    forces and torques are comparable. The grasp is in force closure iff the origin lies strictly inside
    the convex hull of the w_ij (their positive span is R⁶). ε is the signed distance from the origin to
    the hull boundary: the radius of the largest wrench ball the grasp resists with unit total normal
    force (> 0 inside, ≤ 0 outside; 0 when the wrenches span less than 6 dimensions).

    Args:
        contacts: (m, 3) contact points, object frame, m.
        normals: (m, 3) outward unit surface normals at the contacts, object frame.
        mu: friction coefficient, a scalar or (m,) per contact (0: frictionless, e.g. a sliding finger).
        center: (3,) torque reference point, object frame, m (default: mean of the contacts).
        length: characteristic length L, m (default: max distance of a contact from `center`).
        n_edges: friction-cone edges.

    Returns:
        ε (dimensionless with L-scaled torques).
    """
    center, length = torque_scale(contacts, center, length)
    return ferrari_canny(primitive_wrenches(contacts, normals, mu, center, length, n_edges))


def ferrari_canny(W: NDArray[np.float64]) -> float:
    """Ferrari–Canny ε of primitive wrenches W (k, 6) (`primitive_wrenches`): the signed distance from
    the origin to the boundary of their convex hull (> 0 inside, 0 when they span less than 6
    dimensions)."""
    from scipy.spatial import ConvexHull, QhullError  # imported here: `import regrasp_casadi` stays light

    if len(W) < 7 or np.linalg.matrix_rank(W - W.mean(axis=0), tol=1e-9) < 6:
        return 0.0
    for options in ("Q0", None):  # unmerged facets first (≈ 3× faster), Qhull's default merging on error
        try:
            hull = ConvexHull(W, qhull_options=options)
        except QhullError:
            continue
        return float(-np.max(hull.equations[:, -1]))
    return 0.0


def contact_normals(contacts: NDArray[np.float64], tip_centers: NDArray[np.float64]) -> NDArray[np.float64]:
    """Outward contact normals (m, 3) of sphere tips: the unit direction from each contact (m, 3) to its
    tip-sphere centre (m, 3), object frame."""
    d = np.asarray(tip_centers, float) - np.asarray(contacts, float)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def holding_quality(contacts: NDArray[np.float64], tip_centers: NDArray[np.float64], moving: int,
                    center: NDArray[np.float64], length: float, mu: float = MU) -> float:
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
