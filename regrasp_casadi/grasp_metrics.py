"""Measures of how a grasp changed, one definition each, shared by the planner, OPT2's acceptance and
`verify` (numpy only: no smooth-distance, NLP, planner or CasADi code of its own, so `verify` and `plan`
may use it; `tip_frames` reads a `Hand`'s forward kinematics).

* contact travel (`contact_slip`, `slip_between`): how far each finger's *contact point on the object*
  moved, object frame, m. The contact is the exact closest mesh point of the fingertip centre
  (`ObjectModel.closest_points`). This is not the tip's slip: a rolling tip moves its contact without
  sliding, and a tip turning in place over its contact slides without moving it. The planner, OPT2 and
  verify judge the slip (`tip_slip`, below); until 2026-12-02 they judged this travel.
* tip slip (`tip_slip`): how far the fingertip's *material* slides over the object, m. A spherical tip
  of radius ρ that turns by θ relative to the object (rotation vector, object frame) while pressing at
  outward normal n rolls without slipping only when its centre moves by ρ θ × n; the slip is the rest,
  the tangential part of Δp_centre − ρ θ × n (the velocity of the tip's material point at the contact,
  integrated; along n the tip lifts off or presses, which the surface checks judge). A tip
  that turns in place over a fixed contact slides (its contact does not move, its material does); a tip
  that rolls moves its contact without sliding; turning about n (spin) is not slip.
* pose error: position (m) and rotation (rad) distance of two object poses.

    >>> slip = contact_slip(obj, p_object_tips_before, p_object_tips_after)    # (m,) m
    >>> p, R = tip_frames(hand, q, T_palm_object)                             # (m, 3), (m, 3, 3) object frame
    >>> sliding = tip_slip(p_a, R_a, p_b, R_b, normals, hand.tip_radius)       # (m,) m
    >>> position_m, rotation_rad = pose_error(T_palm_object, T_palm_object_goal)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.objects import ObjectModel

__all__ = ["object_contacts", "slip_between", "contact_slip", "tip_frames", "rolling_displacement",
           "tip_slip", "path_tip_slip", "pose_error"]


def object_contacts(obj: ObjectModel, p_object_tips: ArrayLike) -> NDArray[np.float64]:
    """The contacts (m, 3), object frame, m, of fingertip centres `p_object_tips` (m, 3), object frame,
    m: their exact closest points on the object's mesh."""
    closest, _ = obj.closest_points(np.asarray(p_object_tips, dtype=float).reshape(-1, 3))
    return np.asarray(closest, dtype=float).reshape(-1, 3)


def slip_between(p_object_contacts_a: ArrayLike, p_object_contacts_b: ArrayLike) -> NDArray[np.float64]:
    """Slip (m,), m: the distance each contact moved on the object between two grasps, from their contacts
    (m, 3), object frame, m (`object_contacts`)."""
    a = np.asarray(p_object_contacts_a, dtype=float).reshape(-1, 3)
    b = np.asarray(p_object_contacts_b, dtype=float).reshape(-1, 3)
    if a.shape != b.shape:
        raise ValueError(f"contacts of different shapes {a.shape} and {b.shape}")
    return np.linalg.norm(b - a, axis=1)


def contact_slip(obj: ObjectModel, p_object_tips_a: ArrayLike, p_object_tips_b: ArrayLike
                 ) -> NDArray[np.float64]:
    """Slip (m,), m, of each finger between two grasps given by their fingertip centres (m, 3), object
    frame, m: the distance its contact (`object_contacts`) moved on the object."""
    return slip_between(object_contacts(obj, p_object_tips_a), object_contacts(obj, p_object_tips_b))


def tip_frames(hand, q: ArrayLike, T_palm_object: ArrayLike
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The fingertips of `hand` (a `Hand`) at joints `q` (n,) rad, object pose `T_palm_object` (4, 4), in
    the object frame: tip-sphere centres (m, 3), m, and tip-link orientations R_object_tip (m, 3, 3), in
    `hand.fingers` order."""
    T = np.asarray(T_palm_object, dtype=float)
    p = (np.asarray(hand.tip_positions(q), dtype=float).reshape(-1, 3) - T[:3, 3]) @ T[:3, :3]
    return p, T[:3, :3].T @ hand.tip_rotations(q)


def rolling_displacement(R_object_tips_a: ArrayLike, R_object_tips_b: ArrayLike, normals_object: ArrayLike,
                         radius: float) -> NDArray[np.float64]:
    """(m, 3) where each spherical tip's centre goes, object frame, m, when it turns from R_a to R_b
    (m, 3, 3), object frame, rolling without slipping over a surface of outward normals (m, 3) (made
    unit): ρ θ × n, θ the rotation vector of R_b R_aᵀ."""
    from regrasp_casadi.transforms import log_SO3_batch  # (transforms loads CasADi: plan.py must not)

    R_a = np.asarray(R_object_tips_a, dtype=float).reshape(-1, 3, 3)
    R_b = np.asarray(R_object_tips_b, dtype=float).reshape(-1, 3, 3)
    n = np.asarray(normals_object, dtype=float).reshape(-1, 3)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    theta = log_SO3_batch(R_b @ np.transpose(R_a, (0, 2, 1)))
    return float(radius) * np.cross(theta, n)


def _slide_vectors(p_a, R_a, p_b, R_b, normals, radius) -> NDArray[np.float64]:
    """(m, 3) the slide of each tip between two grasps, object frame, m (`tip_slip`): Δp − ρ θ × n in the
    tangent plane (a motion along the normal is a lift or a push, not a slide)."""
    p_a = np.asarray(p_a, dtype=float).reshape(-1, 3)
    p_b = np.asarray(p_b, dtype=float).reshape(-1, 3)
    n = np.asarray(normals, dtype=float).reshape(-1, 3)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    d = (p_b - p_a) - rolling_displacement(R_a, R_b, n, radius)
    return d - np.sum(d * n, axis=1, keepdims=True) * n


def tip_slip(p_object_tips_a: ArrayLike, R_object_tips_a: ArrayLike, p_object_tips_b: ArrayLike,
             R_object_tips_b: ArrayLike, normals_object: ArrayLike, radius: float) -> NDArray[np.float64]:
    """Slip (m,), m, of each spherical fingertip's material over the object between two grasps: tip
    centres (m, 3) and tip orientations (m, 3, 3), object frame, at a and b; outward unit normals (m, 3)
    at the contacts (object frame; e.g. the mean of a's and b's); tip `radius` ρ, m. With θ the rotation
    vector of R_b R_aᵀ: the tangential part of (p_b − p_a) − ρ θ × n (exact for a small step;
    `path_tip_slip` adds up the steps of a path; the centre's motion along n is a lift, not a slide)."""
    return np.linalg.norm(_slide_vectors(p_object_tips_a, R_object_tips_a, p_object_tips_b, R_object_tips_b,
                                         normals_object, radius), axis=1)


def path_tip_slip(p_object_tips: ArrayLike, R_object_tips: ArrayLike, normals_object: ArrayLike,
                  radius: float) -> NDArray[np.float64]:
    """Net slip (k, m), m, of each tip from the first of k samples of a motion to every sample: the norm
    of the summed slide vectors of consecutive samples (`tip_slip`'s Δp − ρ θ × n, the mean normal of
    each pair; centres (k, m, 3), orientations (k, m, 3, 3), outward normals (k, m, 3), object frame).
    The slide's velocity integrated: a tip that slides 1 mm and back has slipped 0 net (what the contact
    carries away), not 2 mm."""
    p = np.asarray(p_object_tips, dtype=float)
    R = np.asarray(R_object_tips, dtype=float)
    n = np.asarray(normals_object, dtype=float)
    k, m = p.shape[:2]
    if k < 2:
        return np.zeros((k, m))
    steps = _slide_vectors(p[:-1].reshape(-1, 3), R[:-1].reshape(-1, 3, 3), p[1:].reshape(-1, 3),
                           R[1:].reshape(-1, 3, 3), (n[:-1] + n[1:]).reshape(-1, 3), radius)
    total = np.concatenate([np.zeros((1, m, 3)), np.cumsum(steps.reshape(k - 1, m, 3), axis=0)])
    return np.linalg.norm(total, axis=2)


def pose_error(T_a: ArrayLike, T_b: ArrayLike) -> tuple[float, float]:
    """(position error m, rotation error rad) between two poses (4, 4) of the same frame: the distance of
    their origins and the geodesic angle of their rotations."""
    T_a, T_b = np.asarray(T_a, dtype=float), np.asarray(T_b, dtype=float)
    cos = (np.trace(T_a[:3, :3].T @ T_b[:3, :3]) - 1.0) / 2.0  # as `transforms.rotation_angle`
    return float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])), float(np.arccos(np.clip(cos, -1.0, 1.0)))
