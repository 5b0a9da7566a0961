"""A gait's path: lift-off of the moving finger's tip along its contact normal, a transit above the
object, touch-down on the new contact (`trajectory` module docstring, "Gait"); only that finger's joints
move, the object stays.

* **Lift-off** (`_clear_lift`): the tip centre rises `lift_height` along the contact normal by IK
  (`_lift`), else lower (3/5, 2/5 of it) or leaning 25°/40° away from the closest other finger, choosing
  the first that rises at least β, keeps the finger clear of the others (no closer than at the contact),
  stays within the joint limits and `max_lift_angle`, and keeps the finger's other spheres out of the
  object. The touch-down is the lift from the new contact, reversed.
* **Transit** (`_transit`): linear in joint space between the lifted ends, directly or through a via
  point raised by `via_heights` above their midpoint, else (another finger too close) one also moved
  `_ASIDE` away from that finger, its spheres ≥ β from the object and ≥ `self_clearance` from the other
  fingers (or no closer than at the lifted ends).

    >>> path = gait_path(ctx, step_a, step_b)     # ctx: `trajectory.motion_context(hand, obj)`
    >>> why = lift_problem(ctx, q, T_palm_object, "index")
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.trajectory import _held_joints, _ik, _knots, _limit_problems, _linear, _timed
from regrasp_casadi.transforms import inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.motion import StepPath
    from regrasp_casadi.plan import PlanStep
    from regrasp_casadi.trajectory import _Context

__all__ = ["gait_path", "lift_problem"]

_ASIDE = (0.005, 0.01)
"""How far a transit's via point moves away from the other finger it comes too close to, m."""

_RISE_TOL = 0.1
"""A lift knot may fall short of its height along the normal by this fraction (joint limits)."""

_SIDEWAYS_WEIGHT = 0.1
"""Weight of the sideways error of a lift-off against its rise along the normal (IK)."""


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


def _clear_lift(ctx: _Context, q0: NDArray, T_palm_object: NDArray | None, finger: str, n_palm: NDArray
                ) -> tuple[NDArray[np.float64], str]:
    """`_lift` by `lift_height`, else lower (3/5, 2/5 of it), else leaning 25°, 40° away from the closest
    other finger (full, 3/5, 2/5 height), when the lift brings the finger closer to another than
    `self_clearance` (and than at q0); if every one does, the one that keeps it farthest from the others
    among those whose tip rises at least β along n_palm (a thumb touch-down on bottle_regrasp cleared the
    palm by 0.33 mm only leaning 40° at 2/5 height; a middle lift-off held at its joint limits must not
    trade its rise for clearance from the others). A lift that would put another sphere of the finger into
    the object (hand at q0 (n,) rad, object at `T_palm_object` (4, 4); None: not checked) is passed over
    for the next (measured: the generated cup pair of seed 15, svd, an index inside the cup near its rim:
    the full lift put its middle link 0.12 mm into the rim, 3/5 of it kept 0.24 mm clear; the gait path
    was refused)."""
    o = ctx.options
    floor = min(o.self_clearance or 0.0, float(ctx.self_distance(q0[None], finger)[0])) - 1e-9
    best: tuple[tuple, NDArray[np.float64], str] | None = None
    tries = [(n_palm, f) for f in (1.0, 0.6, 0.4)]
    u = _away_from_others(ctx, q0[None], finger, n_palm)  # from the closest other finger's sphere (or palm)
    if u is not None:  # leaning that way, in the tangent plane
        leans = [n_palm + math.tan(math.radians(deg)) * u for deg in (25, 40)]
        tries += [(d / np.linalg.norm(d), f) for d in leans for f in (1.0, 0.6, 0.4)]
    r_tip = ctx.hand.fingers.index(finger)
    mine = ctx.finger_spheres(finger)
    links = mine[mine != ctx.tip_index[finger]] if T_palm_object is not None else mine[:0]
    Ts = None if T_palm_object is None else np.asarray(T_palm_object, dtype=float)[None]
    for direction, fraction in tries:
        knots, why = _lift(ctx, q0, finger, direction, fraction * o.lift_height)
        gap = float(np.min(ctx.self_distance(knots, finger)))
        rise = float((ctx.hand.tip_positions(knots[-1])[r_tip] - ctx.hand.tip_positions(q0)[r_tip]) @ n_palm)
        outside = not links.size or float(np.min(ctx.clearance(knots, np.repeat(Ts, len(knots), axis=0),
                                                               links))) >= 0.0
        # off the surface by the transit's β first, clear of the others, within the lean limit, the links out
        key = (rise >= o.beta, gap >= floor, not why, outside, gap)
        if all(key[:4]):
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
    raised by `via_heights` along n_mid (palm frame), else (when another finger is what it comes too
    close to) raised by 0 or `via_heights` and moved `_ASIDE` away from the closest other finger's sphere
    across n_mid; the first whose finger spheres keep ≥ β from the object and ≥ `self_clearance` from
    the other fingers, else the one with the largest margin. What is closer at the lifted end q_a or q_b
    (a lift held short by the joint limits or the other fingers, a link near the object in the grasp)
    keeps no worse than there, as OPT1 and `_clear_lift` do: per sphere for the object (flat tool, index
    touch-down 0.70 mm off it), the finger's least distance to the others, never below 0 (bowl seed 9
    SD: an index lifted 0.47 mm from the middle); else both gaits were refused at every iteration. The
    clearance of the finger's spheres at the knots `also` (j, n) comes with the first attempt's query.
    Returns (knots, min clearance m, min distance to the other fingers m, why, clearance of `also` (j,
    spheres) m)."""
    hand, o = ctx.hand, ctx.options
    spheres = ctx.finger_spheres(finger)
    r = hand.fingers.index(finger)
    p_mid = 0.5 * (hand.tip_positions(q_a)[r] + hand.tip_positions(q_b)[r])
    q_mid = 0.5 * (q_a + q_b)
    Q, why = _transit_knots(ctx, [q_a, q_b])
    clear_all = ctx.clearance(np.concatenate([Q, also]), np.repeat(T[None], len(Q) + len(also), axis=0),
                              spheres, o.beta)
    clear_also, gaps = clear_all[len(Q):], ctx.self_distance(Q, finger)
    # per sphere: β, or no worse than at the lifted ends where it is closer there
    floor = np.minimum(o.beta, np.min(clear_all[[0, len(Q) - 1]], axis=0)) - 1e-9
    self_floor = min(max(min(gaps[0], gaps[-1]), 0.0), o.self_clearance or 0.0) - 1e-9

    def judged(Q: NDArray, clear: NDArray, gaps: NDArray, why: str) -> _Transit:
        dip, self_dip = float(np.min(clear - floor)), float(np.min(gaps)) - self_floor  # < 0: below
        return _Transit(Q, min(dip, self_dip), why, float(np.min(clear)), float(np.min(gaps)), dip, self_dip)

    def through(p_via: NDArray) -> _Transit:
        via, _ = _ik(ctx, q_mid, [finger], p_via[None], hand.finger_joints[finger],
                     q_mid)  # as high as the joint limits allow: the clearances judge it
        Q, why = _transit_knots(ctx, [q_a, via, q_b])
        return judged(Q, ctx.clearance(Q, np.repeat(T[None], len(Q), axis=0), spheres, o.beta),
                      ctx.self_distance(Q, finger), why)

    best = judged(Q, clear_all[: len(Q)], gaps, why)
    for height in o.via_heights if best.margin < 0.0 else ():
        best = max(best, through(p_mid + height * n_mid), key=lambda t: t.margin)
        if best.margin >= 0.0:
            break
    away = _away_from_others(ctx, best.Q, finger, n_mid) if best.self_dip < 0.0 else None
    for aside, height in ((d, h) for d in _ASIDE for h in (0.0, *o.via_heights)) if away is not None else ():
        best = max(best, through(p_mid + height * n_mid + aside * away), key=lambda t: t.margin)
        if best.margin >= 0.0:
            break
    why = best.why
    if best.dip < 0.0:
        why += (f"; transit clearance {best.clear * 1e3:.3f} mm < β = {o.beta * 1e3:.3f} mm (or a sphere "
                f"{-best.dip * 1e3:.3f} mm closer than at the transit's ends, where it is closer than β)")
    if best.self_dip < 0.0:
        why += (f"; transit {best.self_clear * 1e3:.3f} mm from another finger < "
                f"{o.self_clearance * 1e3:.3f} mm (or {-best.self_dip * 1e3:.3f} mm closer than at the "
                f"transit's ends, where it is closer)")
    return best.Q, best.clear, best.self_clear, why.strip("; "), clear_also


class _Transit(NamedTuple):
    """One transit tried: knots (k, n), margin (m, ≥ 0: it passes), why its knots failed, least
    clearance from the object and from the other fingers (m), and how far below their floors (m)."""

    Q: NDArray
    margin: float
    why: str
    clear: float
    self_clear: float
    dip: float
    self_dip: float


def _transit_knots(ctx: _Context, waypoints: list[NDArray]) -> tuple[NDArray[np.float64], str]:
    """Knots (k, n) linear in joint space through the waypoints, dense for `max_point_step`, and why a
    leg failed ("")."""
    legs = [_knots(ctx, _linear(a, b), 2, linear=True)[1:] for a, b in zip(waypoints, waypoints[1:],
                                                                           strict=False)]
    Q = np.concatenate([legs[0][0]] + [leg[0][1:] for leg in legs[1:]])
    return Q, "; ".join(w for _, w in legs if w)


def _away_from_others(ctx: _Context, Q: NDArray, finger: str, n: NDArray) -> NDArray[np.float64] | None:
    """(3,) unit direction, palm frame, across n, from the other finger's (or the palm's) sphere closest
    to the finger's spheres over the knots Q (k, n) to the finger's; None when the finger's pairs are not
    checked or that direction is along n."""
    pairs = ctx.self_pairs.get(finger, np.zeros((0, 2), dtype=int))
    if not len(pairs):
        return None
    C, rad = ctx.centers(Q), ctx.radii
    gap = np.linalg.norm(C[:, pairs[:, 0]] - C[:, pairs[:, 1]], axis=2) - rad[pairs[:, 0]] - rad[pairs[:, 1]]
    k, p = np.unravel_index(int(np.argmin(gap)), gap.shape)
    a, b = pairs[p]
    v = (C[k, a] - C[k, b]) * (1.0 if ctx.sphere_finger[a] == finger else -1.0)
    u = v - (v @ n) * n
    return u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else None


def gait_path(ctx: _Context, a: PlanStep, b: PlanStep) -> StepPath:
    """The path of gait step b from step a: lift-off, transit, touch-down of finger `b.finger`.

    Metrics (m; angles rad): "lift_height" (tip-centre rise of the lift-off), "max_lift_angle" (lean of
    the lift-off and touch-down from their normals), "min_transit_clearance" (every sphere of the finger
    in the transit), "min_clearance" (its non-tip spheres during lift-off and touch-down),
    "min_tip_clearance" (its tip then: ≥ −surface_tol), "max_point_step".
    """
    hand, o, finger = ctx.hand, ctx.options, str(b.finger)
    T = np.asarray(b.T_palm_object, dtype=float)
    n_a, n_b = _contact_normal_palm(ctx, a, finger), _contact_normal_palm(ctx, b, finger)
    lift, why_a = _clear_lift(ctx, np.asarray(a.q, dtype=float), T, finger, n_a)
    down, why_b = _clear_lift(ctx, np.asarray(b.q, dtype=float), T, finger, n_b)
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



def lift_problem(ctx: _Context, q: NDArray, T_palm_object: NDArray, finger: str) -> str:
    """Why `finger` could not lift off its contact of the grasp (q (n,) rad, `T_palm_object` (4, 4)) the
    way a gait's path does (`_clear_lift`: `lift_height` along the contact normal, lower or leaning, within
    the joint limits and `max_lift_angle`), nor so touch down on it; "" when it can. Only the tip's
    rise, the lean and the joint limits count here (grasp generation's rule): a lift that keeps the other
    fingers clear is preferred, but a lift that cannot is not reported; the links' clearance from the
    object is not looked at (grasp generation asks this of every candidate grasp)."""
    n_palm = _normal_palm(ctx, q, T_palm_object, None, finger)
    return _clear_lift(ctx, np.asarray(q, dtype=float), None, finger, n_palm)[1]
