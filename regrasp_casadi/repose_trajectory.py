"""The path of a reposing (or final) step: the object moves with the hand, the contacts stay (issue 15).

`trajectory.plan_trajectories` calls `repose_path` for every step of kind "repose" or "final", as it
calls its gait paths and `slide_trajectory.slide_path` for the other kinds; the path is a
`motion.StepPath` whose segments all have the phase "repose".

Knots, s ∈ [0, 1]: the object pose T(s) is interpolated from step A's to step B's (translation linear,
rotation geodesic: `transforms.interpolate_pose`); the tip centres, object frame, go where the tips
roll to as the knot's joints turn them (`_rolling_tips`: A's centres + ρ θ × n + s × the slide OPT2 left
between A and B) and are mapped by T(s); the joints come from `rolling_ik.rolling_tip_ik` for all
fingers (damped least squares on the rolling-contact Jacobian, the targets moving with the joints,
within the joint limits, warm started from the neighbouring knot, pulled towards the joint-space
interpolation of A and B). It replaced (issue 12) a tip-centre IK whose targets were moved twice to
where the last solution rolled them: at a finger stretched to the edge of its reach (tip-centre Jacobian
of rank 2) that picked another branch of the solutions from knot to knot.

**The object follows the hand.** Where that IK leaves a tip more than `FOLLOW_TOL` from its target (a
finger held at two joint limits keeps only two free joints and cannot follow an arbitrary pose path:
on cylinder_slide the middle tip sank 0.53–0.69 mm into the cylinder that way), the knot is solved again
with the object's pose as an unknown too (`tip_ik.tip_object_ik`): the tips reach their places on the
object exactly and the pose leaves T(s) as little as it must. Knots that `trajectory`'s refinement
puts between two solved knots (equal joint-space parts) get the pose interpolated between theirs, which
is what the interpolation rule (`motion.INTERPOLATION`) plays.

Checks (the path's `ok` and `detail`), at every knot and at the midpoint of every segment (where the
interpolation is farthest from the solved knots): the tips within `surface_tol` of the surface (exact
distance − tip radius), the tips' material sliding at most `max_slip` over the object along the path
(`grasp_metrics.path_tip_slip`: a tip may roll); at the knots: every non-tip sphere
(palm included) outside the object, no two fingers overlapping, the joints within their limits.
Metrics (m): "max_surface_error", "max_slip", "max_ik_error" (the tips from their targets at the
knots), "max_pose_correction" (how far the object's following moved a tip's target, palm frame),
"min_clearance", "min_self_clearance", "max_point_step".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.grasp_metrics import path_tip_slip, rolling_displacement, tip_frames
from regrasp_casadi.rolling_ik import Rolling, rolling_tip_ik
from regrasp_casadi.stability import contact_normals
from regrasp_casadi.tip_ik import tip_object_ik
from regrasp_casadi.transforms import interpolate_pose, inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.motion import StepPath
    from regrasp_casadi.plan import PlanStep
    from regrasp_casadi.trajectory import _Context

__all__ = ["repose_path", "FOLLOW_TOL"]

COARSE_SPACING = 0.016
"""A reposing's first IK knots: one per this much motion of the hand's points, m (then bisection)."""

FOLLOW_TOL = 1e-5
"""A knot whose tips the joints alone leave farther than this from their targets (m) is solved with the
object's pose free (`tip_ik.tip_object_ik`)."""


def repose_path(ctx: _Context, a: PlanStep, b: PlanStep) -> StepPath:
    """The path of reposing (or final) step b from step a (see the module docstring)."""
    from regrasp_casadi.trajectory import _held_joints, _knots, _limit_problems, _timed

    hand, o = ctx.hand, ctx.options
    q_a, q_b = np.asarray(a.q, dtype=float), np.asarray(b.q, dtype=float)
    T_a, T_b = np.asarray(a.T_palm_object, dtype=float), np.asarray(b.T_palm_object, dtype=float)
    tips_a = transform_points(inv_T(T_a), hand.tip_positions(q_a))
    tips_b = transform_points(inv_T(T_b), hand.tip_positions(q_b))
    rolling_at = _rolling_tips(ctx, (q_a, T_a, tips_a), (q_b, T_b, tips_b))
    fingers = list(hand.fingers)
    ik_error = [0.0]  # the largest tip error of the IK knots, m
    poses: dict[float, NDArray] = {0.0: T_a, 1.0: T_b}  # s -> the pose of every solved knot

    def curve(s: float, warm: NDArray | None) -> tuple[NDArray, str]:
        if s in (0.0, 1.0):
            return (q_a if s == 0.0 else q_b), ""
        T_s, roll = interpolate_pose(T_a, T_b, s), rolling_at(s)
        q_lin = (1.0 - s) * q_a + s * q_b
        q, e = rolling_tip_ik(hand, q_lin if warm is None else warm, T_s, roll, ctx.finger_joints, q_lin,
                              damping=o.ik_damping, max_iters=o.ik_max_iters)
        T = T_s
        if float(np.max(np.linalg.norm(e, axis=1))) > FOLLOW_TOL:  # the object follows the hand
            held = roll.targets(tip_frames(hand, q, T_s)[1])[0]
            q, T, e = tip_object_ik(hand, q, T_s, fingers, held, ctx.finger_joints, q_ref=q_lin, T_ref=T_s,
                                    damping=o.ik_damping, max_iters=o.ik_max_iters)
        poses[s] = T
        err = float(np.max(np.linalg.norm(e, axis=1)))
        ik_error[0] = max(ik_error[0], err)
        if err <= o.ik_tol:
            return q, ""
        return q, f"a tip is {err * 1e3:.4f} mm from its target{_held_joints(ctx, q, ctx.finger_joints)}"

    chord = float(ctx.segment_motion(np.stack([q_a, q_b]))[0])
    s_knots, Q, why = _knots(ctx, curve, int(math.ceil(chord / COARSE_SPACING)) + 1)
    Ts = _knot_poses(s_knots, poses)
    held = [rolling_at(float(s)).targets(tip_frames(hand, q, T)[1])[0]
            for s, q, T in zip(s_knots, Q, Ts, strict=True)]
    correction = max(float(np.max(np.linalg.norm(
        transform_points(T, c) - transform_points(interpolate_pose(T_a, T_b, float(s)), c), axis=1)))
        for s, T, c in zip(s_knots, Ts, held, strict=True))
    metrics = {"max_ik_error": ik_error[0], "max_pose_correction": correction,
               **_repose_metrics(ctx, Q, Ts)}
    problems = [f"IK: {why}"] if why else []
    if metrics["max_surface_error"] > o.surface_tol:
        problems.append(f"a tip is {metrics['max_surface_error'] * 1e3:.3f} mm off the surface "
                        f"(> {o.surface_tol * 1e3:.2f} mm)")
    if metrics["max_slip"] > o.max_slip:
        problems.append(f"a tip slides {metrics['max_slip'] * 1e3:.3f} mm over the object "
                        f"(> {o.max_slip * 1e3:.2f} mm)")
    if metrics["min_clearance"] < 0.0:
        problems.append(f"a non-tip sphere is {-metrics['min_clearance'] * 1e3:.3f} mm inside the object")
    if metrics["min_self_clearance"] < 0.0:
        problems.append(f"two fingers overlap by {-metrics['min_self_clearance'] * 1e3:.3f} mm")
    problems += _limit_problems(ctx, Q)
    return _timed(ctx, Q, Ts, ["repose"] * (len(Q) - 1), problems, metrics)


def _rolling_tips(ctx: _Context, a: tuple, b: tuple) -> Callable[[float], Rolling]:
    """rolling_at(s) -> the `rolling_ik.Rolling` of knot s of a reposing from a = (q_a, T_a, tips_a) to b
    (joints, pose, tip centres in the object frame): each tip at tips_a + ρ θ × n, θ its turn since a
    (rolling, `grasp_metrics.rolling_displacement`; n between a's normal and the one interpolated towards
    b's) + s × the slide that OPT2 left between a and b (spread evenly), so that the path's tips roll as
    its ends do."""
    (q_a, T_a, tips_a), (q_b, T_b, tips_b) = a, b
    hand, rho = ctx.hand, ctx.hand.tip_radius
    R_a, R_b = tip_frames(hand, q_a, T_a)[1], tip_frames(hand, q_b, T_b)[1]
    n_a, n_b = (contact_normals(np.asarray(ctx.obj.closest_points(t)[0], float), t) for t in (tips_a, tips_b))
    left = (tips_b - tips_a) - rolling_displacement(R_a, R_b, n_a + n_b, rho)

    def rolling_at(s: float) -> Rolling:
        n_s = (1.0 - s) * n_a + s * n_b
        n_s /= np.linalg.norm(n_s, axis=1, keepdims=True)
        n = n_a + n_s
        return Rolling(tips_a, R_a, n / np.linalg.norm(n, axis=1, keepdims=True), s * left, rho)

    return rolling_at


def _knot_poses(s_knots: NDArray, poses: dict[float, NDArray]) -> NDArray[np.float64]:
    """(k, 4, 4) object pose at every knot: the solved knots' own, the others' interpolated (geodesic)
    between the nearest solved knots before and after (their joints are equal parts between those)."""
    solved = np.array(sorted(poses))
    out = []
    for s in np.asarray(s_knots, dtype=float):
        if s in poses:
            out.append(poses[float(s)])
            continue
        j = int(np.searchsorted(solved, s))
        s0, s1 = solved[j - 1], solved[j]
        out.append(interpolate_pose(poses[float(s0)], poses[float(s1)], (s - s0) / (s1 - s0)))
    return np.stack(out)


def _repose_metrics(ctx: _Context, Q: NDArray, Ts: NDArray) -> dict[str, float]:
    """"max_surface_error" and "max_slip" (the tips' material sliding over the object, accumulated along
    the path: `grasp_metrics.path_tip_slip`) of the tips at the knots Q (k, n), Ts (k, 4, 4) and the
    segments' midpoints; "min_clearance" (non-tip spheres),
    "min_self_clearance" and "max_point_step" at the knots; m."""
    from regrasp_casadi.trajectory import _to_object

    mid_T = [interpolate_pose(T0, T1, 0.5) for T0, T1 in zip(Ts[:-1], Ts[1:], strict=True)]
    k = len(Q)  # path order: knot 0, midpoint 0, knot 1, ..., knot k-1
    Q_all = np.empty((2 * k - 1, Q.shape[1]))
    Q_all[0::2], Q_all[1::2] = Q, 0.5 * (Q[:-1] + Q[1:])
    T_all = np.empty((2 * k - 1, 4, 4))
    T_all[0::2], T_all[1::2] = Ts, np.reshape(mid_T, (-1, 4, 4))
    tips = np.array([ctx.tip_index[f] for f in ctx.hand.fingers])
    p_object = _to_object(T_all, ctx.centers(Q_all)[:, tips])
    closest, sd = ctx.obj.closest_points(p_object.reshape(-1, 3))
    surface = np.abs(np.reshape(sd, (len(Q_all), -1)) - ctx.radii[tips][None])
    closest = np.reshape(closest, (len(Q_all), -1, 3))
    normals = np.stack([contact_normals(c, p) for c, p in zip(closest, p_object, strict=True)])
    R_object_tips = np.stack([tip_frames(ctx.hand, q, T)[1] for q, T in zip(Q_all, T_all, strict=True)])
    slip = path_tip_slip(p_object, R_object_tips, normals, ctx.hand.tip_radius)
    others = np.flatnonzero(~ctx.is_tip)
    clear = ctx.clearance(Q, Ts, others) if others.size else np.full((1, 1), math.inf)
    return {"max_surface_error": float(np.max(surface)), "max_slip": float(np.max(slip)),
            "min_clearance": float(np.min(clear)), "min_self_clearance": float(np.min(ctx.self_distance(Q))),
            "max_point_step": float(np.max(ctx.segment_motion(Q)))}
