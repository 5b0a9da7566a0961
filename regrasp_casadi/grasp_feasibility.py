"""Whether an object admits a four-finger precision grasp of a hand at all, decided before any solve.

Three necessary conditions, each from the object's extents and the hand's fingertip workspace (tip
centres over `_N_SAMPLES` joint samples within the limits) and tip radius r:

* **too small**: the four tip centres of a generated grasp are pairwise ≥ s = `grasp_gen._TIP_SPACING`
  (3 cm) apart and within r of the surface, so they lie in the ball of radius R + r about the centre
  of mass (R: the object's bounding radius about it). Four points pairwise ≥ s apart need a ball of
  radius ≥ s·√(3/8) (the regular tetrahedron's circumradius): the object is too small when
  R + r < s·√(3/8).
* **too large**: a precision grasp opposes the thumb to the fingers across the object, so on a convex
  object (hull volume within `CONVEX_EXCESS` of the mesh's: no wall or rim to pinch) the tip centres of
  the thumb and some finger are at least w + 2r apart, w the object's narrowest width (the smallest
  extent of its convex hull over the hull's face normals and the oriented bounding box's axes).
  Too large when w + 2r exceeds D_max, the largest thumb-to-finger tip-centre distance of the workspace.
* **too thin**: pinched across its thickness t (the smallest extent of the oriented bounding box), the
  thumb's and a finger's tip spheres are t apart, but the self-collision rule keeps them
  ≥ `self_clearance` apart: too thin when t < `self_clearance` (no condition without self-clearance).

    >>> check_graspable(Hand.allegro_right(), ObjectModel.sphere(0.005))
    Traceback (most recent call last):
    UngraspableError: 'sphere' is too small for a precision grasp: ...
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import ConvexHull

from regrasp_casadi.errors import GraspError
from regrasp_casadi.grasp_workspace import joint_tip_samples

__all__ = ["CONVEX_EXCESS", "TIP_SPACING", "UngraspableError", "HandReach", "hand_reach", "check_graspable",
           "narrowest_width"]

CONVEX_EXCESS = 0.25
"""An object whose hull's volume exceeds its own by at most this fraction counts as convex for the
"too large" test (objects with walls, rims or handles may be pinched and are not tested)."""
_N_SAMPLES = 20000
TIP_SPACING = 0.03
"""Minimum distance between two fingertip targets of a generated grasp, m (`grasp_gen`)."""


class UngraspableError(GraspError):
    """The object admits no precision grasp of the hand; `reason` is "too_small", "too_large" or
    "too_thin" and the message gives the measured sizes."""

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class HandReach:
    """What the fingertips can span: the largest thumb-to-finger tip-centre distance D_max (m) over the
    workspace samples, and the tip radius r (m)."""

    max_thumb_finger: float
    tip_radius: float


_REACH: dict[int, tuple[object, HandReach]] = {}


def hand_reach(hand) -> HandReach:
    """The `HandReach` of `hand` (cached per hand object): tip centres of `_N_SAMPLES` uniform joint
    samples (seed 7); D_max over the convex-hull vertices of the thumb's and each finger's tip cloud."""
    hit = _REACH.get(id(hand))
    if hit is not None and hit[0] is hand:
        return hit[1]
    _, clouds = joint_tip_samples(hand, _N_SAMPLES, seed=7)
    thumb = hand.thumb if hand.thumb is not None else hand.fingers[-1]
    outer = {f: v[ConvexHull(v).vertices] for f, v in clouds.items()}
    d_max = max(float(np.max(np.linalg.norm(outer[thumb][:, None] - outer[f][None], axis=2)))
                for f in hand.fingers if f != thumb)
    reach = HandReach(d_max, float(hand.tip_radius))
    _REACH[id(hand)] = (hand, reach)
    return reach


def narrowest_width(vertices: NDArray[np.float64], extra_directions: NDArray[np.float64] | None = None
                    ) -> float:
    """The smallest extent (m) of the points (v, 3) over their convex hull's face normals and
    `extra_directions` (k, 3) unit vectors (an upper bound of the width, exact for a polytope whose
    narrowest direction is a face normal, e.g. a box)."""
    v = np.asarray(vertices, float)
    hull = ConvexHull(v)
    dirs = hull.equations[:, :3]
    if extra_directions is not None:
        dirs = np.vstack([dirs, np.asarray(extra_directions, float)])
    proj = v[hull.vertices] @ dirs.T
    return float(np.min(proj.max(axis=0) - proj.min(axis=0)))


def check_graspable(hand, obj, self_clearance: float | None = None) -> None:
    """Raise `UngraspableError` if `obj` fails one of the module docstring's necessary conditions for a
    precision grasp of `hand` (tips `self_clearance` m apart, None: no self-collision rule)."""
    from regrasp_casadi.stability import torque_reference

    mesh = obj.mesh
    reach = hand_reach(hand)
    r = reach.tip_radius
    _, bound_radius = torque_reference(mesh)
    need = TIP_SPACING * math.sqrt(3.0 / 8.0)
    if bound_radius + r < need:
        raise UngraspableError("too_small", (
            f"{obj.name!r} is too small for a precision grasp: its bounding radius "
            f"{bound_radius * 1e3:.1f} mm + the tip radius {r * 1e3:.1f} mm < {need * 1e3:.1f} mm, "
            f"the smallest ball that holds four fingertips {TIP_SPACING * 1e3:.0f} mm apart"))
    obb = mesh.bounding_box_oriented
    axes = np.asarray(obb.primitive.transform)[:3, :3].T
    thickness = float(np.min(obb.primitive.extents))
    if self_clearance is not None and thickness < self_clearance:
        raise UngraspableError("too_thin", (
            f"{obj.name!r} is too thin for the fingertips: {thickness * 1e3:.2f} mm thick, but two tips "
            f"pinching it must keep the self-clearance of {self_clearance * 1e3:.2f} mm"))
    excess = (mesh.convex_hull.volume - mesh.volume) / mesh.volume
    if excess <= CONVEX_EXCESS:
        width = narrowest_width(np.asarray(mesh.vertices), axes)
        if width + 2 * r > reach.max_thumb_finger:
            raise UngraspableError("too_large", (
                f"{obj.name!r} is too large for a precision grasp: its narrowest width {width * 1e3:.0f} mm "
                f"+ two tip radii > {reach.max_thumb_finger * 1e3:.0f} mm, the farthest the thumb's and "
                f"a finger's tip centres can be apart"))
