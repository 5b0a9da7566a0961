"""The motion between plan steps as plain data: `StepPath`, its time stamps and its sampling.

A `StepPath` leads from the previous step of a plan to its own step: knots (joint angles and object
pose), one phase name per segment, time stamps and a flag that says whether the planner's own checks
passed. Between knots the motion follows `INTERPOLATION`: linear in joint space and in the object pose
(translation linear, rotation along the geodesic), at constant speed in the time stamps. Time stamps come
from a joint speed limit (`time_stamps`). `sample_knots` evaluates that rule at any times; `Plan.sample`
uses it for the whole plan.

    >>> t, q, T_palm_object = sample_knots(path.t, path.q, path.T_palm_object, dt=0.01)

Only numpy and the standard library are imported at module level (scipy's rotations when sampling): no
hand, object or CasADi code. The paths are computed in `regrasp_casadi.trajectory`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "StepPath",
    "PathPhase",
    "PATH_PHASES",
    "INTERPOLATION",
    "DEFAULT_MAX_JOINT_SPEED",
    "DEFAULT_MIN_STEP_DURATION",
    "time_stamps",
    "interpolate_knots",
    "sample_knots",
    "join_step_motions",
    "step_knots",
]

INTERPOLATION = "linear"
"""The one interpolation rule between knots: q linear in time; object translation linear and rotation
along the geodesic R_a·exp(s·log(R_aᵀR_b)), with the same fraction s = (t − t_a)/(t_b − t_a)."""

DEFAULT_MAX_JOINT_SPEED = 1.0
"""Largest joint speed of the time stamps, rad/s (issue 15: 1 rad/s)."""

DEFAULT_MIN_STEP_DURATION = 0.05
"""Shortest duration of one step's motion, s: a step whose joints barely move still takes this long."""

PathPhase = Literal["lift", "transit", "touch_down", "repose", "slide"]
"""What a segment of a path does: a gait's lift-off along the contact normal, its transit above the
object, its touch-down along the new contact's normal; an in-grasp reposing (also the final moves); or
a slide (one tip along the surface, `slide_trajectory`)."""

PATH_PHASES: tuple[PathPhase, ...] = get_args(PathPhase)


def _frozen(x: Any, ndim: int) -> NDArray[np.float64]:
    a = np.array(x, dtype=np.float64, copy=True)
    if a.ndim != ndim:
        raise ValueError(f"expected a {ndim}-D array, got shape {a.shape}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class StepPath:
    """The motion of one plan step, from the previous step's configuration to this step's.

    Knot 0 is the previous step (q, T_palm_object), the last knot this step. Equality compares every
    array bit for bit.
    """

    t: NDArray[np.float64]
    """(k,) time stamps, s from the start of the step; t[0] = 0, non-decreasing."""
    q: NDArray[np.float64]
    """(k, n) joint angles at the knots, rad, `hand.joint_names` order."""
    T_palm_object: NDArray[np.float64]
    """(k, 4, 4) object pose in the palm frame at the knots."""
    phases: tuple[str, ...]
    """(k − 1,) phase of each segment (between knot i and i + 1), one of `PATH_PHASES`."""
    ok: bool
    """True when the path passed the checks of the code that made it (see `detail` otherwise)."""
    detail: str
    """Why `ok` is False (e.g. an IK failure at a knot, a clearance below β), "" when it is True."""
    metrics: dict[str, float] = field(default_factory=dict)
    """Figures measured on the path by the code that made it (m, e.g. "min_clearance"); plain floats."""
    interpolation: str = INTERPOLATION
    """The rule between knots (`INTERPOLATION`; the only one)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", _frozen(self.t, 1))
        object.__setattr__(self, "q", _frozen(self.q, 2))
        object.__setattr__(self, "T_palm_object", _frozen(self.T_palm_object, 3))
        object.__setattr__(self, "phases", tuple(self.phases))
        object.__setattr__(self, "metrics", {str(k): float(v) for k, v in self.metrics.items()})
        k = len(self.t)
        shapes_ok = self.q.shape[0] == k and self.T_palm_object.shape == (k, 4, 4)
        if k < 2 or not shapes_ok or len(self.phases) != k - 1:
            raise ValueError(f"a path needs k ≥ 2 knots with t (k,), q (k, n), T_palm_object (k, 4, 4) and "
                             f"k − 1 phases; got t {self.t.shape}, q {self.q.shape}, T_palm_object "
                             f"{self.T_palm_object.shape}, {len(self.phases)} phases")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, StepPath):
            return NotImplemented
        return (
            np.array_equal(self.t, other.t)
            and np.array_equal(self.q, other.q)
            and np.array_equal(self.T_palm_object, other.T_palm_object)
            and self.phases == other.phases
            and self.ok == other.ok
            and self.detail == other.detail
            and self.metrics == other.metrics
            and self.interpolation == other.interpolation
        )

    __hash__ = None  # type: ignore[assignment]

    @property
    def duration(self) -> float:
        """Length of the motion, s (t[-1])."""
        return float(self.t[-1])


def time_stamps(q_knots: NDArray[np.float64], max_joint_speed: float = DEFAULT_MAX_JOINT_SPEED,
                min_duration: float = DEFAULT_MIN_STEP_DURATION) -> NDArray[np.float64]:
    """Time stamps (k,) of knots (k, n) so that no joint exceeds `max_joint_speed` (rad/s).

    Rule: the time between knots i and i + 1 is max_j |q[i+1, j] − q[i, j]| / max_joint_speed (with
    linear interpolation the fastest joint runs exactly at the limit); when the whole motion would be
    shorter than `min_duration` (s), every interval is stretched by the same factor (equal intervals for
    a motion that does not move). t[0] = 0.
    """
    q_knots = np.asarray(q_knots, dtype=float)
    if max_joint_speed <= 0:
        raise ValueError(f"max_joint_speed must be positive, got {max_joint_speed}")
    dt = np.max(np.abs(np.diff(q_knots, axis=0)), axis=1, initial=0.0) / max_joint_speed
    total = float(np.sum(dt))
    if len(dt) and total < min_duration:
        dt = dt * (min_duration / total) if total > 0 else np.full(len(dt), min_duration / len(dt))
    return np.concatenate([[0.0], np.cumsum(dt)])


def _slerp(R_a: NDArray, R_b: NDArray, s: NDArray) -> NDArray:
    """(N, 3, 3) rotations a fraction s (N,) along the geodesic from R_a (N, 3, 3) to R_b (N, 3, 3)."""
    from scipy.spatial.transform import Rotation

    r_a = Rotation.from_matrix(R_a)
    w = (r_a.inv() * Rotation.from_matrix(R_b)).as_rotvec()
    return (r_a * Rotation.from_rotvec(w * s[:, None])).as_matrix()


def interpolate_knots(t_knots: NDArray, q_knots: NDArray, T_knots: NDArray,
                      t: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The motion of knots at times `t` by the `INTERPOLATION` rule.

    Args:
        t_knots: (k,) non-decreasing knot times, s.
        q_knots: (k, n) joint angles, rad.
        T_knots: (k, 4, 4) object poses in the palm frame.
        t: (N,) query times, s (clamped to [t_knots[0], t_knots[-1]]).

    Returns:
        q (N, n) rad and T_palm_object (N, 4, 4).
    """
    t_knots, q_knots, T_knots = (np.asarray(a, dtype=float) for a in (t_knots, q_knots, T_knots))
    t = np.clip(np.asarray(t, dtype=float), t_knots[0], t_knots[-1])
    if len(t_knots) == 1:
        return np.repeat(q_knots, len(t), axis=0), np.repeat(T_knots, len(t), axis=0)
    i = np.clip(np.searchsorted(t_knots, t, side="right") - 1, 0, len(t_knots) - 2)
    span = t_knots[i + 1] - t_knots[i]
    s = np.divide(t - t_knots[i], span, out=np.ones_like(t), where=span > 0)
    q = q_knots[i] + s[:, None] * (q_knots[i + 1] - q_knots[i])
    T = np.zeros((len(t), 4, 4))
    T[:, 3, 3] = 1.0
    T[:, :3, 3] = T_knots[i, :3, 3] + s[:, None] * (T_knots[i + 1, :3, 3] - T_knots[i, :3, 3])
    R_a, R_b = T_knots[i, :3, :3], T_knots[i + 1, :3, :3]
    turning = (s > 0.0) & (s < 1.0) & np.any(R_a != R_b, axis=(1, 2))  # else exactly a knot's rotation
    T[:, :3, :3] = np.where((s >= 1.0)[:, None, None], R_b, R_a)
    if np.any(turning):
        T[turning, :3, :3] = _slerp(R_a[turning], R_b[turning], s[turning])
    return q, T


def sample_knots(t_knots: NDArray, q_knots: NDArray, T_knots: NDArray,
                 dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Sample knots every `dt` s, from t_knots[0] to t_knots[-1] (the end always included).

    Returns:
        t (N,) s, q (N, n) rad, T_palm_object (N, 4, 4), by `interpolate_knots`.
    """
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    t0, t1 = float(t_knots[0]), float(t_knots[-1])
    t = t0 + dt * np.arange(int(np.floor((t1 - t0) / dt + 1e-9)) + 1)
    if t1 - t[-1] > 1e-9 * max(1.0, t1):
        t = np.append(t, t1)
    q, T = interpolate_knots(t_knots, q_knots, T_knots, t)
    return t, q, T


def step_knots(prev: Any, step: Any, max_joint_speed: float = DEFAULT_MAX_JOINT_SPEED,
               min_step_duration: float = DEFAULT_MIN_STEP_DURATION
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The knots of one step's motion from the step before (`prev`): its path's, or, without a path, a
    straight line in joint space and object pose timed by `time_stamps` (rad/s, s).

    Returns:
        t (k,) s from the step's start, q (k, n) rad, T_palm_object (k, 4, 4).
    """
    if step.path is not None:
        return step.path.t, step.path.q, step.path.T_palm_object
    q = np.stack([np.asarray(prev.q, dtype=float), np.asarray(step.q, dtype=float)])
    T = np.stack([np.asarray(prev.T_palm_object, dtype=float), np.asarray(step.T_palm_object, dtype=float)])
    return time_stamps(q, max_joint_speed, min_step_duration), q, T


def join_step_motions(steps: Sequence[Any], max_joint_speed: float = DEFAULT_MAX_JOINT_SPEED,
                      min_step_duration: float = DEFAULT_MIN_STEP_DURATION
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], list[int]]:
    """The knots of a whole plan: every step's path one after the other.

    Args:
        steps: plan steps (anything with `q` (n,), `T_palm_object` (4, 4) and `path`, a `StepPath` or
            None); steps[0] is the start.
        max_joint_speed, min_step_duration: the `time_stamps` of a step without a path, which moves
            linearly from the previous step (rad/s, s).

    Returns:
        t (K,) s from steps[0], q (K, n) rad, T_palm_object (K, 4, 4), and the indices of the steps
        that had no path.
    """
    if not steps:
        raise ValueError("an empty plan has no motion")
    t_knots, q_knots = [np.zeros(1)], [np.asarray(steps[0].q, dtype=float)[None]]
    T_knots = [np.asarray(steps[0].T_palm_object, dtype=float)[None]]
    unpathed = [i for i in range(1, len(steps)) if steps[i].path is None]
    for i in range(1, len(steps)):
        t, q, T = step_knots(steps[i - 1], steps[i], max_joint_speed, min_step_duration)
        t_knots.append(t_knots[-1][-1] + t[1:])
        q_knots.append(q[1:])
        T_knots.append(T[1:])
    return np.concatenate(t_knots), np.concatenate(q_knots), np.concatenate(T_knots), unpathed
