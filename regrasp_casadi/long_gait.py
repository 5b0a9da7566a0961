"""A finger gait warm started at the finger's goal: the paper planner's way out of a stalled finger whose
goal its own links or an edge keep OPT1 from approaching by η-steps.

OPT1 is local: from the finger's joints it lowers the tip's distance to its goal by at most η per gait,
so a finger whose straight way to the goal is blocked — a link held near the object (no worse than at
its start), the tip sphere cutting an edge or a rim on the way — stops in a local minimum of OPT1 with
the goal still reachable at the current object pose (measured: mug seed 2 sd, the ring 22.6 mm from its
goal tip centre with the object at the desired pose; three gaits of η/2, η and 2η each moved the tip
0.01 mm). `long_gait` solves OPT1 (the same NLP and step bound η) from other joints: first the
finger's IK at the goal itself, then about η of tip travel along the joint-space line from the
finger's joints to that IK (`tip_ik.finger_reach_ik`, the links ignored: from the finger's joints, else
from the goal grasp's, else from mid-range), which go around what the tip's straight line runs into
(measured: the mug pair of seed 1, svd, the ring 41.5 mm from its goal: from its joints and from part of
the way OPT1 moved it η with a transit 0.11 mm closer to the mug than its floor; from the IK, clear).
The gait's exact checks and its lift-off / transit / touch-down path (`certified_round.accept_gait`)
judge it like any other gait.

    >>> moved = long_gait(run, "ring")        # run: the planner's `_Run`, stalled
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from regrasp_casadi.certified_round import accept_gait
from regrasp_casadi.stall_report import REACH_TOL
from regrasp_casadi.surface_route import nearer_goal
from regrasp_casadi.tip_ik import finger_reach_ik

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.planner import _Run

__all__ = ["long_gait", "reach_at_goal"]


def long_gait(run: _Run, finger: str) -> bool:
    """One gait of `finger` towards its goal tip centre, started at its IK there at the current object
    pose, else from the joints a part of the way to that IK (see the module docstring); True when a gait
    that brings its contact closer to its goal is taken (along the surface where the finger takes a
    surface route: `surface_route.nearer_goal`). Not tried (False) when the goal is out of the
    finger's reach at this pose (its IK, `tip_ik.finger_reach_ik`, ends farther than
    `stall_report.REACH_TOL`)."""
    r, T = run.fingers.index(finger), run.T_palm_object
    goal_object = run.goal_tips[r]
    way = float(np.linalg.norm(goal_object - run.tips_object()[r]))
    if way <= 0.0:
        return False
    q_goal, e = reach_at_goal(run, finger)
    if float(np.linalg.norm(e)) > REACH_TOL:
        return False
    eta = run.options.finger_gait.eta
    # at its IK, then about η of the way there (within η of the goal, that start is the IK itself)
    starts = [q_goal] if way <= eta else [q_goal, run.q + eta / way * (q_goal - run.q)]
    for q_init in starts:
        res = run.gait_nlps[finger].solve(run.q, T, goal_object, q_init=q_init)
        run.timing["opt1"] += res.solve_time
        run.solves["opt1"] += res.solves
        if res.success and nearer_goal(run, r, res.p_object_tip) and accept_gait(run, finger, res):
            return True
    return False


def reach_at_goal(run: _Run, finger: str) -> tuple[np.ndarray, np.ndarray]:
    """`finger`'s IK at its goal tip centre at the run's object pose (`tip_ik.finger_reach_ik`, the links
    ignored: from its joints, else the goal grasp's, else mid-range): q (n,) rad, the other fingers where
    they are, and the tip error (3,), palm frame, m."""
    T = run.T_palm_object
    goal = T[:3, :3] @ run.goal_tips[run.fingers.index(finger)] + T[:3, 3]
    return finger_reach_ik(run.hand, run.q, finger, goal, [run.q_goal], tol=REACH_TOL)
