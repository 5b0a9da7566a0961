"""Trajectories between the steps of a plan: the motion a robot executes (issue 15, items 2–4).

A plan's steps are static grasps. This module turns each pair of consecutive steps into a `StepPath`
(`regrasp_casadi.motion`): knots of joint angles and object pose, time stamps from a joint speed limit,
linear interpolation between knots (`motion.INTERPOLATION`). No NLP: numeric forward kinematics and tip
Jacobians of the `Hand`, damped least-squares IK within the joint limits, and the object's EXACT mesh
distance for the checks.

* **Gait** (one finger r moves, the object stays): lift-off of r's tip centre along its contact normal
  by `lift_height`, a transit linear in joint space between the lifted start and the lifted point above
  the new contact (through a via point raised above the object when a sample comes closer than β),
  touch-down along the new contact's normal. Only r's joints change. The lift-off and touch-down come
  from IK on the tip (the touch-down is the lift from the new contact, reversed, so it ends exactly at
  the step).
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
from regrasp_casadi.transforms import inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import Plan, PlanStep

__all__ = ["TrajectoryOptions", "motion_context", "step_path", "lift_problem", "plan_trajectories",
           "attach_trajectories"]

_log = logging.getLogger(__name__)

_RISE_TOL = 0.1
"""A lift knot may fall short of its height along the normal by this fraction (joint limits)."""

_SIDEWAYS_WEIGHT = 0.1
"""Weight of the sideways error of a lift-off against its rise along the normal (IK)."""

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


# ----------------------------------------------------------------------------------------------- gait
def _contact_normal_palm(ctx: _Context, step: PlanStep, finger: str) -> NDArray[np.float64]:
    """(3,) `_normal_palm` at the finger's contact of `step` (the exact closest point the step stores)."""
    contact = np.asarray(step.contacts_object, dtype=float)[ctx.hand.fingers.index(finger)]
    return _normal_palm(ctx, step.q, step.T_palm_object, contact, finger)


def _normal_palm(ctx: _Context, q: NDArray, T_palm_object: NDArray, contact_object: NDArray | None,
                 finger: str) -> NDArray[np.float64]:
    """(3,) unit outward normal, palm frame, at the finger's contact `contact_object` (3,), object frame,
    m (None: the exact closest point of its tip centre), hand at q (n,) rad: from the contact to the tip
    centre, the direction in which the tip's distance grows fastest (the face normal on a face)."""
    r = ctx.hand.fingers.index(finger)
    T = np.asarray(T_palm_object, dtype=float)
    p_object = transform_points(inv_T(T), ctx.hand.tip_positions(q)[[r]])
    if contact_object is None:
        contact_object = ctx.obj.closest_points(p_object)[0][0]
    n = p_object[0] - contact_object
    if np.linalg.norm(n) < 1e-9:  # a point tip on the surface
        n = np.asarray(ctx.obj.surface_normals(p_object), dtype=float)[0]
    return T[:3, :3] @ (n / np.linalg.norm(n))


def _clear_lift(ctx: _Context, q0: NDArray, finger: str, n_palm: NDArray) -> tuple[NDArray[np.float64], str]:
    """`_lift` by `lift_height`, else lower (3/5, 2/5 of it), else leaning 25°, 40° away from the closest
    other finger (full, 3/5, 2/5 height), when the lift brings the finger closer to another than
    `self_clearance` (and than at q0); if every one does, the one that keeps it farthest from the others
    among those whose tip rises at least β along n_palm (a thumb touch-down on bottle_regrasp cleared the
    palm by 0.33 mm only leaning 40° at 2/5 height; a middle lift-off held at its joint limits must not
    trade its rise for clearance from the others)."""
    o = ctx.options
    floor = min(o.self_clearance or 0.0, float(ctx.self_distance(q0[None], finger)[0])) - 1e-9
    best: tuple[tuple, NDArray[np.float64], str] | None = None
    tries = [(n_palm, f) for f in (1.0, 0.6, 0.4)]
    pairs = ctx.self_pairs.get(finger, np.zeros((0, 2), dtype=int))
    if len(pairs):  # away from the closest sphere of another finger (or the palm), in the tangent plane
        C, r = ctx.centers(q0[None])[0], ctx.radii
        a, b = pairs[int(np.argmin(np.linalg.norm(C[pairs[:, 0]] - C[pairs[:, 1]], axis=1)
                                   - r[pairs[:, 0]] - r[pairs[:, 1]]))]
        v = (C[a] - C[b]) * (1.0 if ctx.sphere_finger[a] == finger else -1.0)
        u = v - (v @ n_palm) * n_palm
        leans = [n_palm + math.tan(math.radians(deg)) * u / max(np.linalg.norm(u), 1e-12) for deg in (25, 40)]
        tries += [(d / np.linalg.norm(d), f) for d in leans for f in (1.0, 0.6, 0.4)]
    r_tip = ctx.hand.fingers.index(finger)
    for direction, fraction in tries:
        knots, why = _lift(ctx, q0, finger, direction, fraction * o.lift_height)
        gap = float(np.min(ctx.self_distance(knots, finger)))
        rise = float((ctx.hand.tip_positions(knots[-1])[r_tip] - ctx.hand.tip_positions(q0)[r_tip]) @ n_palm)
        # off the surface by the transit's β first, clear of the others, then within the lean limit
        key = (rise >= o.beta, gap >= floor, not why, gap)
        if all(key[:3]):
            return knots, why
        best = best if best is not None and best[0] >= key else (key, knots, why)
    assert best is not None
    return best[1], best[2]


def _lift(ctx: _Context, q0: NDArray, finger: str, n_palm: NDArray,
          h: float) -> tuple[NDArray[np.float64], str]:
    """Knots (k, n) lifting the finger's tip centre from where it is at q0 by h (m) along n_palm."""
    hand = ctx.hand
    p0 = hand.tip_positions(q0)[hand.fingers.index(finger)]
    joints = hand.finger_joints[finger]
    along = np.outer(n_palm, n_palm)
    weight = along + _SIDEWAYS_WEIGHT * (np.eye(3) - along)  # rise first, then stay on the line

    def reach(s: float, start: NDArray) -> tuple[NDArray, bool]:
        q, e = _ik(ctx, start, [finger], (p0 + s * h * n_palm)[None], joints, q0, weight)
        return q, abs(float(e[0] @ n_palm)) <= _RISE_TOL * s * h and _lift_angle(
            e[0], s * h, n_palm) <= ctx.options.max_lift_angle

    def curve(s: float, warm: NDArray | None) -> tuple[NDArray, str]:
        if s == 0.0:
            return q0, ""
        q, ok = reach(s, q0 if warm is None else warm)
        if not ok:  # march up the line from the contact: limits can stop one long IK step
            q = q0
            for u in (0.25, 0.5, 0.75, 1.0):
                q, ok = reach(u * s, q)
        if ok:
            return q, ""
        e = p0 + s * h * n_palm - hand.tip_positions(q)[hand.fingers.index(finger)]
        short, angle = abs(float(e @ n_palm)), _lift_angle(e, s * h, n_palm)
        return q, (f"the tip is {short * 1e3:.3f} mm short of its height, {np.degrees(angle):.1f}° off the "
                   f"normal{_held_joints(ctx, q, joints)}")

    _, Q, why = _knots(ctx, curve, 2)
    return Q, why


def _lift_angle(e: NDArray, rise: float, n: NDArray) -> float:
    """Angle (rad) between the contact normal n and a lifted tip's displacement, from its error e (3,) to
    the point `rise` m up the normal."""
    sideways = float(np.linalg.norm(e - (e @ n) * n))
    return math.atan2(sideways, max(rise - float(e @ n), 1e-12))


def _max_lean(ctx: _Context, knots: NDArray, finger: str, n: NDArray) -> float:
    """Largest angle (rad) between n and the finger's tip displacement from knots[0] at knots[1:]."""
    r = ctx.hand.fingers.index(finger)
    d = np.array([ctx.hand.tip_positions(q)[r] for q in knots[1:]]) - ctx.hand.tip_positions(knots[0])[r]
    along = d @ n
    sideways = np.linalg.norm(d - along[:, None] * n[None], axis=1)
    return float(np.max(np.arctan2(sideways, np.maximum(along, 1e-12)), initial=0.0))


def _transit(ctx: _Context, q_a: NDArray, q_b: NDArray, finger: str, n_mid: NDArray, T: NDArray,
             also: NDArray) -> tuple[NDArray[np.float64], float, float, str, NDArray[np.float64]]:
    """Transit knots (k, n) from q_a to q_b, linear in joint space, directly or through one via point
    raised by `via_heights` along n_mid (palm frame); the first whose finger spheres keep ≥ β from the
    object and ≥ `self_clearance` from the other fingers, else the one with the largest margin. What is
    closer at the lifted end q_a or q_b (a lift held short by the joint limits or the other fingers, a
    link near the object in the grasp) keeps no worse than there, as OPT1 and `_clear_lift` do: per
    sphere for the object (flat tool, index touch-down 0.70 mm off it), the finger's least distance to
    the others, never below 0 (bowl seed 9 SD: an index lifted 0.47 mm from the middle); else both
    gaits were refused at every iteration. The clearance of the finger's spheres at the knots `also`
    (j, n) comes with the first attempt's query. Returns (knots, min clearance m, min distance to the
    other fingers m, why, clearance of `also` (j, spheres) m)."""
    hand, o = ctx.hand, ctx.options
    spheres = ctx.finger_spheres(finger)
    r = hand.fingers.index(finger)
    p_mid = 0.5 * (hand.tip_positions(q_a)[r] + hand.tip_positions(q_b)[r])
    q_mid = 0.5 * (q_a + q_b)
    best: tuple | None = None
    clear_also = np.zeros((0, len(spheres)))
    for attempt, height in enumerate((None, *o.via_heights)):
        waypoints = [q_a, q_b]
        if height is not None:
            via, _ = _ik(ctx, q_mid, [finger], (p_mid + height * n_mid)[None], hand.finger_joints[finger],
                         q_mid)  # as high as the joint limits allow: the clearances judge it
            waypoints = [q_a, via, q_b]
        legs = [_knots(ctx, _linear(a, b), 2, linear=True)[1:]
                for a, b in zip(waypoints, waypoints[1:], strict=False)]
        Q = np.concatenate([legs[0][0]] + [leg[0][1:] for leg in legs[1:]])
        first = attempt == 0
        Q_all = np.concatenate([Q, also]) if first else Q
        clear_all = ctx.clearance(Q_all, np.repeat(T[None], len(Q_all), axis=0), spheres, o.beta)
        if first:
            clear_also = clear_all[len(Q):]
        gaps = ctx.self_distance(Q, finger)
        clear, self_clear = float(np.min(clear_all[: len(Q)])), float(np.min(gaps))
        if first:  # per sphere: β, or no worse than at the lifted ends where it is closer there
            floor = np.minimum(o.beta, np.min(clear_all[[0, len(Q) - 1]], axis=0)) - 1e-9
            self_floor = min(max(min(gaps[0], gaps[-1]), 0.0), o.self_clearance or 0.0) - 1e-9
        why = "; ".join(w for _, w in legs if w)
        dip, self_dip = float(np.min(clear_all[: len(Q)] - floor)), self_clear - self_floor  # < 0: below
        margin = min(dip, self_dip)
        if best is None or margin > best[1]:
            best = (Q, margin, why, clear, self_clear, dip, self_dip)
        if margin >= 0.0:
            break
    assert best is not None
    Q, margin, why, clear, self_clear, dip, self_dip = best
    if dip < 0.0:
        why += (f"; transit clearance {clear * 1e3:.3f} mm < β = {o.beta * 1e3:.3f} mm (or a sphere "
                f"{-dip * 1e3:.3f} mm closer than at the transit's ends, where it is closer than β)")
    if self_dip < 0.0:
        why += (f"; transit {self_clear * 1e3:.3f} mm from another finger < {o.self_clearance * 1e3:.3f} mm "
                f"(or {-self_dip * 1e3:.3f} mm closer than at the transit's ends, where it is closer)")
    return Q, clear, self_clear, why.strip("; "), clear_also


def _gait_path(ctx: _Context, a: PlanStep, b: PlanStep) -> StepPath:
    """The path of gait step b from step a: lift-off, transit, touch-down of finger `b.finger`.

    Metrics (m; angles rad): "lift_height" (tip-centre rise of the lift-off), "max_lift_angle" (lean of
    the lift-off and touch-down from their normals), "min_transit_clearance" (every sphere of the finger
    in the transit), "min_clearance" (its non-tip spheres during lift-off and touch-down),
    "min_tip_clearance" (its tip then: ≥ −surface_tol), "max_point_step".
    """
    hand, o, finger = ctx.hand, ctx.options, str(b.finger)
    T = np.asarray(b.T_palm_object, dtype=float)
    n_a, n_b = _contact_normal_palm(ctx, a, finger), _contact_normal_palm(ctx, b, finger)
    lift, why_a = _clear_lift(ctx, np.asarray(a.q, dtype=float), finger, n_a)
    down, why_b = _clear_lift(ctx, np.asarray(b.q, dtype=float), finger, n_b)
    problems = [f"lift-off {w}" for w in [why_a] if w] + [f"touch-down {w}" for w in [why_b] if w]
    n_mid = n_a + n_b
    n_mid = n_mid / np.linalg.norm(n_mid) if np.linalg.norm(n_mid) > 0.3 else n_a
    # the finger's spheres at the lift-off and touch-down knots: with the transit's first query
    transit, min_transit, self_transit, why_t, clear = _transit(ctx, lift[-1], down[-1], finger, n_mid, T,
                                                                np.concatenate([lift, down]))
    problems += [why_t] if why_t else []
    Q = np.concatenate([lift, transit[1:], down[::-1][1:]])
    phases = ["lift"] * (len(lift) - 1) + ["transit"] * (len(transit) - 1) + ["touch_down"] * (len(down) - 1)
    mine = ctx.finger_spheres(finger)
    tip_col = int(np.flatnonzero(mine == ctx.tip_index[finger])[0])
    non_tip = np.delete(clear, tip_col, axis=1)
    min_clear = float(np.min(non_tip)) if non_tip.size else math.inf
    min_tip = float(np.min(clear[:, tip_col]))
    if min_clear < 0.0:
        problems.append(f"a sphere of the {finger} finger is {-min_clear * 1e3:.3f} mm inside the object")
    if min_tip < -o.surface_tol:
        problems.append(f"the {finger} tip sinks {-min_tip * 1e3:.3f} mm into the object")
    min_self = float(np.min(ctx.self_distance(np.concatenate([lift, down]), finger)))
    if min_self < 0.0:
        problems.append(f"the {finger} finger overlaps another by {-min_self * 1e3:.3f} mm")
    problems += _limit_problems(ctx, Q)
    r = hand.fingers.index(finger)
    rise = float(np.dot(hand.tip_positions(lift[-1])[r] - hand.tip_positions(lift[0])[r], n_a))
    lean = max(_max_lean(ctx, lift, finger, n_a), _max_lean(ctx, down, finger, n_b))
    metrics = {"lift_height": rise, "max_lift_angle": lean, "min_transit_clearance": min_transit,
               "min_clearance": min_clear, "min_tip_clearance": min_tip, "min_self_clearance": min_self,
               "min_transit_self_clearance": self_transit,
               "max_point_step": float(np.max(ctx.segment_motion(Q)))}
    return _timed(ctx, Q, np.repeat(T[None], len(Q), axis=0), phases, problems, metrics)


# --------------------------------------------------------------------------------------------- public
def motion_context(hand: Hand, obj: ObjectModel, options: TrajectoryOptions | None = None) -> _Context:
    """The context the paths of one plan share (its IK, knots, checks and their caches), for `step_path`;
    `options` default: `TrajectoryOptions()`."""
    return _Context(hand, obj, options or TrajectoryOptions())


def step_path(ctx: _Context, a: PlanStep, b: PlanStep) -> StepPath | None:
    """The path of step b from step a: lift-off / transit / touch-down for a gait, on the surface for a
    slide (`slide_trajectory.slide_path`), the reposing path for a repose or final move
    (`repose_trajectory.repose_path`); None for any other step."""
    from regrasp_casadi.repose_trajectory import repose_path  # they build on this module's IK and knots
    from regrasp_casadi.slide_trajectory import slide_path

    if b.kind in ("gait", "slide") and b.finger in ctx.hand.fingers:
        return _gait_path(ctx, a, b) if b.kind == "gait" else slide_path(ctx, a, b)
    return repose_path(ctx, a, b) if b.kind in ("repose", "final") else None


def lift_problem(ctx: _Context, q: NDArray, T_palm_object: NDArray, finger: str) -> str:
    """Why `finger` could not lift off its contact of the grasp (q (n,) rad, `T_palm_object` (4, 4)) the
    way a gait's path does (`_clear_lift`: `lift_height` along the contact normal, lower or leaning, within
    the joint limits and `max_lift_angle`), nor so touch down on it; "" when it can."""
    n_palm = _normal_palm(ctx, q, T_palm_object, None, finger)
    return _clear_lift(ctx, np.asarray(q, dtype=float), finger, n_palm)[1]


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
