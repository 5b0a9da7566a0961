"""Making way: a stalled finger whose goal another finger is in the way of, reached after that finger
moves its contact aside, within ζ of its own goal.

A finger's reach posture at its goal (`tip_ik.finger_reach_ik`) can run through a neighbour that sits on
its own goal contact: the stall report then says "reaches the goal only through the middle finger"
(`stall_report.through_others`) and OPT1, which keeps the fingers `self_clearance` apart, stops short
(measured: the generated mug pair of seed 16, both methods, stalled with the ring 37 mm from its goal,
its reach posture 0.3 mm into the middle's collision spheres). Nothing in the gait rounds moves the
neighbour: it is at its goal. `make_way` moves it: a gait of the neighbour (OPT1 started at its IK there)
to the surface point, among `WAY_DISTANCES` × `WAY_DIRECTIONS` around its contact and within ζ of its
goal contact, where it is clearest of the stalled finger's reach posture (at least `self_clearance`);
then the stalled finger's `long_gait`. Both are gaits like any other: their exact checks and their
lift-off / transit / touch-down paths (`certified_round.accept_gait`). The neighbour's contact stays
within ζ of its goal, so the plan can still converge with it there; the gait rounds bring it back
towards its goal as far as the fingers' clearance lets them. `move_aside` alone also serves the
re-posture gaits (`reposture`): a finger whose goal posture runs through a neighbour.

    >>> moved = make_way(run, "ring")        # run: the planner's `_Run`, stalled, without stability
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from regrasp_casadi.certified_round import accept_gait
from regrasp_casadi.long_gait import long_gait, reach_at_goal
from regrasp_casadi.stall_report import REACH_TOL, blocker
from regrasp_casadi.surface_route import surface_targets
from regrasp_casadi.tip_ik import finger_reach_ik

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.planner import _Run

__all__ = ["WAY_DISTANCES", "WAY_DIRECTIONS", "make_way", "move_aside"]

WAY_DISTANCES = (0.002, 0.004)
"""How far the neighbour's contact is moved, m (tried together: the clearest point is taken)."""
WAY_DIRECTIONS = 8
"""Directions of the tangent plane tried at each distance."""


def make_way(run: _Run, finger: str) -> bool:
    """Move the finger that `finger`'s reach posture at its goal runs through aside, then `long_gait`
    (see the module docstring); True when `finger` took a gait. Not tried (False) when its goal is out
    of reach at this object pose, or `move_aside` moves nothing."""
    q_reach, e = reach_at_goal(run, finger)
    if float(np.linalg.norm(e)) > REACH_TOL:
        return False
    return move_aside(run, finger, q_reach) and long_gait(run, finger)


def move_aside(run: _Run, finger: str, q_reach: np.ndarray) -> bool:
    """The gait that moves the finger whose collision spheres `finger`'s at `q_reach` (n,) rad overlap
    most (`stall_report.blocker`) to the surface point around its contact, within ζ of its goal, where it
    is clearest of them (at least the self-clearance; see the module docstring); True when it was taken.
    Nothing is moved when `q_reach` overlaps no other finger (or only the palm) or no point clears it."""
    hit = blocker(run.hand, q_reach, finger)
    if hit is None or hit[0] is None:
        return False
    other = hit[0]
    way = _clearest_aside(run, finger, other, q_reach)
    if way is None:
        return False
    tip, q_init = way
    res = run.gait_nlps[other].solve(run.q, run.T_palm_object, tip, q_init=q_init)
    run.timing["opt1"] += res.solve_time
    run.solves["opt1"] += res.solves
    if not res.success:
        return False
    b = run.fingers.index(other)
    contact, _ = run.obj.closest_points(res.p_object_tip[None])
    if float(np.linalg.norm(contact[0] - run.goal_contacts[b])) > run.options.zeta:
        return False
    return accept_gait(run, other, res)


def _clearest_aside(run: _Run, finger: str, other: str, q_reach: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray] | None:
    """The tip centre (3,), object frame, m, and the IK joints (n,) rad of `other` at the surface point
    around its contact, within ζ of its goal contact, where its collision spheres are farthest from
    `finger`'s at `finger`'s reach posture `q_reach` (n,) rad, if that is at least the self-clearance."""
    hand, T, b = run.hand, run.T_palm_object, run.fingers.index(other)
    pairs = [p for p in hand.self_collision_pairs(finger)
             if other in (hand.spheres[p[0]].finger, hand.spheres[p[1]].finger)]
    joints = hand.finger_joints[other]
    floor = run.options.finger_gait.self_clearance or 0.0
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    tip_now = run.tips_object()[b]
    for distance in WAY_DISTANCES:
        tips, contacts, _ = surface_targets(run.obj, float(hand.tip_radius), tip_now, run.goal_tips[b],
                                            distance, WAY_DIRECTIONS)
        for tip, contact in zip(tips, contacts, strict=True):
            if float(np.linalg.norm(contact - run.goal_contacts[b])) > run.options.zeta:
                continue
            q_other, e = finger_reach_ik(hand, run.q, other, T[:3, :3] @ tip + T[:3, 3], tol=REACH_TOL)
            if float(np.linalg.norm(e)) > REACH_TOL:
                continue
            q_both = q_reach.copy()
            q_both[joints] = q_other[joints]
            gap = float(np.min(hand.self_collision_distances(q_both, pairs)))
            if gap >= floor and (best is None or gap > best[0]):
                best = (gap, tip, q_other)
    return None if best is None else (best[1], best[2])
