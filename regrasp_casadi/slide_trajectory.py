"""The path of a slide step: one finger's tip moves along the object's surface, the rest of the hand and
the object still (the paper's assumption 5; the planner's "slide" steps, `certified_round`).

`trajectory.plan_trajectories` calls `slide_path` for every step of kind "slide", as it calls its own
gait and reposing paths for the other kinds; the path is a `motion.StepPath` whose segments all have the
phase "slide", timed and interpolated like every other path (`Plan.sample`, export and replay follow it).

Knots: the tip-sphere centre c(s), s ∈ [0, 1], goes from its place at step A to its place at step B
over the offset surface: the straight line (1 − s)·c_A + s·c_B in the object frame, projected on the
surface (its exact closest point p(s) and outward normal n(s)) and lifted by the tip radius,
c(s) = p(s) + r_tip·n(s); the finger's joints come from the IK of `trajectory` (damped least squares
within the joint limits, pulled towards the joint-space interpolation of A and B), and `trajectory`'s
knot refinement keeps no point of the hand moving more than `max_point_step` between two knots.

Checks (the path's `ok` and `detail`): the tip centre's exact distance minus its radius within
`surface_tol` at every knot and at the midpoint of every segment, the finger's other spheres outside
the object, the joints within their limits. Metrics (m): "max_surface_error", "max_ik_error",
"min_clearance" (the finger's non-tip spheres), "slide_length" (tip travel along the knots),
"max_point_step".
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.transforms import inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.motion import StepPath
    from regrasp_casadi.plan import PlanStep
    from regrasp_casadi.trajectory import _Context

__all__ = ["slide_path", "surface_tip_targets"]

_COARSE_SPACING = 0.002
"""The first IK knots of a slide: one per this much tip travel, m (then `trajectory`'s refinement)."""


def surface_tip_targets(obj, tip_a: NDArray, tip_b: NDArray, s: NDArray, tip_radius: float
                        ) -> NDArray[np.float64]:
    """Tip-sphere centres (len(s), 3), object frame, m, on the offset surface along a slide: the points
    (1 − s)·tip_a + s·tip_b (tip_a, tip_b (3,), object frame) projected on the object's surface (exact
    closest point p and outward normal n) and lifted by `tip_radius`: p + tip_radius·n."""
    s = np.asarray(s, dtype=float).reshape(-1, 1)
    line = (1.0 - s) * np.asarray(tip_a, float)[None] + s * np.asarray(tip_b, float)[None]
    closest, sd = obj.closest_points(line)
    away = (line - closest) * np.sign(np.where(sd == 0, 1.0, sd))[:, None]
    n = away / np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-12)
    return np.asarray(closest, dtype=float) + float(tip_radius) * n


def slide_path(ctx: _Context, a: PlanStep, b: PlanStep) -> StepPath:
    """The path of slide step b from step a (finger `b.finger`; see the module docstring)."""
    from regrasp_casadi.trajectory import _held_joints, _ik, _knots, _limit_problems, _timed, _to_object

    hand, o, finger = ctx.hand, ctx.options, str(b.finger)
    r = hand.fingers.index(finger)
    joints = np.asarray(hand.finger_joints[finger])
    q_a, q_b = np.asarray(a.q, dtype=float), np.asarray(b.q, dtype=float)
    T = np.asarray(b.T_palm_object, dtype=float)
    tip_a, tip_b = (transform_points(inv_T(T), hand.tip_positions(q)[[r]])[0] for q in (q_a, q_b))
    ik_error = [0.0]

    def curve(s: float, warm: NDArray | None) -> tuple[NDArray, str]:
        if s in (0.0, 1.0):
            return (q_a if s == 0.0 else q_b), ""
        target = transform_points(T, surface_tip_targets(ctx.obj, tip_a, tip_b, [s], hand.tip_radius))
        q_lin = (1.0 - s) * q_a + s * q_b
        q, e = _ik(ctx, q_lin if warm is None else warm, [finger], target, joints, q_lin)
        err = float(np.linalg.norm(e[0]))
        ik_error[0] = max(ik_error[0], err)
        if err <= o.ik_tol:
            return q, ""
        return q, f"the tip is {err * 1e3:.4f} mm from the surface point{_held_joints(ctx, q, joints)}"

    travel = float(np.linalg.norm(tip_b - tip_a))
    _, Q, why = _knots(ctx, curve, int(math.ceil(travel / _COARSE_SPACING)) + 1)
    problems = [f"IK: {why}"] if why else []
    Ts = np.repeat(T[None], len(Q), axis=0)
    samples = np.concatenate([Q, 0.5 * (Q[:-1] + Q[1:])])  # the knots and every segment's midpoint
    tips = _to_object(np.repeat(T[None], len(samples), axis=0),
                      ctx.centers(samples)[:, [ctx.tip_index[finger]]]).reshape(-1, 3)
    _, sd = ctx.obj.closest_points(tips)
    mine = [k for k in ctx.finger_spheres(finger) if k != ctx.tip_index[finger]]
    clear = ctx.clearance(Q, Ts, np.asarray(mine, dtype=np.int64)) if mine else np.full((1, 1), math.inf)
    knot_tips = np.array([hand.tip_positions(q)[r] for q in Q])
    metrics = {"max_surface_error": float(np.max(np.abs(np.asarray(sd, float) - hand.tip_radius))),
               "max_ik_error": ik_error[0], "min_clearance": float(np.min(clear)),
               "slide_length": float(np.sum(np.linalg.norm(np.diff(knot_tips, axis=0), axis=1))),
               "max_point_step": float(np.max(ctx.segment_motion(Q)))}
    if metrics["max_surface_error"] > o.surface_tol:
        problems.append(f"the {finger} tip is {metrics['max_surface_error'] * 1e3:.3f} mm off the surface "
                        f"(> {o.surface_tol * 1e3:.2f} mm)")
    if metrics["min_clearance"] < 0.0:
        problems.append(f"a sphere of the {finger} finger is {-metrics['min_clearance'] * 1e3:.3f} mm inside "
                        f"the object")
    problems += _limit_problems(ctx, Q)
    return _timed(ctx, Q, Ts, ["slide"] * (len(Q) - 1), problems, metrics)
