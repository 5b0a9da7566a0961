"""verify's checks of the whole motion (issue 15, item 5): rows of `verify.CHECK_TABLE` that sample every
step's path and judge every sample with exact geometry and verify's own tolerances.

**Sampling.** Every step after the first is followed from the step before: by its `path`
(`motion.StepPath`, knots joined by `motion.INTERPOLATION`) when it has one, else by the straight line in
joint space and object pose between the two steps (what `Plan.sample` replays for such a step). Any step
kind with a path is sampled the same way (gaits, reposings, final moves, and any later kind). Each
segment between two knots a, b is cut into equal parts in the interpolation parameter s, as many as

    n = ceil((max_f L_f · Σ_{j ∈ f} |Δq_j|  +  ‖Δp‖ + θ · R) / max_point_step)

* L_f, the longest lever arm of finger f: over the finger's collision spheres, the sum of the (rigid,
  constant) distances between consecutive link origins from the finger's first moving joint down to the
  sphere's link, plus the distance of the sphere centre from its link origin, plus its radius. A
  revolute joint turning by Δq moves a point at distance ≤ L from its axis by ≤ L·|Δq|, so no point of
  the sphere cover (which encloses the links) moves more than L_f · Σ|Δq_j| in the palm frame.
* ‖Δp‖ + θ·R: how far the object's frame moves a hand point relative to the object (p the object
  origin in the palm frame, θ the rotation angle between the two knots, R the largest distance of a
  sphere's surface from p at either knot).

So no point of the hand moves more than `MAX_POINT_STEP` (1 mm), relative to the palm or to the object,
between two samples; the knots themselves are samples. Sphere centres are computed for all samples
at once (the hand's CasADi sphere function mapped over the samples).

**Checks** at every sample of step k's motion (one finding per step and link / finger / joint, at its
worst sample, naming the step, the time into the step's path and from the plan's start, the phase, the
links and fingers):

* ``motion_penetration``: every non-tip collision sphere (palm included) keeps an exact distance −
  radius ≥ ``min_clearance`` from the object (the exact mesh distance wherever the mesh's bounding box,
  the convex pieces' estimate or a nearby sample cannot show it is 0.5 mm above the threshold), and
  no fingertip sphere sinks more than ``surface_tol`` into it;
* ``motion_self_collision``: every self-collision sphere pair (`Hand.self_collision_pairs()`, none
  pruned) keeps ≥ ``self_clearance`` (off with ``self_clearance=None``); the spheres enclose the link
  meshes, so clear spheres mean clear meshes (the link meshes are checked at the steps by
  ``self_collision_mesh``);
* ``motion_joint_limit``: every joint within its limits ± ``limit_tol``;
* ``motion_held_contact``: the holding fingertips (every finger but a gait's or another single-finger
  step's `finger`) stay on the surface: |exact distance − tip radius| ≤ ``surface_tol``;
* ``motion_slip``: the material of each holding tip slides at most ``max_slip`` over the object, summed
  over the samples from the start of the step's motion (a tip may roll: `grasp_metrics.path_tip_slip`);
  a finger that slides on purpose (a step's `finger` other than in a gait) is on the surface but not
  held in place.

Metrics (in `VerifyReport.metrics`): "motion_samples", "motion_max_point_step" (the largest bound above
between two samples, m), "motion_min_clearance", "motion_min_self_clearance", "motion_max_surface_error",
"motion_max_slip" (m) and "motion_seconds" (time of the sampling and geometry).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.plan import PlanStep
    from regrasp_casadi.verify import Finding, VerifyContext

__all__ = [
    "MAX_POINT_STEP",
    "MotionSamples",
    "lever_arms",
    "sample_plan_motion",
    "check_motion_penetration",
    "check_motion_self_collision",
    "check_motion_joint_limits",
    "check_motion_held_contacts",
    "check_motion_slip",
]

MAX_POINT_STEP = 1e-3
"""Largest motion of any point of the hand between two samples, relative to the palm and the object, m."""

NEAR = 0.5e-3
"""Sphere clearances are exact within this of the threshold (m); farther, a lower bound."""

_CHUNK = 256
"""Samples per evaluation of the mapped sphere-centre function."""

_STRIDE = 8
"""Coarse samples: every this many of a step's samples (and its last), for the Lipschitz bounds."""


# ---------------------------------------------------------------------------------------------- sampling
@dataclass(frozen=True)
class MotionSamples:
    """The sampled motion of a plan (N samples; S = `len(hand.spheres)`)."""

    step: NDArray[np.int64]
    """(N,) index of the plan step whose motion each sample belongs to (≥ 1)."""
    t_step: NDArray[np.float64]
    """(N,) time from the start of that step's motion, s."""
    t_plan: NDArray[np.float64]
    """(N,) time from the start of the plan, s."""
    phase: tuple[str, ...]
    """(N,) phase of the path segment ("lift", "transit", "touch_down", "repose", ...; "linear" for a
    step without a path)."""
    q: NDArray[np.float64]
    """(N, n) joint angles, rad."""
    T_palm_object: NDArray[np.float64]
    """(N, 4, 4) object pose in the palm frame."""
    max_point_step: float
    """Largest bound on the motion of a hand point between two consecutive samples, m."""


def lever_arms(hand: Hand) -> dict[str, float]:
    """Finger -> its longest lever arm L_f (m): over its spheres, the chain of rigid link-origin distances
    from the finger's first moving joint to the sphere's link, + the centre's offset + the radius."""
    fk = hand.fk(hand.q_mid())
    palm_body = hand.rigid_body(hand.root_link)
    out = {f: 0.0 for f in hand.fingers}
    for s in hand.spheres:
        if s.finger is None:
            continue
        reach, link = float(np.linalg.norm(s.center_link)) + float(s.radius), s.link
        while True:
            parent = hand.parent_link(link)
            if parent is None or hand.rigid_body(parent) == palm_body:
                break  # `link` hangs on the palm: its origin is the first joint's axis point
            reach += float(np.linalg.norm(fk[link][:3, 3] - fk[parent][:3, 3]))
            link = parent
        out[s.finger] = max(out[s.finger], reach)
    return out


_MAPPED: dict[int, tuple] = {}
"""id(sphere function) -> (function, its map over `_CHUNK` samples, evaluation buffer, input, output)."""


def sphere_centres(hand: Hand, Q: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, S, 3) centres of every collision sphere (`hand.spheres` order), palm frame, m, at Q (N, n): the
    hand's sphere function mapped over `_CHUNK` samples, evaluated through a preallocated buffer."""
    fn = hand.sphere_centers_function(None, include_tip=True)
    S = len(hand.spheres)
    entry = _MAPPED.get(id(fn))
    if entry is None or entry[0] is not fn:
        mapped = fn.map(_CHUNK)
        q_buf = np.zeros((_CHUNK, hand.n_joints))  # column-major (n, CHUNK): row i is sample i
        out_buf = np.zeros((_CHUNK * S, 3))  # column-major (3, S·CHUNK)
        buf, evaluate = mapped.buffer()
        buf.set_arg(0, memoryview(q_buf))
        buf.set_res(0, memoryview(out_buf))
        entry = _MAPPED[id(fn)] = (fn, mapped, buf, evaluate, q_buf, out_buf)
    _, _, _, evaluate, q_buf, out_buf = entry
    out = np.zeros((len(Q), S, 3))
    for start in range(0, len(Q), _CHUNK):
        block = np.asarray(Q[start:start + _CHUNK], dtype=float)
        q_buf[: len(block)] = block
        q_buf[len(block):] = block[-1]
        evaluate()
        out[start:start + len(block)] = out_buf.reshape(_CHUNK, S, 3)[: len(block)]
    return out


def _rotation_angles(R_a: NDArray, R_b: NDArray) -> NDArray[np.float64]:
    """(k,) angles (rad) of R_aᵀ R_b for (k, 3, 3) stacks."""
    c = (np.einsum("kji,kji->k", R_a, R_b) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def _segment_bounds(hand: Hand, levers: NDArray, finger_cols: NDArray, q: NDArray,
                    T: NDArray) -> NDArray[np.float64]:
    """(k − 1,) bound on the motion of a hand point, relative to palm and object, over each segment of
    knots q (k, n), T (k, 4, 4) (module docstring)."""
    dq = np.abs(np.diff(q, axis=0)) @ finger_cols  # (k − 1, fingers) Σ|Δq| per finger
    hand_bound = np.max(dq * levers[None], axis=1, initial=0.0)
    p = T[:, :3, 3]
    C = sphere_centres(hand, q)
    radii = np.array([s.radius for s in hand.spheres])
    reach = np.max(np.linalg.norm(C - p[:, None], axis=2) + radii[None], axis=1)  # (k,)
    theta = _rotation_angles(T[:-1, :3, :3], T[1:, :3, :3])
    return hand_bound + np.linalg.norm(np.diff(p, axis=0), axis=1) + theta * np.maximum(reach[:-1], reach[1:])


def _interpolate(q: NDArray, T: NDArray, seg: NDArray, s: NDArray) -> tuple[NDArray, NDArray]:
    """Joints (N, n) and poses (N, 4, 4) a fraction s (N,) along segments seg (N,) of knots q, T, by
    `motion.INTERPOLATION` (q and translation linear, rotation geodesic)."""
    from scipy.spatial.transform import Rotation

    qs = q[seg] + s[:, None] * (q[seg + 1] - q[seg])
    Ts = np.zeros((len(s), 4, 4))
    Ts[:, 3, 3] = 1.0
    Ts[:, :3, 3] = T[seg, :3, 3] + s[:, None] * (T[seg + 1, :3, 3] - T[seg, :3, 3])
    R_a, R_b = T[seg, :3, :3], T[seg + 1, :3, :3]
    Ts[:, :3, :3] = np.where((s >= 1.0)[:, None, None], R_b, R_a)
    turning = (s > 0.0) & (s < 1.0) & np.any(R_a != R_b, axis=(1, 2))  # else exactly a knot's rotation
    if np.any(turning):
        r_a = Rotation.from_matrix(R_a[turning])
        w = (r_a.inv() * Rotation.from_matrix(R_b[turning])).as_rotvec()
        Ts[turning, :3, :3] = (r_a * Rotation.from_rotvec(w * s[turning, None])).as_matrix()
    return qs, Ts


def _step_knots(prev: PlanStep, step: PlanStep) -> tuple[NDArray, NDArray, NDArray, tuple[str, ...]]:
    """(t (k,), q (k, n), T (k, 4, 4), phases (k − 1,)) of a step's motion from the step before."""
    from regrasp_casadi.motion import time_stamps

    path = getattr(step, "path", None)
    if path is not None:
        return np.asarray(path.t), np.asarray(path.q), np.asarray(path.T_palm_object), tuple(path.phases)
    q = np.stack([prev.q, step.q]).astype(float)
    return time_stamps(q), q, np.stack([prev.T_palm_object, step.T_palm_object]).astype(float), ("linear",)


def sample_plan_motion(plan_steps, hand: Hand, max_point_step: float = MAX_POINT_STEP) -> MotionSamples:
    """Samples of every step's motion (from step 1 on), dense enough for `max_point_step` (m); see the
    module docstring for the rule."""
    levers_by_finger = lever_arms(hand)
    levers = np.array([levers_by_finger[f] for f in hand.fingers])
    finger_cols = np.zeros((hand.n_joints, len(hand.fingers)))
    for i, f in enumerate(hand.fingers):
        finger_cols[np.asarray(hand.finger_joints[f]).ravel(), i] = 1.0
    parts: list[tuple] = []
    t_start, worst = 0.0, 0.0
    for k in range(1, len(plan_steps)):
        t, q, T, phases = _step_knots(plan_steps[k - 1], plan_steps[k])
        bound = _segment_bounds(hand, levers, finger_cols, q, T)
        n_sub = np.maximum(1, np.ceil(bound / max_point_step - 1e-9)).astype(int)
        worst = max(worst, float(np.max(bound / n_sub, initial=0.0)))
        seg = np.repeat(np.arange(len(n_sub)), n_sub)
        s = np.concatenate([np.arange(n) / n for n in n_sub])
        seg, s = np.append(seg, len(n_sub) - 1), np.append(s, 1.0)  # the last knot
        qs, Ts = _interpolate(q, T, seg, s)
        ts = t[seg] + s * (t[seg + 1] - t[seg])
        parts.append((np.full(len(s), k), ts, t_start + ts, [phases[i] for i in seg], qs, Ts))
        t_start += float(t[-1])
    if not parts:
        n = hand.n_joints
        return MotionSamples(np.zeros(0, int), np.zeros(0), np.zeros(0), (), np.zeros((0, n)),
                             np.zeros((0, 4, 4)), 0.0)
    cat = [np.concatenate([p[i] for p in parts]) for i in (0, 1, 2, 4, 5)]
    phase = tuple(x for p in parts for x in p[3])
    return MotionSamples(cat[0].astype(int), cat[1], cat[2], phase, cat[3], cat[4], worst)


# ---------------------------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class MotionGeometry:
    """The exact geometry of every sample (N samples, m fingers, S spheres, P self-collision pairs)."""

    samples: MotionSamples
    clearance: NDArray[np.float64]
    """(N, S) exact distance − radius of every sphere (tips included; exact within `NEAR` of 0)."""
    tip_gap: NDArray[np.float64]
    """(N, m) exact distance of each tip centre − tip radius, m."""
    p_object_contact: NDArray[np.float64]
    """(N, m) exact closest points of the tip centres, object frame, m."""
    p_object_tip: NDArray[np.float64]
    """(N, m, 3) the tip centres, object frame, m."""
    self_min: dict[int, tuple[NDArray[np.float64], NDArray[np.int64]]]
    """step -> (smallest surface distance (P,) of every self-collision pair over the step's samples, m;
    the sample where it is), exact below the threshold + `NEAR` (P = 0 when not checked)."""


def motion_geometry(ctx: VerifyContext) -> MotionGeometry:
    """The motion's samples and geometry, computed once per `verify` call (kept on `ctx`)."""
    cached = ctx.__dict__.get("_motion_geometry")
    if cached is not None:
        return cached
    t0 = time.perf_counter()
    hand, tol = ctx.hand, ctx.tol
    samples = sample_plan_motion(ctx.plan.steps, hand)
    C = sphere_centres(hand, samples.q)
    T = samples.T_palm_object
    p_object = np.einsum("kij,ksi->ksj", T[:, :3, :3], C - T[:, None, :3, 3])  # (N, S, 3)
    N, S = C.shape[:2]
    radii = np.array([s.radius for s in hand.spheres])
    tip_idx = np.array([next(i for i, s in enumerate(hand.spheres) if s.is_tip and s.finger == f)
                        for f in ctx.fingers])
    threshold = np.full(S, max(tol.min_clearance, 0.0))
    threshold[tip_idx] = -tol.surface_tol
    blocks = _step_blocks(samples.step)
    on_surface = np.stack([_on_surface(ctx, ctx.plan.steps[k]) for k in samples.step]) if N else \
        np.zeros((0, len(tip_idx)), bool)
    skip = np.zeros((N, S), bool)
    skip[:, tip_idx] = on_surface  # the holding tips: exact below
    clearance = _object_clearance(ctx.obj, p_object, radii, threshold, blocks, samples.max_point_step, skip)
    tip_gap, contact = _tip_contacts(ctx.obj, p_object[:, tip_idx], radii[tip_idx], on_surface)
    clearance[:, tip_idx] = np.where(on_surface, tip_gap, clearance[:, tip_idx])
    tip_gap = np.where(on_surface, tip_gap, clearance[:, tip_idx])
    pairs = ctx.self_pairs if tol.self_clearance is not None else ()
    judged = {k: _judged_rows(samples, ctx.plan.steps, k) for k in np.unique(samples.step).tolist()}
    judged = {k: rows for k, rows in judged.items() if rows.size}
    per_step = _self_distances(hand, C, pairs, tol.self_clearance or 0.0, list(judged.values()),
                               samples.max_point_step)
    self_min = dict(zip(judged, per_step, strict=True))
    geom = MotionGeometry(samples, clearance, tip_gap, contact, p_object[:, tip_idx], self_min)
    ctx.__dict__["_motion_geometry"] = geom
    ctx.metrics.update({"motion_samples": int(N), "motion_max_point_step": samples.max_point_step,
                        "motion_seconds": time.perf_counter() - t0})
    return geom


def _step_blocks(step_of_sample: NDArray) -> list[slice]:
    """The sample rows of each step's motion, as slices (samples are in step order)."""
    if not len(step_of_sample):
        return []
    cuts = np.flatnonzero(np.diff(step_of_sample)) + 1
    bounds = [0, *cuts.tolist(), len(step_of_sample)]
    return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def _coarse_rows(n: int) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Every `_STRIDE`-th row of a block of n rows and its last: (coarse rows, the nearest coarse row
    of each row (n,), its distance in rows (n,))."""
    coarse = np.unique(np.append(np.arange(0, n, _STRIDE), n - 1))
    pos = np.clip(np.searchsorted(coarse, np.arange(n)), 1, len(coarse) - 1) if len(coarse) > 1 else \
        np.zeros(n, int)
    if len(coarse) > 1:
        left, right = coarse[pos - 1], coarse[pos]
        pos = np.where(np.arange(n) - left <= right - np.arange(n), pos - 1, pos)
    nearest = coarse[pos]
    return coarse, nearest, np.abs(np.arange(n) - nearest).astype(float)


def _object_clearance(obj, p_object: NDArray, radii: NDArray, threshold: NDArray, blocks: list[slice],
                      delta: float, skip: NDArray) -> NDArray[np.float64]:
    """(N, S) distance − radius of every sphere (not where `skip` (N, S)): exact where it may be below
    threshold (S,) + `NEAR`; elsewhere a lower bound: the distance to the mesh's bounding box, the
    convex pieces' support-plane estimate (`ObjectModel.near_signed_distance`: the pieces cover the
    mesh up to their decomposition error, which `NEAR` absorbs), or the value at the nearest coarse
    sample of the same step minus `delta` (m, the most a point moves between two samples) per sample
    between them (the distance is 1-Lipschitz). Each distinct point is queried once (in a gait the
    palm and the other fingers do not move)."""
    N, S = p_object.shape[:2]
    lo, hi = (np.asarray(b, float) for b in obj.mesh.bounds)
    box = np.linalg.norm(np.maximum(np.maximum(lo - p_object, p_object - hi), 0.0), axis=2)
    value, known = box - radii[None], skip.copy()
    limit = threshold[None] + NEAR

    def fill(rows: NDArray, mask: NDArray) -> None:
        r, j = np.nonzero(mask)
        if r.size:
            keys = np.column_stack([p_object[rows[r], j], j])
            uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
            jj = uniq[:, 3].astype(int)
            d = obj.near_signed_distance(uniq[:, :3], radii[jj] + threshold[jj] + NEAR) - radii[jj]
            value[rows[r], j] = d[np.asarray(inverse).reshape(-1)]
            known[rows[r], j] = True

    for block in blocks:
        rows = np.arange(block.start, block.stop)
        coarse, nearest, steps = _coarse_rows(len(rows))
        fill(rows[coarse], (value[rows[coarse]] < limit) & ~known[rows[coarse]])
        near_val = value[rows[nearest]] - steps[:, None] * delta
        value[rows] = np.maximum(value[rows], np.where(known[rows[nearest]], near_val, -np.inf))
        fill(rows, (value[rows] < limit) & ~known[rows])
    return value


def _tip_contacts(obj, p_object_tips: NDArray, tip_radii: NDArray,
                  mask: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact (gap (N, m) m, closest point (N, m, 3) object frame m) of the tip centres (N, m, 3) where
    `mask` (N, m) (NaN elsewhere); each distinct point queried once."""
    N, m = mask.shape
    gap, contact = np.full((N, m), np.nan), np.full((N, m, 3), np.nan)
    r, f = np.nonzero(mask)
    if r.size:
        pts, inverse = np.unique(p_object_tips[r, f], axis=0, return_inverse=True)
        closest, sd = obj.closest_points(pts)
        inverse = np.asarray(inverse).reshape(-1)
        gap[r, f] = np.asarray(sd)[inverse] - tip_radii[f]
        contact[r, f] = np.asarray(closest)[inverse]
    return gap, contact


def _self_distances(hand: Hand, C: NDArray, pairs, limit: float, blocks: list[NDArray[np.int64]],
                    delta: float) -> list[tuple[NDArray[np.float64], NDArray[np.int64]]]:
    """Per step (its consecutive sample rows): (smallest surface distance (P,) of each sphere pair
    (P, 2) over the step's samples, m; the sample row where it is). Exact for the pairs that may come
    within `limit` + `NEAR` (at every sample), a lower bound for the others (their coarse samples'
    minimum − 2·delta per sample to the farthest sample they stand for, m; at the coarse sample)."""
    from regrasp_casadi.self_collision import pair_distances

    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    out = []
    for rows in blocks:
        if not len(pairs):
            out.append((np.zeros(0), np.zeros(0, int)))
            continue
        coarse, _, _ = _coarse_rows(len(rows))
        D = pair_distances(hand, C[rows[coarse]], pairs)
        reach = 2.0 * delta * (_STRIDE / 2.0 + 1.0)
        lower, at = np.min(D, axis=0) - reach, rows[coarse[np.argmin(D, axis=0)]]
        close = np.flatnonzero(lower < limit + NEAR)
        if close.size:
            full = pair_distances(hand, C[rows], pairs[close])
            lower[close], at[close] = np.min(full, axis=0), rows[np.argmin(full, axis=0)]
        out.append((lower, at))
    return out


def _on_surface(ctx: VerifyContext, step: PlanStep) -> NDArray[np.bool_]:
    """(m,) the fingers whose tips must stay on the surface during the step's motion: all but a gait's
    moving finger."""
    return np.array([not (step.kind == "gait" and f == step.finger) for f in ctx.fingers])


def _rows(ctx: VerifyContext, k: int, ends: bool = False) -> NDArray[np.int64]:
    """Indices of the samples of step k's motion (`_judged_rows`)."""
    return _judged_rows(motion_geometry(ctx).samples, ctx.plan.steps, k, ends)


def _judged_rows(samples: MotionSamples, steps, k: int, ends: bool = False) -> NDArray[np.int64]:
    """Indices of the samples of step k's motion; without `ends`, not its first and last sample when
    they are exactly the previous step and step k (the static rows of `CHECK_TABLE` judge those)."""
    rows = np.flatnonzero(samples.step == k)
    if ends or not rows.size:
        return rows
    keep = np.ones(len(rows), bool)
    for pos, step in ((0, steps[k - 1]), (-1, steps[k])):
        i = rows[pos]
        keep[pos] &= not (np.array_equal(samples.q[i], step.q)
                          and np.array_equal(samples.T_palm_object[i], step.T_palm_object))
    return rows[keep]


def _when(ctx: VerifyContext, k: int, i: int) -> str:
    """"at step k, t = … s into its motion (… s into the plan, phase …)" for sample i."""
    s = motion_geometry(ctx).samples
    return (f"at step {k} ({ctx.plan.steps[k].kind}), t = {s.t_step[i]:.3f} s into its motion "
            f"({s.t_plan[i]:.3f} s into the plan, {s.phase[i]})")


def _moving_finger(step: PlanStep) -> str | None:
    return step.finger if step.finger else None


# ---------------------------------------------------------------------------------------------- checks
def check_motion_penetration(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """No sphere of the hand in the object at any sample: non-tip spheres ≥ min_clearance, tips ≥
    −surface_tol (metric "motion_min_clearance")."""
    from regrasp_casadi.verify import Finding

    rows = _rows(ctx, k)
    if not rows.size:
        return []
    geom, hand = motion_geometry(ctx), ctx.hand
    clear = geom.clearance[rows]
    is_tip = np.array([s.is_tip for s in hand.spheres])
    non_tip = clear[:, ~is_tip]
    if non_tip.size:
        ctx.metrics["motion_min_clearance"] = min(ctx.metrics.get("motion_min_clearance", math.inf),
                                                  float(np.min(non_tip)))
    limit = np.where(is_tip, -ctx.tol.surface_tol, ctx.tol.min_clearance)
    worst: dict[str, tuple[float, int, int]] = {}  # link -> (clearance, sample row, sphere)
    for r, j in zip(*np.nonzero(clear < limit[None]), strict=True):
        link = hand.spheres[j].link
        if link not in worst or clear[r, j] < worst[link][0]:
            worst[link] = (float(clear[r, j]), int(rows[r]), int(j))
    out = []
    for link, (c, i, j) in sorted(worst.items(), key=lambda kv: kv[1][0]):
        sph = hand.spheres[j]
        out.append(Finding(link, c, float(limit[j]),
                           f"{_when(ctx, k, i)}: link {link} ({sph.finger or 'palm'}) is "
                           f"{-c * 1e3:.2f} mm inside the object (sphere {sph.label}; allowed "
                           f"{abs(min(float(limit[j]), 0.0)) * 1e3:.2f} mm)" if c < 0 else
                           f"{_when(ctx, k, i)}: link {link} ({sph.finger or 'palm'}) has only "
                           f"{c * 1e3:.2f} mm clearance (< {limit[j] * 1e3:.2f} mm; sphere {sph.label})"))
    return out


def check_motion_self_collision(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Sphere pairs of different fingers / a finger and the palm ≥ self_clearance at every sample; one
    finding per link pair, at its worst sample (metric "motion_min_self_clearance")."""
    from regrasp_casadi.verify import Finding

    limit, geom, hand = ctx.tol.self_clearance, motion_geometry(ctx), ctx.hand
    if limit is None or k not in geom.self_min or not len(geom.self_min[k][0]):
        return []
    pair_min, at = geom.self_min[k]
    ctx.metrics["motion_min_self_clearance"] = min(ctx.metrics.get("motion_min_self_clearance", math.inf),
                                                   float(np.min(pair_min)))
    worst: dict[tuple[str, str], int] = {}
    for p in np.argsort(pair_min, kind="stable"):
        if pair_min[p] >= limit:
            break
        a, b = ctx.self_pairs[p]
        worst.setdefault((hand.spheres[a].link, hand.spheres[b].link), int(p))
    out = []
    for (la, lb), p in worst.items():
        a, b = ctx.self_pairs[p]
        sa, sb, d, i = hand.spheres[a], hand.spheres[b], float(pair_min[p]), int(at[p])
        what = f"overlap by {-d * 1e3:.2f} mm" if d < 0 else f"are only {d * 1e3:.2f} mm apart"
        out.append(Finding(f"{la}|{lb}", d, limit,
                           f"{_when(ctx, k, i)}: links {la} ({sa.finger or 'palm'}) and {lb} "
                           f"({sb.finger or 'palm'}) {what} (spheres {sa.label}, {sb.label}; required "
                           f"{limit * 1e3:.2f} mm)"))
    return out


def check_motion_joint_limits(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Every joint within [q_lower − limit_tol, q_upper + limit_tol] at every sample."""
    from regrasp_casadi.verify import Finding

    rows = _rows(ctx, k)
    if not rows.size:
        return []
    hand, tol = ctx.hand, ctx.tol.limit_tol
    Q = motion_geometry(ctx).samples.q[rows]
    over = np.maximum(np.asarray(hand.q_lower, float)[None] - Q, Q - np.asarray(hand.q_upper, float)[None])
    out = []
    for j in np.flatnonzero(np.max(over, axis=0) > tol):
        r = int(np.argmax(over[:, j]))
        name = hand.joint_names[j]
        out.append(Finding(name, float(over[r, j]), tol,
                           f"{_when(ctx, k, int(rows[r]))}: joint {name} = {Q[r, j]:.6g} rad is "
                           f"{over[r, j]:.3g} rad outside its limits"))
    return out


def _holding(ctx: VerifyContext, step: PlanStep) -> NDArray[np.bool_]:
    """(m,) the fingers whose tips hold the object during the step's motion (all but a moving finger)."""
    return np.array([f != _moving_finger(step) for f in ctx.fingers])


def check_motion_held_contacts(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """The holding fingertips on the surface, |gap| ≤ surface_tol, at every sample (a step's sliding
    finger too, other than a gait's) (metric "motion_max_surface_error")."""
    from regrasp_casadi.verify import Finding

    rows = _rows(ctx, k)
    if not rows.size:
        return []
    on_surface = _on_surface(ctx, step)
    gap, tol = np.abs(motion_geometry(ctx).tip_gap[rows][:, on_surface]), ctx.tol.surface_tol
    if gap.size:
        ctx.metrics["motion_max_surface_error"] = max(ctx.metrics.get("motion_max_surface_error", 0.0),
                                                      float(np.max(gap)))
    fingers = [f for f, on in zip(ctx.fingers, on_surface, strict=True) if on]
    signed = motion_geometry(ctx).tip_gap[rows][:, on_surface]
    out = []
    for c in np.flatnonzero(np.max(gap, axis=0, initial=0.0) > tol):
        r = int(np.argmax(gap[:, c]))
        where = "above" if signed[r, c] > 0 else "inside"
        out.append(Finding(fingers[c], float(gap[r, c]), tol,
                           f"{_when(ctx, k, int(rows[r]))}: the {fingers[c]} tip, holding the object, is "
                           f"{gap[r, c] * 1e3:.2f} mm {where} the surface (tolerance {tol * 1e3:.2f} mm)"))
    return out


def _motion_tip_slip(ctx: VerifyContext, k: int, step: PlanStep, rows: NDArray[np.int64]) -> NDArray:
    """(len(rows), m) how far each tip's material has slid over the object from the first of `rows` (the
    samples of step k's motion, in order), m: `grasp_metrics.path_tip_slip` of the tip centres, the exact
    normals and, in a reposing or final move, the tip orientations (elsewhere a holding tip does not
    turn relative to the object: its slip is its centre's travel)."""
    from regrasp_casadi.grasp_metrics import path_tip_slip
    from regrasp_casadi.stability import contact_normals

    geom, hand = motion_geometry(ctx), ctx.hand
    q, T = geom.samples.q[rows], geom.samples.T_palm_object[rows]
    p_object = geom.p_object_tip[rows]
    normals = np.stack([contact_normals(c, p) for c, p in zip(geom.p_object_contact[rows], p_object,
                                                               strict=True)])
    R = np.broadcast_to(np.eye(3), (len(rows), len(ctx.fingers), 3, 3))
    if step.kind in ("repose", "final"):  # R_palm_tip of every sample, one mapped call per finger
        R_palm = np.stack([np.asarray(hand.link_rotation_function(hand.tip_links[f]).map(len(q))(q.T), float)
                           .reshape(3, len(q), 3).transpose(1, 0, 2) for f in ctx.fingers], axis=1)
        R = np.einsum("kji,kfjl->kfil", T[:, :3, :3], R_palm)
    return path_tip_slip(p_object, R, normals, hand.tip_radius)


def check_motion_slip(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Each holding tip's material slides at most max_slip over the object from the start of the step's
    motion, at every sample (`grasp_metrics.path_tip_slip`: a tip may roll; metric "motion_max_slip")."""
    from regrasp_casadi.verify import Finding

    rows = _rows(ctx, k, ends=True)
    if not _rows(ctx, k).size:
        return []
    held, tol = _holding(ctx, step), ctx.tol.max_slip
    slip = _motion_tip_slip(ctx, k, step, rows)[:, held]
    if slip.size:
        ctx.metrics["motion_max_slip"] = max(ctx.metrics.get("motion_max_slip", 0.0), float(np.max(slip)))
    fingers = [f for f, h in zip(ctx.fingers, held, strict=True) if h]
    out = []
    for c in np.flatnonzero(np.max(slip, axis=0, initial=0.0) > tol):
        r = int(np.argmax(slip[:, c]))
        out.append(Finding(fingers[c], float(slip[r, c]), tol,
                           f"{_when(ctx, k, int(rows[r]))}: the {fingers[c]} tip has slid "
                           f"{slip[r, c] * 1e3:.2f} mm over the object (allowed {tol * 1e3:.2f} mm)"))
    return out
