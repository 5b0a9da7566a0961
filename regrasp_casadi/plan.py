"""Regrasp plans as plain data: `PlanStep`, `Plan` and the plan file (JSON).

A `Plan` is what `plan_regrasp` returns: the steps (initial, gaits, reposings, final move), the error
after every iteration, timing, a status and the specs from which the hand and the object can be rebuilt
(`regrasp_casadi.problem.plan_models(plan)`). Each step may carry its motion from the previous step
(`PlanStep.path`, a `regrasp_casadi.motion.StepPath`); `Plan.sample(dt)` returns the whole motion.
Plans are saved as JSON without loss: floats are written with `repr`, so every array is equal to the
bit after `Plan.load(plan.save(...))`. The file is strict: an unknown field, status, method, step kind
or path phase, a duplicate key or a non-UTF-8 file is a `PlanFormatError` naming the file and field.

    >>> plan.save("plan.json")
    >>> assert Plan.load("plan.json") == plan
    >>> t, q, T_palm_object = plan.sample(0.01)   # (N,) s, (N, n) rad, (N, 4, 4)

Schema versions: 2 (written) adds `steps[i].path`; files of version 1 (no paths) still load, their
steps without a path; any other version is a `PlanFormatError` saying which versions are readable.

The file's field validation and JSON text are `regrasp_casadi.plan_codec`. Only numpy, the standard
library, `regrasp_casadi.errors`, `regrasp_casadi.files`, `regrasp_casadi.grasp_metrics`,
`regrasp_casadi.motion` and `regrasp_casadi.plan_codec` are imported here: no hand, object or CasADi code.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import pathlib
from dataclasses import dataclass
from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.errors import PlanFormatError
from regrasp_casadi.files import atomic_write_text
from regrasp_casadi.grasp_metrics import pose_error
from regrasp_casadi.motion import (
    DEFAULT_MAX_JOINT_SPEED,
    DEFAULT_MIN_STEP_DURATION,
    StepPath,
    join_step_motions,
    sample_knots,
)
from regrasp_casadi.plan_codec import (
    check_choice,
    get_array,
    get_certificate,
    get_choice,
    get_field,
    get_float,
    jsonable,
    path_from_dict,
    path_to_dict,
    read_json,
    require_mapping,
)

__all__ = ["PlanStep", "Plan", "StepKind", "PlanStatus", "PlanMethod", "SCHEMA_VERSION",
           "READABLE_SCHEMA_VERSIONS", "STEP_KINDS", "PLAN_STATUSES", "PLAN_METHODS", "frozen_array"]

SCHEMA_VERSION = 2
"""Version of the plan JSON schema written by `Plan.to_dict` (2: steps carry their `path`)."""

READABLE_SCHEMA_VERSIONS = (1, 2)
"""Versions `Plan.from_dict` reads: 1 (no paths: the steps load with `path=None`) and 2."""

_log = logging.getLogger(__name__)

StepKind = Literal["initial", "gait", "repose", "final", "slide"]
"""What a step does: the initial grasp, a finger gait (OPT1), an in-grasp reposing (OPT2), a final move,
or a slide (one finger moves with its tip on the surface, the rest still: the paper's assumption 5)."""

PlanStatus = Literal["converged", "iteration_limit", "stalled", "solver_failure", "invalid_input",
                     "interrupted", "pose_not_reached"]
"""Why the planner stopped: every contact within ζ and the object at the desired pose; `max_iters`
reached; no progress; a solve failed; the input cannot be planned; the user interrupted it (Ctrl-C);
every contact within ζ but the object not within the pose tolerance of the desired pose."""

PlanMethod = Literal["svd", "sd"]
"""The in-grasp objective: the SVD (Kabsch) pose target or the signed distance to the workspace hulls."""

STEP_KINDS: tuple[StepKind, ...] = get_args(StepKind)
PLAN_STATUSES: tuple[PlanStatus, ...] = get_args(PlanStatus)
PLAN_METHODS: tuple[PlanMethod, ...] = get_args(PlanMethod)


def frozen_array(x: Any, shape: tuple[int | None, ...] | None = None) -> NDArray[np.float64]:
    """A read-only float64 copy of `x` (the frozen dataclasses of plans and grasps hold these).

    Args:
        x: anything `np.array` accepts.
        shape: the expected shape; None matches any size along that axis.

    Raises:
        ValueError: the shape differs from `shape`.
    """
    a = np.array(x, dtype=np.float64, copy=True)
    if shape is not None and (
        a.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape, strict=True))
    ):
        raise ValueError(f"expected shape {shape}, got {a.shape}")
    a.setflags(write=False)
    return a


def _fields_equal(a: Any, b: Any) -> bool:
    """Every dataclass field of a and b equal: arrays bit for bit (`np.array_equal`), others by `==`."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if x is None or y is None or not np.array_equal(np.asarray(x), np.asarray(y)):
                return False
        elif x != y:
            return False
    return True


# ------------------------------------------------------------------------------------------- PlanStep
@dataclass(frozen=True, eq=False)
class PlanStep:
    """One step of a plan: the hand configuration and object pose after it, and its contacts.

    Equality compares every array bit for bit (`np.array_equal`). The constructor does not check
    `kind` (so that a malformed plan can be built and judged by `verify`); the file codec does.
    """

    kind: StepKind
    """"initial" | "gait" | "repose" | "final" (`STEP_KINDS`)."""
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
    path: StepPath | None = None
    """The motion from the previous step to this one (None: the initial step, a plan of schema version
    1, or a plan made without trajectories; `Plan.sample` then moves linearly between the steps)."""
    certificate: dict | None = None
    """The stability certificate of the step's holding set (`certificates.Certificate.to_dict()`), None
    when planned without one (stability "none"); written to the file only when set."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", frozen_array(self.q, (None,)))
        object.__setattr__(self, "T_palm_object", frozen_array(self.T_palm_object, (4, 4)))
        object.__setattr__(self, "contacts_object", frozen_array(self.contacts_object, (None, 3)))
        object.__setattr__(self, "contact_error", frozen_array(self.contact_error, (None,)))
        object.__setattr__(self, "solve_time", float(self.solve_time))

    def __eq__(self, other: object) -> bool:
        return _fields_equal(self, other) if isinstance(other, PlanStep) else NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def to_dict(self, where: str = "step") -> dict[str, Any]:
        """JSON-ready dict (arrays as nested lists of floats).

        Raises:
            PlanFormatError: `kind` is not one of `STEP_KINDS` (the file could not be read back).
        """
        check_choice(self.kind, STEP_KINDS, f"{where}.kind")
        d = {
            "kind": self.kind,
            "finger": self.finger,
            "q": self.q.tolist(),
            "T_palm_object": self.T_palm_object.tolist(),
            "contacts_object": self.contacts_object.tolist(),
            "contact_error": self.contact_error.tolist(),
            "solver_status": self.solver_status,
            "solve_time": self.solve_time,
            "path": None if self.path is None else path_to_dict(self.path, f"{where}.path"),
        }
        return d if self.certificate is None else {**d, "certificate": dict(self.certificate)}

    @classmethod
    def from_dict(cls, d: Any, where: str = "step", schema_version: int = SCHEMA_VERSION) -> PlanStep:
        """Inverse of `to_dict`; raises `PlanFormatError` naming the field (`where` prefixes it).

        Unknown fields, a missing field and an unknown `kind` are errors. A step of `schema_version` 1
        has no "path" field (it loads with `path=None`); from version 2 on "path" is required (may be
        null).
        """
        fields = _STEP_FIELDS if schema_version >= 2 else tuple(f for f in _STEP_FIELDS if f != "path")
        d = require_mapping(d, where, fields)
        path = None
        if schema_version >= 2:
            if "path" not in d:
                raise PlanFormatError(f"{where}.path: missing field (null for a step without motion)")
            path = None if d["path"] is None else path_from_dict(d["path"], f"{where}.path")
        step = cls(
            kind=get_choice(d, "kind", where, STEP_KINDS),
            finger=get_field(d, "finger", where, (str, type(None))),
            q=get_array(d, "q", where, 1),
            T_palm_object=get_array(d, "T_palm_object", where, 2, (4, 4)),
            contacts_object=get_array(d, "contacts_object", where, 2, (None, 3)),
            contact_error=get_array(d, "contact_error", where, 1),
            solver_status=get_field(d, "solver_status", where, str),
            solve_time=get_float(d, "solve_time", where),
            path=path,
            certificate=get_certificate(d, where),
        )
        if path is not None and path.q.shape[1] != step.q.shape[0]:
            raise PlanFormatError(f"{where}.path.q: expected {step.q.shape[0]} joints per knot (as "
                                  f"{where}.q), found {path.q.shape[1]}")
        return step


_STEP_FIELDS = tuple(f.name for f in dataclasses.fields(PlanStep))


# ----------------------------------------------------------------------------------------------- Plan
@dataclass(frozen=True, eq=False)
class Plan:
    """A regrasp plan (the output of `plan_regrasp`), saved to / loaded from JSON without loss.

    Equality compares every field, arrays bit for bit. `regrasp_casadi.problem.plan_models(plan)`
    rebuilds the hand and the object from `hand_spec` / `object_spec`. The constructor does not check
    `status` / `method` (a malformed plan can still be judged by `verify`); `to_dict` and `from_dict` do.
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
    method: PlanMethod
    """In-grasp objective: "svd" | "sd" (`PLAN_METHODS`)."""
    status: PlanStatus
    """Why the planner stopped, one of `PLAN_STATUSES` (see `PlanStatus`)."""
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
        object.__setattr__(self, "goal_contacts_object", frozen_array(self.goal_contacts_object, (None, 3)))
        object.__setattr__(self, "goal_T_palm_object", frozen_array(self.goal_T_palm_object, (4, 4)))
        object.__setattr__(self, "iteration_errors", frozen_array(self.iteration_errors, (None,)))

    def __eq__(self, other: object) -> bool:
        return _fields_equal(self, other) if isinstance(other, Plan) else NotImplemented

    __hash__ = None  # type: ignore[assignment]

    # ------------------------------------------------------------------------------- figures
    @property
    def final_error(self) -> float:
        """Average point error of the last step: mean over fingers of its `contact_error`, m."""
        if not self.steps or self.steps[-1].contact_error.size == 0:
            return float("nan")
        return float(np.mean(self.steps[-1].contact_error))

    @property
    def final_pose_error(self) -> tuple[float, float]:
        """(position m, rotation rad) of the last step's object pose from `goal_T_palm_object` (nan: no
        steps); derived from the stored poses, so every plan file, old ones too, has it."""
        return pose_error(self.steps[-1].T_palm_object, self.goal_T_palm_object) if self.steps else (
            float("nan"), float("nan"))

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
            err, (dp, dr) = self.steps[-1].contact_error, self.final_pose_error
            lines.append(
                f"final contact error: avg {np.mean(err) * 1e3:.2f} mm, max {np.max(err) * 1e3:.2f} mm; "
                f"object {dp * 1e3:.2f} mm / {math.degrees(dr):.2f}° from the desired pose")
        paths = [(i, s.path) for i, s in enumerate(self.steps) if s.path is not None]
        if paths:
            flagged = [f"step {i}" for i, p in paths if not p.ok]
            lines.append(f"motion: {sum(p.duration for _, p in paths):.2f} s, {len(paths)} paths"
                         + (f", {len(flagged)} flagged ({', '.join(flagged[:5])})" if flagged else ""))
        if self.timing:
            lines.append("timing: " + ", ".join(f"{k} {v:.3f} s" for k, v in self.timing.items()))
        return "\n".join(lines)

    def sample(self, dt: float = 0.01, max_joint_speed: float = DEFAULT_MAX_JOINT_SPEED,
               min_step_duration: float = DEFAULT_MIN_STEP_DURATION
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The whole motion of the plan sampled every `dt` s (the end included).

        Each step's `path` is followed by its time stamps and `motion.INTERPOLATION` (linear in joint
        space and in the object pose between knots). A step without a path (schema version 1, a plan
        made without trajectories) moves linearly from the previous step, timed by `motion.time_stamps`
        with `max_joint_speed` (rad/s) and `min_step_duration` (s); a note is logged.

        Returns:
            t (N,) s from the initial step; q (N, n) rad; T_palm_object (N, 4, 4), palm frame.
        """
        t, q, T, unpathed = join_step_motions(self.steps, max_joint_speed, min_step_duration)
        if unpathed:
            _log.info("steps %s have no path: moving linearly in joint space and object pose between "
                      "the steps (%.2f rad/s)", unpathed, max_joint_speed)
        return sample_knots(t, q, T, dt)

    # ------------------------------------------------------------------------------- file format
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of the plan (schema `SCHEMA_VERSION`).

        Raises:
            PlanFormatError: a field holds a non-finite number or a value JSON cannot represent, or an
                unknown status, method or step kind (a file `from_dict` would refuse).
        """
        check_choice(self.status, PLAN_STATUSES, "plan.status")
        check_choice(self.method, PLAN_METHODS, "plan.method")
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
            "steps": [s.to_dict(f"steps[{i}]") for i, s in enumerate(self.steps)],
        }
        return jsonable(d, "plan")

    @classmethod
    def from_dict(cls, d: Any) -> Plan:
        """Inverse of `to_dict`.

        A file of schema version 1 loads with every `path` None (and is written back as version 2).

        Raises:
            PlanFormatError: wrong or missing `schema_version` (with readable and found), an unknown
                field, status, method or step kind, or a missing or malformed field (named, e.g.
                "steps[3].q").
        """
        w = "plan"
        d = require_mapping(d, w, _PLAN_FIELDS)
        version = _check_schema_version(d)
        steps_raw = get_field(d, "steps", w, list)
        steps = tuple(PlanStep.from_dict(s, f"steps[{i}]", version) for i, s in enumerate(steps_raw))
        fingers = get_field(d, "fingers", w, list)
        if not all(isinstance(f, str) for f in fingers):
            raise PlanFormatError(f"fingers: expected a list of names, found {fingers!r:.60}")
        timing = get_field(d, "timing", w, dict)
        for k, v in timing.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise PlanFormatError(f"timing.{k}: expected a number, found {v!r:.60}")
        iterations = get_field(d, "iterations", w, int)
        if isinstance(iterations, bool) or iterations < 0:
            raise PlanFormatError(f"iterations: expected a non-negative integer, found {iterations!r}")
        return cls(
            steps=steps,
            goal_contacts_object=get_array(d, "goal_contacts_object", w, 2, (None, 3)),
            goal_T_palm_object=get_array(d, "goal_T_palm_object", w, 2, (4, 4)),
            fingers=tuple(fingers),
            hand_spec=get_field(d, "hand_spec", w, dict),
            object_spec=get_field(d, "object_spec", w, dict),
            method=get_choice(d, "method", w, PLAN_METHODS),
            status=get_choice(d, "status", w, PLAN_STATUSES),
            status_detail=get_field(d, "status_detail", w, str),
            iterations=iterations,
            iteration_errors=get_array(d, "iteration_errors", w, 1),
            timing=dict(timing),
            options=get_field(d, "options", w, dict),
            schema_version=SCHEMA_VERSION,
        )

    def save(self, path: str | pathlib.Path) -> pathlib.Path:
        """Write the plan as JSON (floats by `repr`: lossless; `allow_nan=False`). Returns the path.

        The write is atomic (`atomic_write_text`): if it fails, a previous file at `path` is kept.

        Raises:
            PlanFormatError: the plan cannot be written (see `to_dict`); nothing is written then.
            OSError: the file cannot be written.
        """
        text = json.dumps(self.to_dict(), allow_nan=False, indent=1)
        return atomic_write_text(path, text + "\n")

    @classmethod
    def load(cls, path: str | pathlib.Path) -> Plan:
        """Read a plan written by `save`.

        Raises:
            PlanFormatError: unreadable or non-UTF-8 file, invalid JSON, a duplicate key, wrong schema
                version, unknown or malformed fields; the message starts with the file name.
        """
        path = pathlib.Path(path)
        try:
            return cls.from_dict(read_json(path))
        except PlanFormatError as e:
            raise PlanFormatError(f"{path}: {e}") from None


_PLAN_FIELDS = tuple(f.name for f in dataclasses.fields(Plan))


def _check_schema_version(d: dict) -> int:
    """The file's schema version, one of `READABLE_SCHEMA_VERSIONS`; `PlanFormatError` otherwise."""
    readable = " or ".join(str(v) for v in READABLE_SCHEMA_VERSIONS)
    if "schema_version" not in d:
        raise PlanFormatError(f"schema_version: missing field (expected {readable}); not a regrasp plan?")
    version = d["schema_version"]
    if isinstance(version, bool) or not isinstance(version, int) or version not in READABLE_SCHEMA_VERSIONS:
        newer = isinstance(version, int) and not isinstance(version, bool) and version > SCHEMA_VERSION
        raise PlanFormatError(
            f"schema_version: expected {readable}, found {version!r} ("
            + ("written by a newer version of regrasp_casadi: upgrade it to read this plan)" if newer
               else "written by another version of regrasp_casadi)"))
    return version
