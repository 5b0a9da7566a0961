"""Trajectories between the steps of a plan: the motion a robot executes (issue 15, items 2–4).

A plan's steps are static grasps. This module turns each pair of consecutive steps into a `StepPath`
(`regrasp_casadi.motion`): knots of joint angles and object pose, time stamps from a joint speed limit,
linear interpolation between knots (`motion.INTERPOLATION`). No NLP: numeric forward kinematics and tip
Jacobians of the `Hand`, damped least-squares IK within the joint limits, and the object's EXACT mesh
distance for the checks.

* **Gait** (one finger r moves, the object stays): lift-off of r's tip centre along its contact normal
  by `lift_height`, a transit linear in joint space between the lifted start and the lifted point above
  the new contact (through a via point raised above the object when a sample comes closer than β, or
  moved away from another finger it comes too close to), touch-down along the new contact's normal.
  Only r's joints change. The lift-off and touch-down come from IK on the tip (the touch-down is the
  lift from the new contact, reversed, so it ends exactly at the step); `gait_path` builds them on this
  module's IK and knots.
* **Reposing** (repose and final steps; the object moves with the hand): `repose_trajectory.repose_path`
  (the object pose interpolated from step A to step B, the tip centres held in the object frame, IK for
  all fingers; where the joints alone cannot follow, the object follows the hand).
* **Knots** are placed so that no point of the hand moves more than `max_point_step` between two knots:
  a sphere of radius ρ whose centre moves by Δc on a chain whose joints move by Δq moves no point more
  than ‖Δc‖ + ρ·Σ|Δq_j|. Segments over the bound are bisected with IK knots until joint-space
  interpolation stays within `max_interpolation_error` of the IK solution, then split into equal
  joint-space parts (exactly the interpolation rule; a transit is split so from the start).
* **Checks** at every knot (no point of the hand moves more than `max_point_step` between two, so a
  distance between two knots is within half of it of one of theirs): joint limits, the moving finger's
  spheres ≥ β from the object (a sphere closer than β at the transit's lifted ends, e.g. a lift held
  short by the joint limits, no worse than there) and ≥ `self_clearance` from the other fingers and the
  palm in a transit (`Hand.self_collision_pairs`; or no closer than at its lifted ends, never into
  them), not in the object nor in another finger during lift-off and touch-down (a lift is lowered to
  3/5 or 2/5, or leans 25°/40° away from the closest other finger at any of the three heights, when
  that keeps it clear of the others); in a reposing the tips within `surface_tol` of the surface, the
  contacts within `max_slip` of step A's, every non-tip sphere (palm included) outside the object, no
  two fingers overlapping. A failure (an IK that cannot reach a knot within the limits, a check) is
  reported in the path (`ok` False and `detail`), never hidden.

    >>> plan = attach_trajectories(plan, hand, obj)          # what plan_regrasp does at the end
    >>> t, q, T_palm_object = plan.sample(0.01)
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.constants import BETA, SELF_CLEARANCE
from regrasp_casadi.motion import DEFAULT_MAX_JOINT_SPEED, DEFAULT_MIN_STEP_DURATION, StepPath, time_stamps
from regrasp_casadi.tip_ik import joints_at_limits, tip_ik

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import Plan, PlanStep

__all__ = ["TrajectoryOptions", "motion_context", "step_path", "plan_trajectories",
           "attach_trajectories"]

_log = logging.getLogger(__name__)

_NEAR = 0.001
"""Margin beyond the threshold checked (β in a transit, 0 elsewhere) within which a clearance is exact,
m; farther, a lower bound is enough (bounding box, convex pieces) and the metrics report it."""

Curve = Callable[[float, "NDArray[np.float64] | None"], "tuple[NDArray[np.float64], str]"]
"""s ∈ [0, 1], warm-start q (or None) -> (q (n,), why): a phase of a path; `why` is "" on success."""


@dataclass(frozen=True)
class TrajectoryOptions:
    """Options of the trajectories (SI units)."""

    lift_height: float = 0.005
    """Lift-off and touch-down distance of a gait's tip centre along the contact normal, m."""
    beta: float = BETA
    """β, clearance of every sphere of the moving finger from the object during a transit, m."""
    self_clearance: float | None = SELF_CLEARANCE
    """Clearance of the moving finger's spheres from the other fingers' and the palm's during a transit
    (`Hand.self_collision_pairs`), m; elsewhere no sphere pair may overlap; None: not checked."""
    via_heights: tuple[float, ...] = (0.005, 0.01, 0.02, 0.04)
    """Heights above the lifted points' midpoint of the via points tried when a transit is too close, m."""
    max_point_step: float = 0.001
    """No point of the hand moves more than this between two knots, m."""
    max_joint_speed: float = DEFAULT_MAX_JOINT_SPEED
    """Largest joint speed of the time stamps, rad/s."""
    min_step_duration: float = DEFAULT_MIN_STEP_DURATION
    """Shortest duration of one step's motion, s."""
    surface_tol: float = 5e-4
    """Reposing: largest |exact distance − tip radius| of a tip centre, m."""
    max_slip: float = 1e-3
    """Reposing: largest distance of a contact from where it was on the object at the step before, m."""
    max_lift_angle: float = math.radians(45.0)
    """Lift-off and touch-down: largest angle between the contact normal and the tip centre's
    displacement from its contact, rad. The tip rises along the normal; where the joint limits keep it
    off that line, it leans as little as they allow, and at most this far (45°: it always moves away
    from the surface at least as fast as along it)."""
    ik_tol: float = 5e-4
    """Reposing: largest distance of a tip centre from where the object pose puts it at a knot, m; a
    knot the joint limits keep farther is reported (the largest distance is in the metrics)."""
    ik_max_iters: int = 40
    """IK: damped least-squares iterations per knot."""
    ik_damping: float = 1e-4
    """IK: damping λ of (J Jᵀ + λ² I), m."""
    max_interpolation_error: float = 1e-4
    """Between two IK knots the joint-space interpolation may leave the IK solution by this much (at
    their midpoint, any point of the hand), m; farther, the segment gets another IK knot."""
    max_refinements: int = 12
    """Rounds of knot insertion for the `max_point_step` bound."""


# -------------------------------------------------------------------------------------------- context
class _Context:
    """The hand, the object, the options and the hand's sphere table (built once per plan)."""

    def __init__(self, hand: Hand, obj: ObjectModel, options: TrajectoryOptions):
        self.hand, self.obj, self.options = hand, obj, options
        labels = hand.sphere_labels(None, include_tip=True)
        by_label = {s.label: s for s in hand.spheres}
        self.sphere_finger = [by_label[label].finger for label in labels]
        """Finger of every sphere of `sphere_centers(q, None, include_tip=True)` (None: palm)."""
        self.is_tip = np.array([by_label[label].is_tip for label in labels])
        self.radii = np.asarray(hand.sphere_radii(None, include_tip=True), dtype=float)
        self.chain = np.zeros((len(labels), hand.n_joints))
        """(S, n) 1 where a joint moves the sphere (the joints of its finger)."""
        for k, f in enumerate(self.sphere_finger):
            if f is not None:
                self.chain[k, hand.finger_joints[f]] = 1.0
        self.tip_index = {f: int(np.flatnonzero(self.is_tip & (np.array(self.sphere_finger, object) == f))[0])
                          for f in hand.fingers}
        self.finger_joints = np.unique(np.concatenate([hand.finger_joints[f] for f in hand.fingers]))
        self._centers: dict[bytes, NDArray[np.float64]] = {}
        self.box_lower, self.box_upper = (np.asarray(b, dtype=float) for b in obj.mesh.bounds)
        """The object mesh's bounding box, object frame, m."""
        self.self_pairs = {f: np.asarray(hand.self_collision_pairs(f), dtype=int).reshape(-1, 2)
                           for f in (None, *hand.fingers)} if options.self_clearance is not None else {}
        """finger (None: all) -> (P, 2) self-collision sphere pairs, indices in `centers`' order."""

    def finger_spheres(self, finger: str) -> NDArray[np.int64]:
        """Indices of the finger's spheres (tip included) in `centers`' second axis."""
        return np.flatnonzero(np.array(self.sphere_finger, dtype=object) == finger)

    def centers(self, Q: NDArray[np.float64]) -> NDArray[np.float64]:
        """(k, S, 3) sphere centres, palm frame, m, for knots Q (k, n) (remembered per q for this plan)."""
        out = []
        for q in Q:
            key = q.tobytes()
            c = self._centers.get(key)
            if c is None:
                c = self._centers[key] = self.hand.sphere_centers(q, None, include_tip=True)
            out.append(c)
        return np.stack(out)

    def segment_motion(self, Q: NDArray[np.float64]) -> NDArray[np.float64]:
        """(k − 1,) bound on how far any point of the hand moves between consecutive knots Q (k, n), m."""
        return self.pair_motion(Q[:-1], Q[1:])

    def clearance(self, Q: NDArray[np.float64], Ts: NDArray[np.float64], spheres: NDArray[np.int64],
                  threshold: float = 0.0) -> NDArray[np.float64]:
        """(k, len(spheres)) sd(centre) − radius of the chosen spheres at knots (Q, Ts), m: exact where
        it is below `threshold` + `_NEAR`, the convex pieces' lower bound above."""
        p_object = _to_object(Ts, self.centers(Q)[:, spheres]).reshape(-1, 3)
        r = np.tile(self.radii[spheres], len(Q))
        near = r + max(threshold, 0.0) + _NEAR
        d = np.linalg.norm(np.maximum(np.maximum(self.box_lower - p_object, p_object - self.box_upper), 0.0),
                           axis=1)  # distance to the mesh's bounding box: a lower bound
        close = d <= near
        if np.any(close):
            d[close] = self.obj.near_signed_distance(p_object[close], near[close])
        return (d - r).reshape(len(Q), len(spheres))

    def self_distance(self, Q: NDArray[np.float64], finger: str | None = None) -> NDArray[np.float64]:
        """(k,) smallest surface distance of the finger's (None: all) self-collision pairs at knots Q, m
        (inf when not checked)."""
        pairs = self.self_pairs.get(finger, np.zeros((0, 2), dtype=int))
        if not len(pairs):
            return np.full(len(Q), math.inf)
        C = self.centers(Q)
        gap = np.linalg.norm(C[:, pairs[:, 0]] - C[:, pairs[:, 1]], axis=2)
        return np.min(gap - self.radii[pairs[:, 0]] - self.radii[pairs[:, 1]], axis=1)

    def pair_motion(self, Q_a: NDArray[np.float64], Q_b: NDArray[np.float64]) -> NDArray[np.float64]:
        """(k,) bound on how far any point of the hand moves from Q_a[i] to Q_b[i] (k, n), m: per sphere
        ‖Δc‖ + ρ·Σ|Δq_j| over the joints that move it."""
        dc = np.linalg.norm(self.centers(Q_b) - self.centers(Q_a), axis=2)
        return np.max(dc + self.radii[None, :] * (np.abs(Q_b - Q_a) @ self.chain.T), axis=1)


def _to_object(Ts: NDArray, p_palm: NDArray) -> NDArray[np.float64]:
    """Points p_palm (k, s, 3), palm frame, in the object frame of the poses Ts (k, 4, 4): (k, s, 3)."""
    return np.einsum("kij,ksi->ksj", Ts[:, :3, :3], p_palm - Ts[:, None, :3, 3])


# ------------------------------------------------------------------------------------------------- IK
def _ik(ctx: _Context, q_start: NDArray, fingers: Sequence[str], p_palm_targets: NDArray, joints: NDArray,
        q_ref: NDArray, weight: NDArray | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """`tip_ik.tip_ik` with the options' damping and iteration limit."""
    o = ctx.options
    return tip_ik(ctx.hand, q_start, fingers, p_palm_targets, joints, q_ref, weight, damping=o.ik_damping,
                  max_iters=o.ik_max_iters)


def _held_joints(ctx: _Context, q: NDArray, joints: NDArray) -> str:
    """" (joints at their limits: a, b)" for the joints of `joints` at a limit at q, else ""."""
    held = joints_at_limits(ctx.hand, q, joints)
    return f" (joints at their limits: {', '.join(held)})" if held else ""


# ---------------------------------------------------------------------------------------------- knots
_JUMP_ROUNDS = 3
"""`_knots` takes a curve for a jump of the IK, and stops refining, when its largest gap between knots
after a round is above `_JUMP_SHRINK` of the largest gap this many rounds before: bisecting a continuous
curve halves its largest gap every round once the knots are dense enough (1/8 in three rounds), but not
always before: measured on the paper planner's reposing paths (soft-scrub_3 sd, mustard_2 svd, sugar-box_0
svd), a path that passed after 7 rounds had the gaps 3.46, 3.36, 2.83, 2.16, 1.51, 1.42, 1.16, 0.80 mm, all
at its end (its IK knots approach the step's end joints slowly); jumps stayed flat or grew (27.3, 25.3,
24.4, 24.0, 23.8, 23.7 mm ...; 4.6, 3.5, 3.3, 6.6 mm) or converged to a constant (... 1.75, 1.23, 1.25,
1.25 mm)."""
_JUMP_SHRINK = 0.95
"""See `_JUMP_ROUNDS`: the part of its largest gap a jump keeps over that many rounds."""


def _knots(ctx: _Context, curve: Curve, n_coarse: int, linear: bool = False
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], str]:
    """Knots of a curve from s = 0 to s = 1, dense enough for `max_point_step`.

    Solves the curve on `n_coarse` evenly spaced values of s, then, while a segment moves a point of the
    hand more than `max_point_step`: a segment not yet known to be straight gets a knot solved at its
    middle (warm started from the joint-space midpoint); when that knot is within
    `max_interpolation_error` of the midpoint, both halves are straight. A straight segment (every
    segment of a `linear` curve) is split into equal joint-space parts, which is exactly the
    interpolation rule, without solving. A knot the curve cannot solve keeps its best effort and is
    reported, and the refinement stops there (the path fails whatever its other knots).

    Returns:
        s (k,), knots (k, n), and why: "" or where the curve failed / that the bound was not reached.
    """
    o = ctx.options
    failures: list[str] = []

    def solve(s: float, warm: NDArray | None) -> NDArray:
        q, why = curve(s, warm)
        if why:
            failures.append(f"s = {s:.3f}: {why}")
        return q

    s_knots = list(np.linspace(0.0, 1.0, max(2, n_coarse)))
    Q: list[NDArray] = []
    for s in s_knots:
        Q.append(solve(s, Q[-1] if Q else None))
    straight = [linear] * (len(Q) - 1)
    motion = ctx.segment_motion(np.array(Q))
    largest: list[float] = []  # the largest gap between knots after each round (the coarse knots' not:
    # a first bisection may widen it, its midpoint warm started off the straight line)
    jump = False
    for _ in range(o.max_refinements):
        jump = len(largest) > _JUMP_ROUNDS and largest[-1] > _JUMP_SHRINK * largest[-1 - _JUMP_ROUNDS]
        if failures or np.all(motion <= o.max_point_step) or jump:
            break  # (a knot not reached, or a jump, fails the path: refining further changes no verdict)
        s_new, Q_new, straight_new = [s_knots[0]], [Q[0]], []
        bisected: list[tuple[int, NDArray, NDArray]] = []  # (segment index in straight_new, q_lin, q_mid)
        for i, m in enumerate(motion):
            s0, s1, q0, q1 = s_knots[i], s_knots[i + 1], Q[i], Q[i + 1]
            if m <= o.max_point_step:
                straight_new.append(straight[i])
            elif straight[i]:
                parts = int(math.ceil(m / o.max_point_step))
                s_new += [s0 + (s1 - s0) * j / parts for j in range(1, parts)]
                Q_new += [q0 + (q1 - q0) * j / parts for j in range(1, parts)]
                straight_new += [True] * parts
            else:
                q_lin = 0.5 * (q0 + q1)
                q_mid = solve(0.5 * (s0 + s1), q_lin)
                bisected.append((len(straight_new), q_lin, q_mid))
                s_new.append(0.5 * (s0 + s1))
                Q_new.append(q_mid)
                straight_new += [False, False]
            s_new.append(s1)
            Q_new.append(q1)
        if bisected:  # both halves are straight where the IK midpoint is close to the joint-space one
            gaps = ctx.pair_motion(np.array([b[1] for b in bisected]), np.array([b[2] for b in bisected]))
            for (k, _, _), gap in zip(bisected, gaps, strict=True):
                straight_new[k] = straight_new[k + 1] = bool(gap <= o.max_interpolation_error)
        s_knots, Q, straight = s_new, Q_new, straight_new
        motion = ctx.segment_motion(np.array(Q))
        largest.append(float(np.max(motion)))
    why = ""
    if failures:
        why = f"{len(failures)} knot{'s' if len(failures) > 1 else ''} not reached, first at {failures[0]}"
    elif np.max(motion) > o.max_point_step:
        jump_text = " (a jump: bisection no longer shrinks it)" if jump else ""
        why = (f"knots {np.max(motion) * 1e3:.2f} mm apart > {o.max_point_step * 1e3:.2f} mm after "
               f"{len(largest)} refinements{jump_text}")
    return np.array(s_knots), np.array(Q), why


def _linear(q_a: NDArray, q_b: NDArray) -> Curve:
    return lambda s, _warm: (q_a + s * (q_b - q_a), "")


def _timed(ctx: _Context, Q: NDArray, Ts: NDArray, phases: list[str], problems: list[str],
           metrics: dict[str, float]) -> StepPath:
    """The path of knots Q (k, n), Ts (k, 4, 4) with its time stamps (finite metrics only)."""
    o = ctx.options
    return StepPath(t=time_stamps(Q, o.max_joint_speed, o.min_step_duration), q=Q, T_palm_object=Ts,
                    phases=tuple(phases), ok=not problems, detail="; ".join(problems),
                    metrics={k: v for k, v in metrics.items() if math.isfinite(v)})


def _limit_problems(ctx: _Context, Q: NDArray) -> list[str]:
    """The first knot (k, n) outside the joint limits (by 1e-9), as a problem line."""
    out = (Q < ctx.hand.q_lower - 1e-9) | (Q > ctx.hand.q_upper + 1e-9)
    if not out.any():
        return []
    k, j = np.argwhere(out)[0]
    return [f"joint {ctx.hand.joint_names[j]} = {Q[k, j]:.4f} rad outside its limits at knot {k}"]


# --------------------------------------------------------------------------------------------- public
def motion_context(hand: Hand, obj: ObjectModel, options: TrajectoryOptions | None = None) -> _Context:
    """The context the paths of one plan share (its IK, knots, checks and their caches), for `step_path`;
    `options` default: `TrajectoryOptions()`."""
    return _Context(hand, obj, options or TrajectoryOptions())


def step_path(ctx: _Context, a: PlanStep, b: PlanStep) -> StepPath | None:
    """The path of step b from step a: lift-off / transit / touch-down for a gait, on the surface for a
    slide (`slide_trajectory.slide_path`), the reposing path for a repose or final move
    (`repose_trajectory.repose_path`); None for any other step."""
    from regrasp_casadi.gait_path import gait_path  # they build on this module's IK and knots
    from regrasp_casadi.repose_trajectory import repose_path
    from regrasp_casadi.slide_trajectory import slide_path

    if b.kind in ("gait", "slide") and b.finger in ctx.hand.fingers:
        return gait_path(ctx, a, b) if b.kind == "gait" else slide_path(ctx, a, b)
    return repose_path(ctx, a, b) if b.kind in ("repose", "final") else None


def plan_trajectories(plan_steps: Sequence[PlanStep], hand: Hand, obj: ObjectModel,
                      options: TrajectoryOptions | None = None) -> list[StepPath | None]:
    """The path of every step from the step before (None for the initial step and unknown kinds).

    Gait steps get a lift-off / transit / touch-down path, repose and final steps a reposing path (see
    the module docstring), slide steps a path on the surface (`slide_trajectory.slide_path`); a step
    that carries its path already keeps it. A path whose checks fail has `ok` False and says why in
    `detail`.

    Args:
        plan_steps: the steps of a plan, in order (`Plan.steps`).
        hand, obj: the models the plan was made with.
        options: `TrajectoryOptions` (default: issue 15's values).
    """
    ctx = motion_context(hand, obj, options)
    paths: list[StepPath | None] = [None]
    for a, b in zip(plan_steps[:-1], plan_steps[1:], strict=True):
        # a path computed already (the planner's checked moves, `_Run.unrealisable`) is kept
        paths.append(b.path if b.path is not None else step_path(ctx, a, b))
    flagged = [i for i, p in enumerate(paths) if p is not None and not p.ok]
    if flagged:
        _log.info("%d of %d paths failed their checks (steps %s)", len(flagged), len(paths) - 1, flagged)
    return paths[: len(plan_steps)]


def attach_trajectories(plan: Plan, hand: Hand, obj: ObjectModel,
                        options: TrajectoryOptions | None = None) -> Plan:
    """`plan` with every step's `path` (`plan_trajectories`), the options used in
    `plan.options["trajectory"]` and the time spent in `plan.timing["trajectories"]` (added to "total")."""
    options = options or TrajectoryOptions()
    t0 = time.perf_counter()
    paths = plan_trajectories(plan.steps, hand, obj, options)
    elapsed = time.perf_counter() - t0
    steps = tuple(step if path is None else replace(step, path=path)
                  for step, path in zip(plan.steps, paths, strict=True))
    timing = {**plan.timing, "trajectories": elapsed, "total": plan.timing.get("total", 0.0) + elapsed}
    recorded = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(options).items()}
    return replace(plan, steps=steps, timing=timing, options={**plan.options, "trajectory": recorded})
