"""The replay's keyframes of a plan: the scene at instants of the replay (every link pose, the object pose
and the current contacts, palm frame). Pure numpy; the viewer (`viewer`) turns them into Meshcat tracks.

Two timings, chosen by the plan:

* **The plan's motion** (a plan whose steps carry their paths, `PlanStep.path`, a `motion.StepPath`:
  the planner's default): the keyframes play the motion exactly as `Plan.sample` evaluates it (the
  knots, their time stamps and `motion.INTERPOLATION`; a step without a path moves linearly in joint
  space, timed by `motion.time_stamps`, as `Plan.sample` does), so a gait lifts the finger off along
  the contact normal, transits and touches down. Step i's motion, d_i s of plan time, plays in
  D_i = max(d_i / speed, min_step_seconds) s of replay time, uniformly scaled (`speed` 1: the plan's
  own time stamps, 1 s of replay = 1 s of motion at the plan's joint speed limit; a short step stays
  on screen for `min_step_seconds`). The keyframes of a step are knots of its path: every phase change
  (lift-off / transit / touch-down) and the step itself, and in between as few knots as keep every
  point of the hand (the surfaces of its collision spheres) and of the object's bounding box within
  `max_move` of motion from one keyframe to the next; a segment between two knots that moves farther is
  split into equal-time samples. Current contacts ride on their fingertips: the contact of finger r
  at a keyframe of step i is the tip centre plus the tip-centre-to-contact offset (object frame, from
  step i−1's to step i's, linearly in the step's progress α) turned with the object, so it is exactly
  the plan's contact at each step and follows the tip as it slides or the object turns. The finger of
  a gait is not in contact from its lift-off until its touch-down: its marker is hidden at the
  keyframes of those phases inside the step (`Keyframe.contacts_visible`) and shows again at the new
  contact when the step is reached.
* **Interpolated steps** (no step has a path: schema-1 plan files, `plan_regrasp(..., trajectories=
  False)`): between step i−1 (time (i−1)·Δ) and step i (time i·Δ, Δ = `seconds_per_step`) joints move
  linearly with a smoothstep easing, the object translation linearly and its rotation by slerp, the
  contacts linearly in the object frame.

Both give one keyframe exactly at each step (`alpha` 1, the step's own q, object pose and contacts), at
`step_times(plan, ...)`.

    >>> frames = plan_keyframes(plan, hand, obj, speed=1.0)
    >>> times = step_times(plan, speed=1.0)       # (len(plan.steps),) s, the overlay's step times
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from regrasp_casadi.motion import interpolate_knots, step_knots
from regrasp_casadi.problem import plan_models

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import Plan

__all__ = ["Keyframe", "plan_keyframes", "step_times", "has_motion", "DEFAULT_SPEED", "MIN_STEP_SECONDS",
           "MAX_KEYFRAME_MOVE", "OFF_SURFACE_PHASES"]

DEFAULT_SPEED = 1.0
"""Replay seconds per plan second are 1 / speed: 1 plays the plan's motion at its own time stamps (the
shipped plans: 9–20 s of motion at 1 rad/s, 22–68 steps; with `MIN_STEP_SECONDS`, 15–30 s of replay)."""

MIN_STEP_SECONDS = 0.3
"""Shortest replay duration of one step, s (a 50 ms slide stays visible)."""

MAX_KEYFRAME_MOVE = 0.002
"""Largest motion of any point of the hand or the object between two consecutive keyframes, m."""

OFF_SURFACE_PHASES = ("lift", "transit", "touch_down")
"""Phases during which a gait's finger is not in contact (its contact marker is hidden)."""


@dataclass(frozen=True)
class Keyframe:
    """The scene at one instant of the replay (palm frame).

    Attributes:
        time: time since the start of the replay, s.
        step: index of the plan step being moved into (the segment from step i-1 to step i belongs to
            step i); at a step time, exactly that step.
        alpha: progress from step `step - 1` to step `step`, in [0, 1] (1 at the step itself; 1 for step
            0): the fraction of the step's replay time (interpolated steps) or of its motion's plan time.
        kind: `plan.steps[step].kind` ("initial" | "gait" | "repose" | "final" | "slide").
        finger: `plan.steps[step].finger` (the finger moved by a gait or slide, else None).
        q: (n,) joint angles, rad.
        T_palm_link: link name -> (4, 4) pose of the link in the palm frame, for every link of the hand.
        T_palm_object: (4, 4) object pose in the palm frame.
        p_palm_contacts: (m, 3) current contact points in the palm frame, m, rows in `plan.fingers` order.
        plan_time: time of this instant in the plan's motion (`Plan.sample`'s t), s; None for
            interpolated steps.
        phase: the path phase being played (`motion.PATH_PHASES`; at a knot, the segment ending there);
            None for interpolated steps, step 0 and steps without a path.
        contacts_visible: (m,) whether each current-contact marker shows (False: the finger is off the
            surface); None: all show.
    """

    time: float
    step: int
    alpha: float
    kind: str
    finger: str | None
    q: NDArray
    T_palm_link: dict[str, NDArray]
    T_palm_object: NDArray
    p_palm_contacts: NDArray
    plan_time: float | None = None
    phase: str | None = None
    contacts_visible: tuple[bool, ...] | None = None


def has_motion(plan: Plan) -> bool:
    """True when a step after the first carries its path (the replay plays the plan's motion)."""
    return any(s.path is not None for s in plan.steps[1:])


def _smoothstep(u: float) -> float:
    """3u² − 2u³: eases in and out, equals u at 0, 0.5 and 1."""
    return u * u * (3.0 - 2.0 * u)


def _step_motion(plan: Plan, i: int) -> tuple[NDArray, NDArray, NDArray, tuple[str | None, ...]]:
    """Knots of step i's motion (i ≥ 1) as `Plan.sample` plays them (`motion.step_knots`): t (k,) s from
    the step's start, q (k, n), T (k, 4, 4) and the phase of each segment (None without a path)."""
    step = plan.steps[i]
    t, q, T = step_knots(plan.steps[i - 1], step)
    return t, q, T, tuple(step.path.phases) if step.path is not None else (None,)


def _replay_durations(plan_durations: NDArray, speed: float, min_step_seconds: float) -> NDArray:
    return np.maximum(np.asarray(plan_durations, float) / speed, min_step_seconds)


def step_times(plan: Plan, seconds_per_step: float = 0.8, speed: float = DEFAULT_SPEED,
               min_step_seconds: float = MIN_STEP_SECONDS) -> NDArray:
    """Replay time at which each step is reached, s, shape (len(plan.steps),); step 0 at 0.

    With the plan's motion (`has_motion`): the running sum of D_i = max(d_i / speed, min_step_seconds)
    over the steps' motion durations d_i (s). Interpolated steps: `i * seconds_per_step`.
    """
    if speed <= 0 or min_step_seconds < 0 or seconds_per_step <= 0:
        raise ValueError(f"speed and seconds_per_step must be positive and min_step_seconds ≥ 0, got "
                         f"{speed}, {seconds_per_step} and {min_step_seconds}")
    if not has_motion(plan):
        return np.arange(len(plan.steps), dtype=float) * float(seconds_per_step)
    d = [float(_step_motion(plan, i)[0][-1]) for i in range(1, len(plan.steps))]
    return np.concatenate([[0.0], np.cumsum(_replay_durations(np.array(d), speed, min_step_seconds))])


def plan_keyframes(
    plan: Plan,
    hand: Hand | None = None,
    obj: ObjectModel | None = None,
    fps: float = 30,
    seconds_per_step: float = 0.8,
    easing: bool = True,
    *,
    speed: float = DEFAULT_SPEED,
    min_step_seconds: float = MIN_STEP_SECONDS,
    max_move: float = MAX_KEYFRAME_MOVE,
) -> list[Keyframe]:
    """Keyframes of the replay of `plan` in time order, with one keyframe exactly at each step.

    A plan with paths plays its motion (module docstring); the others interpolate the steps: between
    step i-1 and step i there are `k = max(1, round(fps·Δ))` frames at `u = j/k`, j = 1..k; with
    `s = smoothstep(u)` (or `s = u` without easing): `q(s) = q_{i-1} + s (q_i - q_{i-1})`; object
    translation `t_{i-1} + s (t_i - t_{i-1})`, rotation `slerp(R_{i-1}, R_i, s)`; contacts
    `T_palm_object(s) · (c_{i-1} + s (c_i - c_{i-1}))` with `c` in the object frame. Links come from
    `hand.fk(q)`.

    Args:
        plan: the plan to replay.
        hand, obj: the plan's hand and object (default: rebuilt from the plan, `problem.plan_models`).
        fps: frames per second of interpolated steps (> 0; unused with the plan's motion).
        seconds_per_step: replay duration of one interpolated step, s (> 0).
        easing: smoothstep easing between interpolated steps (True) or constant speed (False).
        speed: plan seconds played per replay second (> 0), with the plan's motion.
        min_step_seconds: shortest replay duration of a step with the plan's motion, s (≥ 0).
        max_move: largest motion of a hand or object point between keyframes of the plan's motion, m.

    Raises:
        ValueError: empty plan or a non-positive fps / seconds_per_step / speed / max_move.
    """
    if not plan.steps:
        raise ValueError("plan has no steps")
    if fps <= 0 or seconds_per_step <= 0 or max_move <= 0:
        raise ValueError(f"fps, seconds_per_step and max_move must be positive, got {fps}, "
                         f"{seconds_per_step} and {max_move}")
    times = step_times(plan, seconds_per_step, speed, min_step_seconds)
    hand, obj = plan_models(plan, hand, obj)
    if has_motion(plan):
        return _motion_keyframes(plan, hand, obj, times, max_move)
    return _step_keyframes(plan, hand, times, max(1, int(round(fps * seconds_per_step))), easing)


# ------------------------------------------------------------------------------------- interpolated steps
def _step_keyframes(plan: Plan, hand: Hand, times: NDArray, k: int, easing: bool) -> list[Keyframe]:
    """Interpolated steps (`plan_keyframes`): k frames per step, at `times` (s) the steps."""

    def frame(i: int, u: float) -> Keyframe:
        step = plan.steps[i]
        s = (_smoothstep(u) if easing else u) if i > 0 else 1.0
        if i == 0 or u >= 1.0:
            q = np.asarray(step.q, dtype=float)
            T_po = np.asarray(step.T_palm_object, dtype=float)
            c_obj = np.asarray(step.contacts_object, dtype=float)
            t = float(times[i])
        else:
            prev = plan.steps[i - 1]
            q0, q1 = np.asarray(prev.q, float), np.asarray(step.q, float)
            q = q0 + s * (q1 - q0)   # exact where a joint does not move
            T0 = np.asarray(prev.T_palm_object, float)
            T1 = np.asarray(step.T_palm_object, float)
            if np.array_equal(T0, T1):
                T_po = T0.copy()
            else:
                slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([T0[:3, :3], T1[:3, :3]])))
                T_po = np.eye(4)
                T_po[:3, :3] = slerp([s]).as_matrix()[0]
                T_po[:3, 3] = T0[:3, 3] + s * (T1[:3, 3] - T0[:3, 3])
            c0 = np.asarray(prev.contacts_object, float)
            c_obj = c0 + s * (np.asarray(step.contacts_object, float) - c0)
            t = float(times[i - 1] + u * (times[i] - times[i - 1]))
        p_palm = c_obj @ T_po[:3, :3].T + T_po[:3, 3]
        T_links = {name: np.asarray(T, dtype=float) for name, T in hand.fk(q).items()}
        return Keyframe(
            time=t, step=i, alpha=float(u) if i > 0 else 1.0, kind=step.kind, finger=step.finger, q=q,
            T_palm_link=T_links, T_palm_object=T_po, p_palm_contacts=p_palm,
        )

    frames = [frame(0, 1.0)]
    for i in range(1, len(plan.steps)):
        frames.extend(frame(i, j / k) for j in range(1, k + 1))
    return frames


# ----------------------------------------------------------------------------------------- plan's motion
class _Scene:
    """What the keyframes of the plan's motion need of the hand and the object."""

    def __init__(self, plan: Plan, hand: Hand, obj: ObjectModel) -> None:
        self.hand = hand
        self.tip_rows = [hand.fingers.index(str(f)) for f in plan.fingers]
        units = np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])          # (7, 3)
        self.links = sorted({s.link for s in hand.spheres})
        self.points = {ln: np.concatenate([s.center_link + s.radius * units for s in hand.spheres
                                           if s.link == ln]) for ln in self.links}
        lo, hi = np.asarray(obj.mesh.bounds, dtype=float)
        self.corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                 for z in (lo[2], hi[2])])
        # offset from the tip centre to the contact, object frame, at every step: (S, m, 3)
        self.offsets = np.stack([self._offset(s) for s in plan.steps])

    def _offset(self, step) -> NDArray:
        T = np.asarray(step.T_palm_object, float)
        tips = self.hand.tip_positions(step.q)[self.tip_rows]
        return np.asarray(step.contacts_object, float) - (tips - T[:3, 3]) @ T[:3, :3]

    def points_at(self, q: NDArray, T: NDArray) -> NDArray:
        """(P, 3) points of the hand's collision spheres (centre and ±radius along the link axes) and
        of the object's bounding box, palm frame, m."""
        fk = self.hand.fk(q)
        hand_pts = [self.points[ln] @ fk[ln][:3, :3].T + fk[ln][:3, 3] for ln in self.links]
        return np.concatenate([*hand_pts, self.corners @ T[:3, :3].T + T[:3, 3]])


def _keyframe_times(scene: _Scene, t: NDArray, q: NDArray, T: NDArray, phases: tuple[str | None, ...],
                    max_move: float) -> NDArray:
    """Plan times (s from the step's start, t[0] excluded, t[-1] included) of the keyframes of one step.

    Kept: the end of every phase and of the step, and knots so that the motion of every point between
    consecutive keyframes (summed over the knot intervals, the largest displacement of any point per
    interval) stays within `max_move`; an interval that alone moves farther is split into equal times.
    """
    pts = np.stack([scene.points_at(q[k], T[k]) for k in range(len(t))])
    moves = np.max(np.linalg.norm(np.diff(pts, axis=0), axis=2), axis=1)   # (k-1,) m
    keep: list[float] = []
    acc = 0.0
    for k, move in enumerate(moves):
        if acc > 0.0 and acc + move > max_move:
            keep.append(float(t[k]))
            acc = 0.0
        n = max(1, math.ceil(move / max_move - 1e-9))
        keep.extend(float(t[k] + (t[k + 1] - t[k]) * j / n) for j in range(1, n))
        acc += move / n
        if k == len(moves) - 1 or phases[k] != phases[k + 1]:
            keep.append(float(t[k + 1]))
            acc = 0.0
    return np.unique(np.array(keep))


def _motion_keyframes(plan: Plan, hand: Hand, obj: ObjectModel, times: NDArray,
                      max_move: float) -> list[Keyframe]:
    """The plan's motion (`plan_keyframes`); `times` (S,) replay times of the steps, s."""
    scene = _Scene(plan, hand, obj)
    frames = [_motion_frame(scene, plan, 0, 1.0, tau=0.0, plan_time=0.0, q=None, T=None, phase=None)]
    plan_start = 0.0
    for i in range(1, len(plan.steps)):
        t, q, T, phases = _step_motion(plan, i)
        d = float(t[-1])
        ts = _keyframe_times(scene, t, q, T, phases, max_move)
        qs, Ts = interpolate_knots(t, q, T, ts)
        seg = np.clip(np.searchsorted(t, ts, side="left") - 1, 0, len(t) - 2)   # at a knot: the one ending
        for j, tj in enumerate(ts):
            alpha = float(tj / d) if d > 0 and tj < t[-1] else 1.0
            tau = float(times[i - 1] + alpha * (times[i] - times[i - 1]))
            frames.append(_motion_frame(scene, plan, i, alpha, tau=tau, plan_time=plan_start + float(tj),
                                        q=qs[j], T=Ts[j], phase=phases[seg[j]]))
        plan_start += d
    return frames


def _motion_frame(scene: _Scene, plan: Plan, i: int, alpha: float, *, tau: float, plan_time: float,
                  q: NDArray | None, T: NDArray | None, phase: str | None) -> Keyframe:
    """Keyframe of step i at progress alpha (1: the step itself, its own q, pose and contacts)."""
    step = plan.steps[i]
    if alpha >= 1.0:
        q, T = np.asarray(step.q, dtype=float), np.asarray(step.T_palm_object, dtype=float)
        p = np.asarray(step.contacts_object, float) @ T[:3, :3].T + T[:3, 3]
    else:
        offset = (1.0 - alpha) * scene.offsets[i - 1] + alpha * scene.offsets[i]
        p = scene.hand.tip_positions(q)[scene.tip_rows] + offset @ T[:3, :3].T
    visible = tuple(not (0.0 < alpha < 1.0 and step.kind == "gait" and str(f) == step.finger
                         and phase in OFF_SURFACE_PHASES) for f in plan.fingers)
    T_links = {name: np.asarray(M, dtype=float) for name, M in scene.hand.fk(q).items()}
    return Keyframe(time=tau, step=i, alpha=alpha, kind=step.kind, finger=step.finger, q=np.array(q),
                    T_palm_link=T_links, T_palm_object=np.array(T), p_palm_contacts=p, plan_time=plan_time,
                    phase=phase if i > 0 else None, contacts_visible=visible)
