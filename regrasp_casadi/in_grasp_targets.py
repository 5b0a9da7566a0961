"""OPT2's targets and move bounds: the SVD form's target pose (`svd_target`, with the goal pull of round
objects, `is_round`), the fingers' reachable-workspace hulls of the SD form (`workspace_hull`), and the
trust region of one in-grasp move (`trust_region`, `clip_pose`). Numeric (numpy/scipy), no CasADi;
`in_grasp` builds the NLP and re-exports these names.

    >>> T_target = svd_target(T_palm_object, contacts_object, goal_contacts_object)
    >>> T_step = clip_pose(T_palm_object, T_target, *trust_region(options))
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull

from regrasp_casadi.transforms import interpolate_pose, inv_T, kabsch, log_SO3

if TYPE_CHECKING:
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.in_grasp import InGraspOptions
    from regrasp_casadi.objects import ObjectModel

__all__ = ["WorkspaceHull", "workspace_hull", "svd_target", "is_round", "ROUND_GOAL_PULL", "clip_pose",
           "trust_region"]

ROUND_GOAL_PULL = 0.25
"""The default `goal_pull` on round objects. Ten generated 7 cm sphere pairs, SVD reposings, paper
planner (stability "none"): with 0 the contacts converged while the object drifted up to 101° and 55 mm
from the desired pose (2 pose_not_reached); with 0.5, 7 of 10 converged and verified; with 0.25, 10 of 10
converged, 9 verified. Other objects keep 0: on the shipped problems 0.25 changed 4 of 5 svd plans
(flat_tool_regrasp then failed verify)."""


@dataclass(frozen=True)
class WorkspaceHull:
    """Convex hull R_r of a finger's reachable tip-centre positions, palm frame: {x : n_i·x ≤ h_i}."""

    normals: NDArray[np.float64]
    """(k, 3) unit outward normals."""
    offsets: NDArray[np.float64]
    """(k,) support values, m."""


def workspace_hull(hand: Hand, finger: str, n_samples: int = 4000, seed: int = 0,
                   max_planes: int = 64) -> WorkspaceHull:
    """Reachable-workspace hull of `finger` from tip samples over the joint limits (paper §III-B).

    The hull's face planes are merged (coplanar facets) and, if more than `max_planes`, the planes of the
    largest facets are kept with their exact support values, which can only enlarge the polytope.
    """
    pts = hand.tip_workspace_samples(finger, n=n_samples, seed=seed)
    hull = ConvexHull(pts)
    normals = hull.equations[:, :3]
    # merge near-duplicate planes, keep the largest-area representatives
    tri = pts[hull.simplices]  # (F, 3, 3) facets
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    order = np.argsort(-areas)
    kept: list[int] = []
    for i in order:
        if all(normals[i] @ normals[j] < 0.999 for j in kept):
            kept.append(i)
        if len(kept) >= max_planes:
            break
    n = normals[kept]
    h = np.max(pts @ n.T, axis=0)
    return WorkspaceHull(normals=n, offsets=h)


def svd_target(T_palm_object: ArrayLike, contacts_object: ArrayLike, goal_contacts_object: ArrayLike,
               T_palm_object_goal: ArrayLike | None = None, goal_pull: float = 0.0) -> NDArray[np.float64]:
    """The target object pose of OPT2's SVD method (paper §III-B), (4, 4) palm frame.

    Kabsch / Besl–McKay gives the rigid transform T_rel (object frame) with X_goal ≈ T_rel · X, X the
    current contacts (m, 3) and X_goal the goal contacts (m, 3), object frame, m. Moving the object to
    T* = T_palm_object · T_rel⁻¹ brings each goal contact where its finger's contact is now
    (T* X_goal ≈ T_palm_object X), so that a finger that keeps its place in the palm reaches its goal.

    With the desired pose T_d = `T_palm_object_goal` and α = `goal_pull` ∈ [0, 1] (an addition to the
    paper), the goal contacts are brought part of the way from where the fingers touch now to where the
    desired grasp has them (palm frame):

        T* = argmin_T Σ_r ||T x_goal,r − y_r||²,   y_r = (1 − α) T_palm_object x_r + α T_d x_goal,r,

    so T* = T_d when α = 1 and the paper's target when α = 0. Contacts alone do not fix the pose of a body
    of revolution held by fingertips (a sphere can be held in any orientation): with α = 0 a sequence of
    reposings can carry it far from T_d while the contacts converge (measured: 100° on a 7 cm sphere);
    α > 0 makes every reposing also bring the object towards T_d, and once the contacts are reached
    (x = x_goal) the target is a fraction α of the way from the current pose to T_d.
    """
    T0 = np.asarray(T_palm_object, float)
    if T_palm_object_goal is None or goal_pull <= 0.0:
        T_rel = kabsch(contacts_object, goal_contacts_object)  # X_goal ≈ T_rel · X
        return T0 @ inv_T(T_rel)  # so that o'·X_goal ≈ o·X
    if goal_pull > 1.0:
        raise ValueError(f"goal_pull must be in [0, 1], got {goal_pull}")
    Td = np.asarray(T_palm_object_goal, float)
    x, x_goal = np.asarray(contacts_object, float), np.asarray(goal_contacts_object, float)
    y = (1.0 - goal_pull) * (x @ T0[:3, :3].T + T0[:3, 3]) + goal_pull * (x_goal @ Td[:3, :3].T + Td[:3, 3])
    return kabsch(x_goal, y)


def is_round(obj: ObjectModel, tol: float = 0.05) -> bool:
    """Whether the object is a ball: its mesh's vertices and face centres all lie within `tol` (relative)
    of one distance r from the bounding-box centre, (max r − min r) ≤ tol · max r (the 320-face
    icosphere: 1.8 %; a cube: 59 %). Every rotation about its centre maps such an object (nearly) onto
    itself, so fingertip contacts do not fix its orientation."""
    mesh = obj.mesh
    points = np.vstack([mesh.vertices, mesh.triangles_center])
    r = np.linalg.norm(points - np.mean(mesh.bounds, axis=0), axis=1)
    return bool(r.max() - r.min() <= tol * r.max())


def trust_region(options: InGraspOptions) -> tuple[float, float]:
    """OPT2's trust region as (largest translation, m; largest rotation angle, rad) of one move: the
    bounds `max_translation` and `max_rotation` (on the Cayley vector, tan(θ/2)) of `options`."""
    return options.max_translation, 2.0 * float(np.arctan(options.max_rotation))


def clip_pose(T_from: NDArray, T_to: NDArray, max_translation: float, max_angle: float) -> NDArray:
    """The pose a fraction of the way from `T_from` to `T_to` (translation linear, rotation geodesic)
    such that it is at most `max_translation` (m) and `max_angle` (rad) from `T_from`: the trust region.
    A target beyond it would only pull harder against the relaxed rigidity, i.e. make the tips slide."""
    dt = T_to[:3, 3] - T_from[:3, 3]
    w = log_SO3(T_from[:3, :3].T @ T_to[:3, :3])
    frac = min(1.0, max_translation / max(float(np.linalg.norm(dt)), 1e-12),
               max_angle / max(float(np.linalg.norm(w)), 1e-12))
    return interpolate_pose(T_from, T_to, frac)
