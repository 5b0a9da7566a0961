"""Measures of how a grasp changed, one definition each, shared by the planner, OPT2's acceptance and
`verify` (numpy only: no smooth-distance, NLP, planner or CasADi code, so `verify` and `plan` may use it).

* contact slip: how far each finger's *contact point on the object* moved, object frame, m. The contact
  is the exact closest mesh point of the fingertip centre (`ObjectModel.closest_points`), not the centre
  itself: a tip that rolls over an edge or around a curved surface moves its centre more (convex) or less
  (concave) than its contact, and only the contact's motion on the object is slip.
* pose error: position (m) and rotation (rad) distance of two object poses.

    >>> slip = contact_slip(obj, p_object_tips_before, p_object_tips_after)    # (m,) m
    >>> position_m, rotation_rad = pose_error(T_palm_object, T_palm_object_goal)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.objects import ObjectModel

__all__ = ["object_contacts", "slip_between", "contact_slip", "pose_error"]


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


def pose_error(T_a: ArrayLike, T_b: ArrayLike) -> tuple[float, float]:
    """(position error m, rotation error rad) between two poses (4, 4) of the same frame: the distance of
    their origins and the geodesic angle of their rotations."""
    T_a, T_b = np.asarray(T_a, dtype=float), np.asarray(T_b, dtype=float)
    cos = (np.trace(T_a[:3, :3].T @ T_b[:3, :3]) - 1.0) / 2.0  # as `transforms.rotation_angle`
    return float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])), float(np.arccos(np.clip(cos, -1.0, 1.0)))
