"""Why the fingers of a stalled plan are not at their goal contacts: a sentence per finger still farther
than ζ (or within ζ but across the object from its goal, `surface_route.fingers_across`), from checks
independent of the NLPs at the plan's last grasp, for the plan's `status_detail`.

* **In the way**: the straight line from the finger's tip centre to its goal tip centre (object frame),
  which OPT1's cost pulls the tip along, passes through the object (exact signed distance < 0 at one of
  its samples): the goal is across a wall, a rim or a handle, and η-bounded gaits that each lower that
  distance cannot go around it. Where the line stays outside but closer than a tip radius, the tip
  sphere would cut into the object on the way (reported as such).
* **Out of reach**: the finger's tip cannot be put on its goal at the current object pose within the
  joint limits (damped least-squares IK, `tip_ik`, collisions ignored), or only with one of its other
  collision spheres in the object (exact distance): the object must move first.
* **Through another finger**: reached, the finger's collision spheres overlap another finger's (or the
  palm's), the others where they are: that finger, or the object, must move first.
* **No touch-down there**: reached, the finger could not lift off its goal contact in that posture
  the way a gait's path does (`gait_path.lift_problem`), so no gait can put it down there either
  (measured: bowl seed 9's desired grasp before `grasp_gen`'s lift-off rule, the ring on the floor at
  its flexion limits).
* **No nearer point within η** (with `eta`): no point of the surface within η of the finger's contact is
  much nearer its goal contact (the mesh subdivided to η/5, its vertices within η): a gait moves a
  contact at most η, and the way to the goal leaves the surface — across a cup's mouth, say — or goes
  the long way round it (measured: the generated cup pair of seed 4, SD, the ring on the rim 74.4 mm
  from its goal on the opposite rim: the best point within η is 2.1 mm nearer).

    >>> stalled_fingers(hand, obj, q, T_palm_object, goal_tips_object, contact_error, zeta)
    '; not at their goals: ring 37.8 mm (the object lies between its tip and its goal: ...)'
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.gait_path import lift_problem
from regrasp_casadi.surface_route import line_clearance
from regrasp_casadi.tip_ik import finger_reach_ik
from regrasp_casadi.trajectory import motion_context

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel

__all__ = ["stalled_fingers", "reached_through_others", "through_others", "blocker", "REACH_TOL",
           "OFF_SURFACE_GAIN"]

REACH_TOL = 1e-3
"""A finger whose IK gets its tip centre no closer than this to its goal cannot reach it, m."""

LINE_SAMPLES = 41
"""Samples of each straight tip-to-goal line whose exact signed distance is taken."""

OFF_SURFACE_GAIN = 0.25
"""A finger whose best surface point within η of its contact is less than this part of η nearer its goal
contact is reported (on a face towards the goal the best is η nearer)."""


def stalled_fingers(hand: Hand, obj: ObjectModel, q: NDArray, T_palm_object: NDArray,
                    goal_tips_object: NDArray, contact_error: NDArray, zeta: float, *,
                    q_goal: NDArray | None = None, eta: float | None = None,
                    across: tuple[int, ...] | list[int] = ()) -> str:
    """"; not at their goals: <finger> <error> mm (<why>) | ..." for every finger whose contact error
    exceeds `zeta` or whose row is in `across` (within ζ, across the object from its goal:
    `surface_route.fingers_across`), or "" when none is.

    Args:
        hand: the hand.
        obj: the object (exact distances).
        q: (n,) joints of the grasp, rad.
        T_palm_object: (4, 4) object pose of the grasp, palm frame, m.
        goal_tips_object: (m, 3) goal tip-sphere centres, object frame, m (`Grasp.tip_centers_object`).
        contact_error: (m,) distance of each contact to its goal contact, m.
        zeta: ζ, m.
        q_goal: (n,) the goal grasp's joints, rad, if known: a further start of the reach IK
            (`tip_ik.finger_reach_ik`).
        eta: η, m: when given, a finger whose surface gains less than `OFF_SURFACE_GAIN` × η towards its
            goal within η of its contact is reported so (module docstring).
        across: rows of fingers within ζ that are reported too (across the object from their goals).
    """
    R, t = np.asarray(T_palm_object, float)[:3, :3], np.asarray(T_palm_object, float)[:3, 3]
    tips = (np.asarray(hand.tip_positions(q), float) - t) @ R
    rho = float(hand.tip_radius)
    parts = []
    motion = None  # the paths' context (`trajectory.motion_context`), built once when a finger needs it
    for r, finger in enumerate(hand.fingers):
        if contact_error[r] <= zeta and r not in across:
            continue
        goal = np.asarray(goal_tips_object[r], float)
        least = line_clearance(obj, tips[r], goal, LINE_SAMPLES)
        why = []
        if least < 0.0:
            why.append(f"the object lies between its tip and its goal: the straight line passes "
                       f"{-least * 1e3:.1f} mm inside it")
        elif least < rho - 1e-4:
            why.append(f"its tip sphere would cut {(rho - least) * 1e3:.1f} mm into the object on the "
                       f"straight line to its goal")
        q = np.asarray(q, float)
        q_reach, e = finger_reach_ik(hand, q, finger, R @ goal + t, [q_goal], tol=REACH_TOL)
        if float(np.linalg.norm(e)) > REACH_TOL:
            why.append(f"out of its reach at this object pose (its tip gets no closer than "
                       f"{float(np.linalg.norm(e)) * 1e3:.1f} mm)")
        else:  # reached: with its other links clear of the object?
            depth = link_depth(hand, obj, q_reach, T_palm_object, finger)
            if depth < 0.0:
                why.append(f"at this object pose its tip reaches the goal only with a link "
                           f"{-depth * 1e3:.1f} mm in the object")
            why += through_others(hand, q_reach, finger)
            motion = motion or motion_context(hand, obj)
            lift = lift_problem(motion, q_reach, T_palm_object, finger)
            if lift:
                why.append(f"it reaches the goal only in a posture it could not touch down in ({lift})")
        if eta is not None:
            gain = _best_gain(obj, tips[r], goal, eta)
            if gain < OFF_SURFACE_GAIN * eta:
                why.append(f"a gait moves its contact at most η = {eta * 1e3:.1f} mm, and no point of the "
                           f"surface that near is more than {gain * 1e3:.1f} mm nearer its goal")
        parts.append(f"{finger} {contact_error[r] * 1e3:.1f} mm" + (f" ({'; '.join(why)})" if why else ""))
    return "; not at their goals: " + " | ".join(parts) if parts else ""


def link_depth(hand: Hand, obj: ObjectModel, q: NDArray, T_palm_object: NDArray, finger: str) -> float:
    """The least distance (m, < 0: inside) from `finger`'s collision spheres at `q` (n,) rad to the object
    at `T_palm_object` (4, 4) (exact signed distance less the sphere radii)."""
    R, t = np.asarray(T_palm_object, float)[:3, :3], np.asarray(T_palm_object, float)[:3, 3]
    links = (np.asarray(hand.sphere_centers(q, finger), float).reshape(-1, 3) - t) @ R
    return float(np.min(obj.exact_signed_distance(links) - hand.sphere_radii(finger)))


def reach_obstruction(hand: Hand, obj: ObjectModel, q: NDArray, T_palm_object: NDArray,
                      goal_tip_object: NDArray, finger: str, q_goal: NDArray | None = None) -> str:
    """What keeps `finger` from its goal tip centre `goal_tip_object` (3,), object frame, m, at the grasp
    (`q` (n,) rad, `T_palm_object` (4, 4)), by its IK there (`tip_ik.finger_reach_ik`, the other fingers
    where they are; `q_goal` (n,) rad a further start): "reach" (out of its reach), "object" (reached
    only with a link in the object, `link_depth`), "finger" (only through another finger or the palm,
    `blocker`) or "" (nothing)."""
    R, t = np.asarray(T_palm_object, float)[:3, :3], np.asarray(T_palm_object, float)[:3, 3]
    goal_palm = R @ np.asarray(goal_tip_object, float) + t
    q_reach, e = finger_reach_ik(hand, np.asarray(q, float), finger, goal_palm, [q_goal], tol=REACH_TOL)
    return ik_obstruction(hand, obj, q_reach, e, T_palm_object, finger)


def ik_obstruction(hand: Hand, obj: ObjectModel, q_reach: NDArray, e: NDArray, T_palm_object: NDArray,
                   finger: str) -> str:
    """What an IK result of `finger` at its goal (`q_reach` (n,) rad, tip error `e` (3,) m; object at
    `T_palm_object` (4, 4)) says keeps it from there: "reach" (the error above `REACH_TOL`), "object"
    (a link in the object, `link_depth`), "finger" (another finger or the palm in the way, `blocker`) or
    "" (nothing)."""
    if float(np.linalg.norm(e)) > REACH_TOL:
        return "reach"
    if link_depth(hand, obj, q_reach, T_palm_object, finger) < 0.0:
        return "object"
    return "finger" if blocker(hand, q_reach, finger) is not None else ""


def reached_through_others(hand: Hand, q: NDArray, T_palm_object: NDArray, goal_tips_object: NDArray,
                           contact_error: NDArray, zeta: float, q_goal: NDArray | None = None) -> bool:
    """Whether a finger farther than `zeta` (m) from its goal reaches it at this object pose (`q` (n,) rad,
    `T_palm_object` (4, 4)) only through another finger or the palm (`through_others`, at its
    `tip_ik.finger_reach_ik` posture; `goal_tips_object` (m, 3), object frame, m)."""
    R, t = np.asarray(T_palm_object, float)[:3, :3], np.asarray(T_palm_object, float)[:3, 3]
    for r, finger in enumerate(hand.fingers):
        if contact_error[r] <= zeta:
            continue
        q_reach, e = finger_reach_ik(hand, np.asarray(q, float), finger, R @ goal_tips_object[r] + t,
                                     [q_goal], tol=REACH_TOL)
        if float(np.linalg.norm(e)) <= REACH_TOL and through_others(hand, q_reach, finger):
            return True
    return False


def through_others(hand: Hand, q_reach: NDArray, finger: str,
                   reaches: str = "at this object pose its tip reaches the goal") -> list[str]:
    """["<reaches> only through the <other> finger (...)"] when the finger's collision spheres overlap
    another finger's or the palm's at `q_reach` (n,) rad (its reach posture, the other fingers where they
    are), else []: the other finger, or the object's pose, must move first (measured: the generated
    sphere pair of seed 19, SD, stalled with the middle 10.2 mm from its goal, which it reached only
    through the index, 13.0 mm deep)."""
    hit = blocker(hand, q_reach, finger)
    if hit is None:
        return []
    name = "palm" if hit[0] is None else f"{hit[0]} finger"
    return [f"{reaches} only through the {name} (its collision spheres overlap {hit[1] * 1e3:.1f} mm)"]


def blocker(hand: Hand, q: NDArray, finger: str) -> tuple[str | None, float] | None:
    """(the other finger, None for the palm; the overlap, m > 0) of the deepest overlap of `finger`'s
    collision spheres with another body's at `q` (n,) rad, or None when they overlap none."""
    pairs = hand.self_collision_pairs(finger)
    if not pairs:
        return None
    gaps = hand.self_collision_distances(q, pairs)
    k = int(np.argmin(gaps))
    if gaps[k] >= 0.0:
        return None
    a, b = (hand.spheres[i] for i in pairs[k])
    return (b.finger if a.finger == finger else a.finger), -float(gaps[k])


def _best_gain(obj: ObjectModel, tip_object: NDArray, goal_tip_object: NDArray, eta: float) -> float:
    """How much nearer (m) the goal contact (the closest point of `goal_tip_object` (3,)) the surface point
    within `eta` (m) of the contact (the closest point of `tip_object` (3,)) nearest it is: over the
    vertices of the mesh subdivided to eta / 5 (object frame)."""
    import trimesh  # (only when a plan stalls)

    (contact, goal), _ = obj.closest_points(np.stack([tip_object, goal_tip_object]))
    triangles = np.asarray(obj.mesh.triangles, float)
    on_face = trimesh.triangles.closest_point(triangles, np.repeat(contact[None], len(triangles), axis=0))
    faces = np.asarray(obj.mesh.faces)[np.linalg.norm(on_face - contact, axis=1) <= eta]  # those within η
    v, _ = trimesh.remesh.subdivide_to_size(np.asarray(obj.mesh.vertices, float), faces, max_edge=eta / 5.0)
    near = v[np.linalg.norm(v - contact, axis=1) <= eta]
    if not len(near):
        return 0.0
    return float(np.linalg.norm(contact - goal) - np.min(np.linalg.norm(near - goal, axis=1)))
