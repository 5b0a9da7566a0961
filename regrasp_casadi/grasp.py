"""Grasps and regrasp plans: `Grasp` (validated hand–object grasp), `PlanStep`, `Plan` and the plan file.

A `Grasp` ties a hand configuration (or desired contacts) to an object pose and checks it against the
exact object mesh. A `Plan` is what `plan_regrasp` returns: the steps (initial, gaits, reposings, final
move), the error after every iteration, timing and a status. Plans are saved as JSON, losslessly (floats
are written with `repr`, so every array is equal to the bit after `Plan.load(plan.save(...))`).

    >>> grasp0 = Grasp.from_joints(hand, obj, q0, T_palm_object)
    >>> plan.save("plan.json")
    >>> assert Plan.load("plan.json") == plan

Only numpy and the standard library are imported here; `Hand` and `ObjectModel` are imported lazily.
"""

from __future__ import annotations

import json
import math
import pathlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.errors import GraspError, PlanFormatError
from regrasp_casadi.transforms import inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.geometry import ObjectModel
    from regrasp_casadi.hand import Hand

__all__ = ["Grasp", "PlanStep", "Plan", "SCHEMA_VERSION", "STEP_KINDS", "PLAN_STATUSES"]

SCHEMA_VERSION = 1
"""Version of the plan JSON schema written by `Plan.to_dict`; `Plan.from_dict` accepts only this one."""

STEP_KINDS = ("initial", "gait", "repose", "final")
PLAN_STATUSES = ("converged", "iteration_limit", "solver_failure", "invalid_input")

JOINT_LIMIT_TOL = 1e-6
"""Slack on joint limits when validating a grasp, rad (m for prismatic joints)."""

RIGID_TOL = 1e-6
"""Tolerance on RᵀR = I, det R = 1 and the last row (0 0 0 1) of a rigid transform."""


# --------------------------------------------------------------------------------------------- helpers
def _frozen_array(x: Any, shape: tuple[int | None, ...] | None = None) -> NDArray[np.float64]:
    """A read-only float64 copy of `x` (the dataclasses here are frozen: so are their arrays)."""
    a = np.array(x, dtype=np.float64, copy=True)
    if shape is not None and (
        a.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape, strict=True))
    ):
        raise ValueError(f"expected shape {shape}, got {a.shape}")
    a.setflags(write=False)
    return a


def _check_joints(hand: Hand, q: Any, what: str = "q") -> NDArray[np.float64]:
    """Validate a joint vector (count, finiteness, limits within `JOINT_LIMIT_TOL`); return it as (n,)."""
    q = np.asarray(q, dtype=np.float64)
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
    T = np.asarray(T, dtype=np.float64)
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
        object.__setattr__(self, "T_palm_object", _frozen_array(self.T_palm_object, (4, 4)))
        object.__setattr__(self, "contacts_object", _frozen_array(self.contacts_object, (None, 3)))
        if self.q is not None:
            object.__setattr__(self, "q", _frozen_array(self.q, (None,)))
        object.__setattr__(self, "_tip_centers_cache", None)

    @property
    def fingers(self) -> tuple[str, ...]:
        """Finger names, the order of the rows of `contacts_object`."""
        return tuple(self.hand.fingers)

    @property
    def tip_centers_object(self) -> NDArray[np.float64]:
        """(m, 3) fingertip sphere centres for this grasp, object frame, m.

        For `from_joints` (or whenever `q` is given and the grasp was built directly) the actual tip
        centres of `q`; for `from_contacts` each contact pushed out along the outward surface normal by
        the tip radius. The planner uses them as the tip-centre targets of goal contacts.
        """
        cached = self._tip_centers_cache  # type: ignore[attr-defined]
        if cached is None:
            if self.q is not None:
                p_palm = np.asarray(self.hand.tip_positions(self.q), dtype=np.float64)
                cached = transform_points(inv_T(self.T_palm_object), p_palm)
            else:
                n = np.asarray(self.obj.surface_normals(self.contacts_object), dtype=np.float64)
                cached = self.contacts_object + float(self.hand.tip_radius) * n
            cached = _frozen_array(cached)
            object.__setattr__(self, "_tip_centers_cache", cached)
        return cached

    @classmethod
    def from_joints(
        cls, hand: Hand, obj: ObjectModel, q: Any, T_palm_object: Any, tol: float = 0.5e-3
    ) -> Grasp:
        """Grasp from a hand configuration; contacts are the exact closest mesh points of the tip centres.

        Args:
            hand: the hand.
            obj: the object.
            q: (n,) joint angles, rad, `hand.joint_names` order.
            T_palm_object: (4, 4) object pose in the palm frame.
            tol: allowed |exact signed distance of a tip centre − tip radius|, m.

        Raises:
            GraspError: wrong joint count, a joint outside its limits (named, with value and limits),
                a transform that is not a proper rigid one, or a fingertip farther than `tol` from the
                object surface (names the finger and the distance in mm).
        """
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
        object.__setattr__(grasp, "_tip_centers_cache", _frozen_array(centers_object))
        return grasp

    @classmethod
    def from_contacts(
        cls,
        hand: Hand,
        obj: ObjectModel,
        contacts_object: Any,
        T_palm_object: Any,
        q: Any = None,
        tol: float = 0.5e-3,
    ) -> Grasp:
        """Grasp from contact points on the object (e.g. a desired grasp).

        Args:
            hand: the hand.
            obj: the object.
            contacts_object: (m, 3) contacts, object frame, m, rows in `hand.fingers` order.
            T_palm_object: (4, 4) (desired) object pose in the palm frame.
            q: optional (n,) joint angles, rad; validated for count and limits only.
            tol: allowed |exact signed distance| of a contact, m.

        Raises:
            GraspError: wrong contacts shape, a contact farther than `tol` from the surface (names the
                finger and the distance in mm), a bad transform or bad joints.
        """
        c = np.asarray(contacts_object, dtype=np.float64)
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
        normals = np.asarray(obj.surface_normals(c), dtype=np.float64)
        object.__setattr__(
            grasp, "_tip_centers_cache", _frozen_array(c + float(hand.tip_radius) * normals)
        )
        return grasp


# ------------------------------------------------------------------------------------------- PlanStep
def _arrays_equal(a: Any, b: Any) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return bool(np.array_equal(np.asarray(a), np.asarray(b)))


@dataclass(frozen=True, eq=False)
class PlanStep:
    """One step of a plan: the hand configuration and object pose after it, and its contacts.

    Equality compares every array bit for bit (`np.array_equal`).
    """

    kind: str
    """"initial" | "gait" | "repose" | "final"."""
    finger: str | None
    """The finger moved by a gait step; None for other kinds."""
    q: NDArray[np.float64]
    """(n,) joint angles after the step, rad, `hand.joint_names` order."""
    T_palm_object: NDArray[np.float64]
    """(4, 4) object pose in the palm frame after the step."""
    contacts_object: NDArray[np.float64]
    """(m, 3) contact points after the step, object frame, m, rows in `Plan.fingers` order."""
    contact_error: NDArray[np.float64]
    """(m,) distance of each contact to its goal contact, m."""
    solver_status: str
    """IPOPT `return_status` of the NLP that produced the step ("" for the initial step)."""
    solve_time: float
    """Wall time of the step's solve, s."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", _frozen_array(self.q, (None,)))
        object.__setattr__(self, "T_palm_object", _frozen_array(self.T_palm_object, (4, 4)))
        object.__setattr__(self, "contacts_object", _frozen_array(self.contacts_object, (None, 3)))
        object.__setattr__(self, "contact_error", _frozen_array(self.contact_error, (None,)))
        object.__setattr__(self, "solve_time", float(self.solve_time))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PlanStep):
            return NotImplemented
        return (
            self.kind == other.kind
            and self.finger == other.finger
            and _arrays_equal(self.q, other.q)
            and _arrays_equal(self.T_palm_object, other.T_palm_object)
            and _arrays_equal(self.contacts_object, other.contacts_object)
            and _arrays_equal(self.contact_error, other.contact_error)
            and self.solver_status == other.solver_status
            and self.solve_time == other.solve_time
        )

    __hash__ = None  # type: ignore[assignment]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (arrays as nested lists of floats)."""
        return {
            "kind": self.kind,
            "finger": self.finger,
            "q": self.q.tolist(),
            "T_palm_object": self.T_palm_object.tolist(),
            "contacts_object": self.contacts_object.tolist(),
            "contact_error": self.contact_error.tolist(),
            "solver_status": self.solver_status,
            "solve_time": self.solve_time,
        }

    @classmethod
    def from_dict(cls, d: Any, where: str = "step") -> PlanStep:
        """Inverse of `to_dict`; raises `PlanFormatError` naming the field (`where` prefixes it)."""
        d = _require_mapping(d, where)
        kind = _get(d, "kind", where, str)
        if kind not in STEP_KINDS:
            raise PlanFormatError(f"{where}.kind: expected one of {STEP_KINDS}, found {kind!r}")
        finger = _get(d, "finger", where, (str, type(None)))
        return cls(
            kind=kind,
            finger=finger,
            q=_get_array(d, "q", where, 1),
            T_palm_object=_get_array(d, "T_palm_object", where, 2, (4, 4)),
            contacts_object=_get_array(d, "contacts_object", where, 2, (None, 3)),
            contact_error=_get_array(d, "contact_error", where, 1),
            solver_status=_get(d, "solver_status", where, str),
            solve_time=_get_float(d, "solve_time", where),
        )


# ---------------------------------------------------------------------------- dict field validation
def _require_mapping(d: Any, where: str) -> dict:
    if not isinstance(d, dict):
        raise PlanFormatError(f"{where}: expected an object (mapping), found {type(d).__name__}")
    return d


def _get(d: dict, key: str, where: str, types: type | tuple[type, ...]) -> Any:
    if key not in d:
        raise PlanFormatError(f"{where}.{key}: missing field")
    v = d[key]
    allowed = types if isinstance(types, tuple) else (types,)
    if not isinstance(v, allowed) or (isinstance(v, bool) and bool not in allowed):
        names = types.__name__ if isinstance(types, type) else " or ".join(t.__name__ for t in types)
        raise PlanFormatError(f"{where}.{key}: expected {names}, found {type(v).__name__} {v!r:.60}")
    return v


def _get_float(d: dict, key: str, where: str) -> float:
    v = _get(d, key, where, (int, float))
    if isinstance(v, bool) or not math.isfinite(v):
        raise PlanFormatError(f"{where}.{key}: expected a finite number, found {v!r}")
    return float(v)


def _get_array(
    d: dict, key: str, where: str, ndim: int, shape: tuple[int | None, ...] | None = None
) -> NDArray[np.float64]:
    if key not in d:
        raise PlanFormatError(f"{where}.{key}: missing field")
    v = d[key]
    try:
        if not isinstance(v, list) or _has_bool(v):
            raise TypeError
        a = np.array(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise PlanFormatError(
            f"{where}.{key}: expected a {ndim}-D array of numbers, found {v!r:.60}"
        ) from None
    if a.ndim != ndim and not (a.size == 0 and ndim == 2 and shape is not None):
        raise PlanFormatError(f"{where}.{key}: expected a {ndim}-D array, found shape {a.shape}")
    if a.size == 0 and ndim == 2 and shape is not None:
        a = a.reshape(0, shape[1] if shape[1] is not None else 0)
    if shape is not None and any(s is not None and s != n for s, n in zip(shape, a.shape, strict=True)):
        raise PlanFormatError(f"{where}.{key}: expected shape {shape}, found {a.shape}")
    if not np.all(np.isfinite(a)):
        raise PlanFormatError(f"{where}.{key}: non-finite values")
    return a


def _has_bool(v: Any) -> bool:
    if isinstance(v, bool):
        return True
    if isinstance(v, list):
        return any(_has_bool(x) for x in v)
    return False


def _jsonable(x: Any, where: str) -> Any:
    """Convert numpy scalars/arrays and tuples to JSON-native values; reject non-finite floats."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v, f"{where}.{k}") for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v, f"{where}[{i}]") for i, v in enumerate(x)]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist(), where)
    if isinstance(x, np.generic):
        return _jsonable(x.item(), where)
    if isinstance(x, float) and not math.isfinite(x):
        raise PlanFormatError(f"{where}: non-finite value {x!r} cannot be written to JSON")
    if isinstance(x, pathlib.PurePath):
        return str(x)
    if x is None or isinstance(x, (bool, int, float, str)):
        return x
    raise PlanFormatError(f"{where}: value of type {type(x).__name__} cannot be written to JSON")


# ----------------------------------------------------------------------------------------------- Plan
@dataclass(frozen=True, eq=False)
class Plan:
    """A regrasp plan (the output of `plan_regrasp`), saved to / loaded from JSON without loss.

    Equality compares every field, arrays bit for bit. `plan.hand()` / `plan.object()` rebuild the
    models from their specs (cached on the instance).
    """

    steps: tuple[PlanStep, ...]
    """Every step in order; steps[0] is the initial grasp (kind "initial")."""
    goal_contacts_object: NDArray[np.float64]
    """(m, 3) desired contacts, object frame, m, rows in `fingers` order."""
    goal_T_palm_object: NDArray[np.float64]
    """(4, 4) desired object pose in the palm frame."""
    fingers: tuple[str, ...]
    """Finger names, the order of every (m, ·) array."""
    hand_spec: dict
    """How to rebuild the hand: `Hand.from_spec(hand_spec)`."""
    object_spec: dict
    """How to rebuild the object: `ObjectModel.from_spec(object_spec)`."""
    method: str
    """In-grasp objective: "svd" | "sd"."""
    status: str
    """"converged" | "iteration_limit" | "solver_failure" | "invalid_input"."""
    status_detail: str
    """Human-readable reason (e.g. the failing step and IPOPT's status)."""
    iterations: int
    """Number of planner iterations (gait round + reposing) performed."""
    iteration_errors: NDArray[np.float64]
    """(iterations + 1,) average point error after each iteration, m (index 0: initial grasp)."""
    timing: dict[str, float]
    """Wall times in s: "build", "opt1", "opt2", "other", "total"."""
    options: dict
    """The planner options used (JSON-native values: e.g. "zeta", "eta", "beta" in m)."""
    schema_version: int = SCHEMA_VERSION
    """Version of the JSON schema."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "steps", tuple(self.steps))
        object.__setattr__(self, "fingers", tuple(self.fingers))
        object.__setattr__(
            self, "goal_contacts_object", _frozen_array(self.goal_contacts_object, (None, 3))
        )
        object.__setattr__(self, "goal_T_palm_object", _frozen_array(self.goal_T_palm_object, (4, 4)))
        object.__setattr__(self, "iteration_errors", _frozen_array(self.iteration_errors, (None,)))
        object.__setattr__(self, "_models", {})

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Plan):
            return NotImplemented
        return (
            self.steps == other.steps
            and _arrays_equal(self.goal_contacts_object, other.goal_contacts_object)
            and _arrays_equal(self.goal_T_palm_object, other.goal_T_palm_object)
            and self.fingers == other.fingers
            and self.hand_spec == other.hand_spec
            and self.object_spec == other.object_spec
            and self.method == other.method
            and self.status == other.status
            and self.status_detail == other.status_detail
            and self.iterations == other.iterations
            and _arrays_equal(self.iteration_errors, other.iteration_errors)
            and self.timing == other.timing
            and self.options == other.options
            and self.schema_version == other.schema_version
        )

    __hash__ = None  # type: ignore[assignment]

    # ------------------------------------------------------------------------------- models
    def hand(self) -> Hand:
        """The hand rebuilt from `hand_spec` (cached on this plan)."""
        if "hand" not in self._models:  # type: ignore[attr-defined]
            from regrasp_casadi.hand import Hand

            self._models["hand"] = Hand.from_spec(self.hand_spec)  # type: ignore[attr-defined]
        return self._models["hand"]  # type: ignore[attr-defined]

    def object(self) -> ObjectModel:
        """The object rebuilt from `object_spec` (cached on this plan)."""
        if "object" not in self._models:  # type: ignore[attr-defined]
            from regrasp_casadi.geometry import ObjectModel

            self._models["object"] = ObjectModel.from_spec(self.object_spec)  # type: ignore[attr-defined]
        return self._models["object"]  # type: ignore[attr-defined]

    # ------------------------------------------------------------------------------- figures
    @property
    def final_error(self) -> float:
        """Average point error of the last step: mean over fingers of its `contact_error`, m."""
        if not self.steps or self.steps[-1].contact_error.size == 0:
            return float("nan")
        return float(np.mean(self.steps[-1].contact_error))

    def step_counts(self) -> str:
        """Steps by kind, e.g. "1 initial, 26 gait, 6 repose, 1 final" (kinds that occur, in order)."""
        counts = {k: sum(s.kind == k for s in self.steps) for k in STEP_KINDS}
        return ", ".join(f"{counts[k]} {k}" for k in STEP_KINDS if counts[k])

    def summary(self) -> str:
        """A short multi-line text: status, iterations, steps by kind, final errors (mm), timing (s)."""
        kinds = self.step_counts()
        lines = [
            f"status: {self.status}" + (f" ({self.status_detail})" if self.status_detail else ""),
            f"method: {self.method}, iterations: {self.iterations}, steps: {len(self.steps)} ({kinds})",
        ]
        if self.steps and self.steps[-1].contact_error.size:
            err = self.steps[-1].contact_error
            lines.append(
                f"final contact error: avg {np.mean(err) * 1e3:.2f} mm, max {np.max(err) * 1e3:.2f} mm"
            )
        if self.timing:
            lines.append("timing: " + ", ".join(f"{k} {v:.3f} s" for k, v in self.timing.items()))
        return "\n".join(lines)

    # ------------------------------------------------------------------------------- file format
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of the plan (schema `SCHEMA_VERSION`).

        Raises:
            PlanFormatError: a field holds a non-finite number or a value JSON cannot represent.
        """
        d = {
            "schema_version": self.schema_version,
            "fingers": list(self.fingers),
            "hand_spec": self.hand_spec,
            "object_spec": self.object_spec,
            "method": self.method,
            "status": self.status,
            "status_detail": self.status_detail,
            "iterations": self.iterations,
            "iteration_errors": self.iteration_errors.tolist(),
            "timing": self.timing,
            "options": self.options,
            "goal_contacts_object": self.goal_contacts_object.tolist(),
            "goal_T_palm_object": self.goal_T_palm_object.tolist(),
            "steps": [s.to_dict() for s in self.steps],
        }
        return _jsonable(d, "plan")

    @classmethod
    def from_dict(cls, d: Any) -> Plan:
        """Inverse of `to_dict`.

        Raises:
            PlanFormatError: wrong or missing `schema_version` (with expected and found), or a missing
                or malformed field (named, e.g. "steps[3].q").
        """
        d = _require_mapping(d, "plan")
        if "schema_version" not in d:
            raise PlanFormatError(
                f"schema_version: missing field (expected {SCHEMA_VERSION}); not a regrasp plan?"
            )
        version = d["schema_version"]
        if isinstance(version, bool) or version != SCHEMA_VERSION:
            raise PlanFormatError(
                f"schema_version: expected {SCHEMA_VERSION}, found {version!r} "
                "(written by another version of regrasp_casadi)"
            )
        w = "plan"
        steps_raw = _get(d, "steps", w, list)
        steps = tuple(PlanStep.from_dict(s, f"steps[{i}]") for i, s in enumerate(steps_raw))
        fingers = _get(d, "fingers", w, list)
        if not all(isinstance(f, str) for f in fingers):
            raise PlanFormatError(f"fingers: expected a list of names, found {fingers!r:.60}")
        timing = _get(d, "timing", w, dict)
        for k, v in timing.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise PlanFormatError(f"timing.{k}: expected a number, found {v!r:.60}")
        iterations = _get(d, "iterations", w, int)
        if isinstance(iterations, bool) or iterations < 0:
            raise PlanFormatError(f"iterations: expected a non-negative integer, found {iterations!r}")
        plan = cls(
            steps=steps,
            goal_contacts_object=_get_array(d, "goal_contacts_object", w, 2, (None, 3)),
            goal_T_palm_object=_get_array(d, "goal_T_palm_object", w, 2, (4, 4)),
            fingers=tuple(fingers),
            hand_spec=_get(d, "hand_spec", w, dict),
            object_spec=_get(d, "object_spec", w, dict),
            method=_get(d, "method", w, str),
            status=_get(d, "status", w, str),
            status_detail=_get(d, "status_detail", w, str),
            iterations=iterations,
            iteration_errors=_get_array(d, "iteration_errors", w, 1),
            timing=dict(timing),
            options=_get(d, "options", w, dict),
            schema_version=SCHEMA_VERSION,
        )
        return plan

    def save(self, path: str | pathlib.Path) -> pathlib.Path:
        """Write the plan as JSON (floats by `repr`: lossless; `allow_nan=False`). Returns the path."""
        path = pathlib.Path(path)
        text = json.dumps(self.to_dict(), allow_nan=False, indent=1)
        path.write_text(text + "\n", encoding="utf-8")
        return path

    @classmethod
    def load(cls, path: str | pathlib.Path) -> Plan:
        """Read a plan written by `save`.

        Raises:
            PlanFormatError: unreadable file, invalid JSON, wrong schema version or malformed fields;
                the message starts with the file name.
        """
        path = pathlib.Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as e:
            raise PlanFormatError(f"{path}: cannot read plan file: {e.strerror or e}") from None
        try:
            d = json.loads(text, parse_constant=_reject_constant)
        except (json.JSONDecodeError, ValueError) as e:
            raise PlanFormatError(f"{path}: not valid JSON: {e}") from None
        try:
            return cls.from_dict(d)
        except PlanFormatError as e:
            raise PlanFormatError(f"{path}: {e}") from None


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} is not allowed in a plan file")

