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

Only numpy, the standard library, `regrasp_casadi.errors`, `regrasp_casadi.files` and
`regrasp_casadi.motion` are imported here: no hand, object or CasADi code.
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
from regrasp_casadi.motion import (
    DEFAULT_MAX_JOINT_SPEED,
    DEFAULT_MIN_STEP_DURATION,
    INTERPOLATION,
    PATH_PHASES,
    StepPath,
    join_step_motions,
    sample_knots,
)

__all__ = [
    "PlanStep",
    "Plan",
    "StepKind",
    "PlanStatus",
    "PlanMethod",
    "SCHEMA_VERSION",
    "READABLE_SCHEMA_VERSIONS",
    "STEP_KINDS",
    "PLAN_STATUSES",
    "PLAN_METHODS",
    "frozen_array",
]

SCHEMA_VERSION = 2
"""Version of the plan JSON schema written by `Plan.to_dict` (2: steps carry their `path`)."""

READABLE_SCHEMA_VERSIONS = (1, 2)
"""Versions `Plan.from_dict` reads: 1 (no paths: the steps load with `path=None`) and 2."""

_log = logging.getLogger(__name__)

StepKind = Literal["initial", "gait", "repose", "final", "slide"]
"""What a step does: the initial grasp, a finger gait (OPT1), an in-grasp reposing (OPT2), a final move,
or a slide (one finger moves with its tip on the surface, the rest still: the paper's assumption 5)."""

PlanStatus = Literal[
    "converged", "iteration_limit", "stalled", "solver_failure", "invalid_input", "interrupted"
]
"""Why the planner stopped: every contact within ζ; `max_iters` reached; no progress; a solve failed;
the input cannot be planned; the user interrupted it (Ctrl-C)."""

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
        _check_choice(self.kind, STEP_KINDS, f"{where}.kind")
        d = {
            "kind": self.kind,
            "finger": self.finger,
            "q": self.q.tolist(),
            "T_palm_object": self.T_palm_object.tolist(),
            "contacts_object": self.contacts_object.tolist(),
            "contact_error": self.contact_error.tolist(),
            "solver_status": self.solver_status,
            "solve_time": self.solve_time,
            "path": None if self.path is None else _path_to_dict(self.path, f"{where}.path"),
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
        d = _require_mapping(d, where, fields)
        path = None
        if schema_version >= 2:
            if "path" not in d:
                raise PlanFormatError(f"{where}.path: missing field (null for a step without motion)")
            path = None if d["path"] is None else _path_from_dict(d["path"], f"{where}.path")
        step = cls(
            kind=_get_choice(d, "kind", where, STEP_KINDS),
            finger=_get(d, "finger", where, (str, type(None))),
            q=_get_array(d, "q", where, 1),
            T_palm_object=_get_array(d, "T_palm_object", where, 2, (4, 4)),
            contacts_object=_get_array(d, "contacts_object", where, 2, (None, 3)),
            contact_error=_get_array(d, "contact_error", where, 1),
            solver_status=_get(d, "solver_status", where, str),
            solve_time=_get_float(d, "solve_time", where),
            path=path,
            certificate=_get_certificate(d, where),
        )
        if path is not None and path.q.shape[1] != step.q.shape[0]:
            raise PlanFormatError(f"{where}.path.q: expected {step.q.shape[0]} joints per knot (as "
                                  f"{where}.q), found {path.q.shape[1]}")
        return step


_STEP_FIELDS = tuple(f.name for f in dataclasses.fields(PlanStep))
_PATH_FIELDS = tuple(f.name for f in dataclasses.fields(StepPath))


def _get_certificate(d: dict, where: str) -> dict | None:
    """The optional step certificate (absent or null: None): a mapping with a known kind and a bool ok."""
    if d.get("certificate") is None:
        return None
    w = f"{where}.certificate"
    c = _require_mapping(d["certificate"], w, ("kind", "ok", "margin", "forces", "detail"))
    _check_choice(c.get("kind"), ("force_closure", "gravity"), f"{w}.kind")
    _get(c, "ok", w, bool)
    return dict(c)


def _path_to_dict(path: StepPath, where: str) -> dict[str, Any]:
    """JSON-ready dict of a `StepPath`; `PlanFormatError` for a phase or rule `from_dict` would refuse."""
    for i, phase in enumerate(path.phases):
        _check_choice(phase, PATH_PHASES, f"{where}.phases[{i}]")
    _check_choice(path.interpolation, (INTERPOLATION,), f"{where}.interpolation")
    return {
        "t": path.t.tolist(),
        "q": path.q.tolist(),
        "T_palm_object": path.T_palm_object.tolist(),
        "phases": list(path.phases),
        "ok": path.ok,
        "detail": path.detail,
        "metrics": dict(path.metrics),
        "interpolation": path.interpolation,
    }


def _path_from_dict(d: Any, where: str) -> StepPath:
    """Inverse of `_path_to_dict`; `PlanFormatError` naming the field."""
    d = _require_mapping(d, where, _PATH_FIELDS)
    phases = _get(d, "phases", where, list)
    for i, phase in enumerate(phases):
        _check_choice(phase, PATH_PHASES, f"{where}.phases[{i}]")
    metrics = _get(d, "metrics", where, dict)
    for k, v in metrics.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise PlanFormatError(f"{where}.metrics.{k}: expected a finite number, found {v!r:.60}")
    t = _get_array(d, "t", where, 1)
    if t.size and (t[0] != 0.0 or np.any(np.diff(t) < 0)):
        raise PlanFormatError(f"{where}.t: expected time stamps from 0, non-decreasing")
    try:
        return StepPath(t=t, q=_get_array(d, "q", where, 2),
                        T_palm_object=_get_array(d, "T_palm_object", where, 3, (None, 4, 4)),
                        phases=tuple(phases), ok=_get(d, "ok", where, bool),
                        detail=_get(d, "detail", where, str), metrics=metrics,
                        interpolation=_get_choice(d, "interpolation", where, (INTERPOLATION,)))
    except ValueError as e:
        raise PlanFormatError(f"{where}: {e}") from None


# ---------------------------------------------------------------------------- dict field validation
def _require_mapping(d: Any, where: str, fields: tuple[str, ...]) -> dict:
    """`d` itself, after checking that it is a dict whose keys are all among `fields`."""
    if not isinstance(d, dict):
        raise PlanFormatError(f"{where}: expected an object (mapping), found {type(d).__name__}")
    unknown = [k for k in d if k not in fields]
    if unknown:
        names = ", ".join(repr(k) for k in unknown)
        raise PlanFormatError(
            f"{where}: unknown field{'s' if len(unknown) > 1 else ''} {names} (known: {', '.join(fields)})"
        )
    return d


def _check_choice(value: Any, choices: tuple[str, ...], name: str) -> None:
    if not isinstance(value, str) or value not in choices:
        raise PlanFormatError(f"{name}: expected one of {', '.join(choices)}, found {value!r:.60}")


def _get(d: dict, key: str, where: str, types: type | tuple[type, ...]) -> Any:
    if key not in d:
        raise PlanFormatError(f"{where}.{key}: missing field")
    v = d[key]
    allowed = types if isinstance(types, tuple) else (types,)
    if not isinstance(v, allowed) or (isinstance(v, bool) and bool not in allowed):
        names = types.__name__ if isinstance(types, type) else " or ".join(t.__name__ for t in types)
        raise PlanFormatError(f"{where}.{key}: expected {names}, found {type(v).__name__} {v!r:.60}")
    return v


def _get_choice(d: dict, key: str, where: str, choices: tuple[str, ...]) -> Any:
    v = _get(d, key, where, str)
    _check_choice(v, choices, f"{where}.{key}")
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
        _check_choice(self.status, PLAN_STATUSES, "plan.status")
        _check_choice(self.method, PLAN_METHODS, "plan.method")
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
        return _jsonable(d, "plan")

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
        d = _require_mapping(d, w, _PLAN_FIELDS)
        version = _check_schema_version(d)
        steps_raw = _get(d, "steps", w, list)
        steps = tuple(PlanStep.from_dict(s, f"steps[{i}]", version) for i, s in enumerate(steps_raw))
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
        return cls(
            steps=steps,
            goal_contacts_object=_get_array(d, "goal_contacts_object", w, 2, (None, 3)),
            goal_T_palm_object=_get_array(d, "goal_T_palm_object", w, 2, (4, 4)),
            fingers=tuple(fingers),
            hand_spec=_get(d, "hand_spec", w, dict),
            object_spec=_get(d, "object_spec", w, dict),
            method=_get_choice(d, "method", w, PLAN_METHODS),
            status=_get_choice(d, "status", w, PLAN_STATUSES),
            status_detail=_get(d, "status_detail", w, str),
            iterations=iterations,
            iteration_errors=_get_array(d, "iteration_errors", w, 1),
            timing=dict(timing),
            options=_get(d, "options", w, dict),
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
            return cls.from_dict(_read_json(path))
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


# ------------------------------------------------------------------------------------------ JSON text
def _read_json(path: pathlib.Path) -> Any:
    """The JSON document in `path` (UTF-8, no NaN/Infinity, no duplicate keys).

    Raises:
        PlanFormatError: without the file name (the caller adds it).
    """
    try:
        data = path.read_bytes()
    except OSError as e:
        raise PlanFormatError(f"cannot read plan file: {e.strerror or e}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise PlanFormatError(f"not a UTF-8 text file (byte {e.start}: {e.reason})") from None
    try:
        return json.loads(text, parse_constant=_reject_constant, object_pairs_hook=_reject_duplicates)
    except ValueError as e:  # json.JSONDecodeError, or NaN / Infinity from `_reject_constant`
        raise PlanFormatError(f"not valid JSON: {e}") from None


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} is not allowed in a plan file")


def _reject_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """`object_pairs_hook` for `json.loads`: a dict, or `PlanFormatError` for a key given twice."""
    d: dict[str, Any] = {}
    for k, v in pairs:
        if k in d:
            raise PlanFormatError(f"duplicate key {k!r} in a JSON object")
        d[k] = v
    return d
