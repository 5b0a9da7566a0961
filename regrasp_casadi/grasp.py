"""Grasps: `Grasp`, a hand–object grasp validated against the exact object mesh.

A `Grasp` ties a hand configuration (or desired contacts) to an object pose and checks it against the
exact object mesh: joint count and limits, a proper rigid transform, every fingertip (or contact) on the
surface. Plans (`Plan`, `PlanStep`) are plain data and live in `regrasp_casadi.plan`.

    >>> grasp0 = Grasp.from_joints(hand, obj, q0, T_palm_object)
    >>> goal = Grasp.from_contacts(hand, obj, contacts_object, T_palm_goal)

`Hand` and `ObjectModel` are only type hints here: a grasp uses the models it is given.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.errors import GraspError
from regrasp_casadi.plan import frozen_array
from regrasp_casadi.transforms import inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel

__all__ = ["Grasp", "CONTACT_TOL", "require_grasp"]

JOINT_LIMIT_TOL = 1e-6
"""Slack on joint limits when validating a grasp, rad (m for prismatic joints)."""

RIGID_TOL = 1e-6
"""Tolerance on RᵀR = I, det R = 1 and the last row (0 0 0 1) of a rigid transform."""

CONTACT_TOL = 0.5e-3
"""Default tolerance of a grasp's contacts, m: |signed distance| of a contact (or of a tip sphere) to the
surface, and distance between a tip's contact and the grasp's contact (`Grasp.inconsistency`)."""


# --------------------------------------------------------------------------------------------- helpers
def _check_models(hand: Any, obj: Any) -> None:
    """`TypeError` naming the argument unless `hand` and `obj` look like a `Hand` and an `ObjectModel`."""
    if not all(hasattr(hand, a) for a in ("fingers", "n_joints", "tip_positions", "tip_radius")):
        raise TypeError(f"hand: expected a regrasp_casadi Hand, got {type(hand).__name__}")
    if not all(hasattr(obj, a) for a in ("closest_points", "exact_signed_distance", "surface_normals")):
        raise TypeError(f"obj: expected a regrasp_casadi ObjectModel, got {type(obj).__name__}")


def require_grasp(value: Any, name: str) -> Grasp:
    """`value` if it is a `Grasp`, else `TypeError` naming the argument `name` (for public entry points)."""
    if not isinstance(value, Grasp):
        raise TypeError(f"{name}: expected a Grasp (Grasp.from_joints / Grasp.from_contacts), "
                        f"got {type(value).__name__}")
    return value


def _float_array(x: Any, what: str, expected: str) -> NDArray[np.float64]:
    """`x` as a float array, or `GraspError` naming `what` when it holds something else than numbers."""
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        shown = repr(x) if len(repr(x)) <= 40 else f"a {type(x).__name__}"
        raise GraspError(f"{what}: expected {expected}, got {shown}") from None


def _check_joints(hand: Hand, q: Any, what: str = "q") -> NDArray[np.float64]:
    """Validate a joint vector (count, finiteness, limits within `JOINT_LIMIT_TOL`); return it as (n,)."""
    q = _float_array(q, what, f"{hand.n_joints} joint angles (rad)")
    if q.ndim != 1:
        raise GraspError(f"{what}: expected a 1-D vector of joint angles, got shape {q.shape}")
    if q.shape[0] != hand.n_joints:
        raise GraspError(f"expected {hand.n_joints} joint angles for {hand.name}, got {q.shape[0]}")
    if not np.all(np.isfinite(q)):
        bad = [hand.joint_names[i] for i in np.flatnonzero(~np.isfinite(q))]
        raise GraspError(f"{what}: joint angles are not finite for {', '.join(bad)}")
    lower, upper = np.asarray(hand.q_lower), np.asarray(hand.q_upper)
    out = np.flatnonzero((q < lower - JOINT_LIMIT_TOL) | (q > upper + JOINT_LIMIT_TOL))
    if out.size:
        parts = [
            f"joint {hand.joint_names[i]} = {q[i]:.6g} rad is outside its limits "
            f"[{lower[i]:.6g}, {upper[i]:.6g}] rad"
            for i in out
        ]
        raise GraspError("; ".join(parts))
    return q


def _check_rigid(T: Any, what: str = "T_palm_object") -> NDArray[np.float64]:
    """Validate a proper rigid (4, 4) transform: RᵀR = I, det R = +1, last row (0, 0, 0, 1)."""
    T = _float_array(T, what, "a (4, 4) rigid transform")
    if T.shape != (4, 4):
        raise GraspError(f"{what}: expected a (4, 4) transform, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise GraspError(f"{what}: has non-finite entries")
    if np.max(np.abs(T[3] - [0.0, 0.0, 0.0, 1.0])) > RIGID_TOL:
        raise GraspError(f"{what}: last row must be [0, 0, 0, 1], got {T[3].tolist()}")
    R = T[:3, :3]
    ortho = float(np.max(np.abs(R.T @ R - np.eye(3))))
    if ortho > RIGID_TOL:
        raise GraspError(f"{what}: rotation is not orthonormal (max |RᵀR − I| = {ortho:.3g})")
    det = float(np.linalg.det(R))
    if abs(det - 1.0) > RIGID_TOL:
        raise GraspError(f"{what}: rotation has det {det:.6g}, expected +1 (a reflection?)")
    return T


def _surface_message(who: str, d: float, tol: float) -> str:
    where = "off" if d > 0 else "inside"
    return f"{who} is {abs(d) * 1e3:.1f} mm {where} the object surface (tolerance {tol * 1e3:.1f} mm)"


# ---------------------------------------------------------------------------------------------- Grasp
@dataclass(frozen=True, eq=False)
class Grasp:
    """A grasp: hand, object, object pose in the palm frame and one contact per finger.

    Build it with `Grasp.from_joints` (a hand configuration; contacts are computed) or
    `Grasp.from_contacts` (desired contacts, e.g. a goal grasp); both validate their input against the
    exact object mesh and raise `GraspError` with the finger and the distance when it is wrong.
    Equality is identity (grasps hold models).
    """

    hand: Hand
    """The hand model."""
    obj: ObjectModel
    """The object model (its mesh is in the object frame, metres)."""
    T_palm_object: NDArray[np.float64]
    """(4, 4) pose of the object in the palm frame (maps object coordinates to palm coordinates)."""
    contacts_object: NDArray[np.float64]
    """(m, 3) contact points, object frame, m; rows in `hand.fingers` order, each on the object surface."""
    q: NDArray[np.float64] | None
    """(n,) joint angles in `hand.joint_names` order, rad; None for a goal given by contacts only."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_palm_object", frozen_array(self.T_palm_object, (4, 4)))
        object.__setattr__(self, "contacts_object", frozen_array(self.contacts_object, (None, 3)))
        if self.q is not None:
            object.__setattr__(self, "q", frozen_array(self.q, (None,)))
        object.__setattr__(self, "_tip_centers_cache", None)

    @property
    def fingers(self) -> tuple[str, ...]:
        """Finger names, the order of the rows of `contacts_object`."""
        return tuple(self.hand.fingers)

    @property
    def tip_centers_object(self) -> NDArray[np.float64]:
        """(m, 3) fingertip sphere centres for this grasp, object frame, m.

        For `from_joints` (or whenever `q` is given and the grasp was built directly), and for
        `from_contacts` given a `q` whose tips touch at the contacts, the actual tip centres of `q`;
        otherwise (`from_contacts`) each contact pushed out along the outward surface normal by the tip
        radius. The planner uses them as the tip-centre targets of goal contacts.
        """
        cached = self._tip_centers_cache  # type: ignore[attr-defined]
        if cached is None:
            if self.q is not None:
                p_palm = np.asarray(self.hand.tip_positions(self.q), dtype=np.float64)
                cached = transform_points(inv_T(self.T_palm_object), p_palm)
            else:
                n = np.asarray(self.obj.surface_normals(self.contacts_object), dtype=np.float64)
                cached = self.contacts_object + float(self.hand.tip_radius) * n
            cached = frozen_array(cached)
            object.__setattr__(self, "_tip_centers_cache", cached)
        return cached

    @classmethod
    def from_joints(
        cls, hand: Hand, obj: ObjectModel, q: Any, T_palm_object: Any, tol: float = CONTACT_TOL
    ) -> Grasp:
        """Grasp from a hand configuration; contacts are the exact closest mesh points of the tip centres.

        Args:
            hand: the hand.
            obj: the object.
            q: (n,) joint angles, rad, `hand.joint_names` order.
            T_palm_object: (4, 4) object pose in the palm frame.
            tol: allowed |exact signed distance of a tip centre − tip radius|, m.

        Raises:
            TypeError: `hand` or `obj` is not a hand / object model.
            GraspError: `q` or `T_palm_object` not numbers, wrong joint count, a joint outside its limits
                (named, with value and limits), a transform that is not a proper rigid one, or a fingertip
                farther than `tol` from the object surface (names the finger and the distance in mm).
        """
        _check_models(hand, obj)
        q = _check_joints(hand, q)
        T = _check_rigid(T_palm_object)
        p_palm = np.asarray(hand.tip_positions(q), dtype=np.float64).reshape(-1, 3)
        centers_object = transform_points(inv_T(T), p_palm)
        closest, sd = obj.closest_points(centers_object)
        gap = np.asarray(sd, dtype=np.float64) - float(hand.tip_radius)
        for finger, g in zip(hand.fingers, gap, strict=True):
            if not abs(g) <= tol:
                raise GraspError(_surface_message(f"{finger} tip", float(g), tol))
        grasp = cls(hand, obj, T, np.asarray(closest, dtype=np.float64), q)
        object.__setattr__(grasp, "_tip_centers_cache", frozen_array(centers_object))
        return grasp

    @classmethod
    def from_contacts(
        cls,
        hand: Hand,
        obj: ObjectModel,
        contacts_object: Any,
        T_palm_object: Any,
        q: Any = None,
        tol: float = CONTACT_TOL,
    ) -> Grasp:
        """Grasp from contact points on the object (e.g. a desired grasp).

        Args:
            hand: the hand.
            obj: the object.
            contacts_object: (m, 3) contacts, object frame, m, rows in `hand.fingers` order.
            T_palm_object: (4, 4) (desired) object pose in the palm frame.
            q: optional (n,) joint angles, rad; validated for count and limits. When its tip spheres
                touch the surface at the contacts (`inconsistency` is ""), the grasp's tip centres
                (`tip_centers_object`, the planner's targets) are those of q, as for `from_joints`;
                otherwise each contact pushed out along its surface normal. They differ at edges and
                rims, where the normal is a blend of the faces': a problem file's goal written from a
                generated pair keeps the generator's tip placement (problems/cup_regrasp.yaml: the ring's
                1.85 mm apart).
            tol: allowed |exact signed distance| of a contact, m.

        Raises:
            TypeError: `hand` or `obj` is not a hand / object model.
            GraspError: contacts not numbers or of the wrong shape, a contact farther than `tol` from the
                surface (names the finger and the distance in mm), a bad transform or bad joints.
        """
        _check_models(hand, obj)
        c = _float_array(contacts_object, "contacts_object", f"({len(hand.fingers)}, 3) contact points (m)")
        m = len(hand.fingers)
        if c.shape != (m, 3):
            raise GraspError(
                f"contacts_object: expected shape ({m}, 3) (one row per finger of {hand.name}: "
                f"{', '.join(hand.fingers)}), got {c.shape}"
            )
        if not np.all(np.isfinite(c)):
            raise GraspError("contacts_object: has non-finite entries")
        T = _check_rigid(T_palm_object)
        if q is not None:
            q = _check_joints(hand, q)
        sd = np.asarray(obj.exact_signed_distance(c), dtype=np.float64)
        for finger, d in zip(hand.fingers, sd, strict=True):
            if not abs(d) <= tol:
                raise GraspError(_surface_message(f"{finger} contact", float(d), tol))
        grasp = cls(hand, obj, T, c, q)
        if q is not None and not grasp.inconsistency(tol=tol):
            return grasp  # the tip centres of q (`tip_centers_object`), where they touch at the contacts
        normals = np.asarray(obj.surface_normals(c), dtype=np.float64)
        object.__setattr__(
            grasp, "_tip_centers_cache", frozen_array(c + float(hand.tip_radius) * normals)
        )
        return grasp

    def inconsistency(self, name: str = "grasp", tol: float = CONTACT_TOL) -> str:
        """Why the joints `q` do not hold the object at this grasp's contacts ("" when they do).

        For each finger, the tip sphere of `q` (object frame, through `T_palm_object`) must touch the
        surface (|exact signed distance of its centre − tip radius| ≤ `tol`) at the grasp's contact
        (closest surface point of the centre within `tol` of the contact row). `from_joints` grasps meet
        this by construction; a `from_contacts` grasp given `q`, or a grasp whose `q`, pose or contacts
        were replaced (`dataclasses.replace`), may not. A grasp without `q` is consistent.

        Args:
            name: how the grasp is named in the message (e.g. "grasp0").
            tol: tolerance, m.

        Returns:
            "" or one line naming the finger and the distance in mm.
        """
        if self.q is None:
            return ""
        p_palm = np.asarray(self.hand.tip_positions(self.q), dtype=np.float64).reshape(-1, 3)
        centers_object = transform_points(inv_T(np.asarray(self.T_palm_object)), p_palm)
        closest, sd = self.obj.closest_points(centers_object)
        gap = np.asarray(sd, dtype=np.float64) - float(self.hand.tip_radius)
        slip = np.linalg.norm(np.asarray(closest, dtype=np.float64) - self.contacts_object, axis=1)
        for finger, g, d in zip(self.hand.fingers, gap, slip, strict=True):
            if not abs(g) <= tol:
                where = "off" if g > 0 else "inside"
                return (f"{name}: its joints q put the {finger} tip {abs(g) * 1e3:.1f} mm {where} the "
                        f"object surface (tolerance {tol * 1e3:.1f} mm)")
            if not d <= tol:
                return (f"{name}: its joints q put the {finger} tip {d * 1e3:.1f} mm from its contact in "
                        f"contacts_object (tolerance {tol * 1e3:.1f} mm)")
        return ""
