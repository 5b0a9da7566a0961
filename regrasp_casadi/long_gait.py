"""Finger gaits warm started at the finger's goal, or aimed along the way over the surface: the paper
planner's way out of a stalled finger whose goal its own links, an edge or a wall keep OPT1 from
approaching by η-steps.

OPT1 is local: from the finger's joints it lowers the tip's distance to its goal by at most η per gait,
so a finger whose straight way to the goal is blocked — a link held near the object (no worse than at
its start), the tip sphere cutting an edge or a rim on the way — stops in a local minimum of OPT1 with
the goal still reachable at the current object pose (measured: mug seed 2 sd, the ring 22.6 mm from its
goal tip centre with the object at the desired pose; three gaits of η/2, η and 2η each moved the tip
0.01 mm). `long_gait` solves OPT1 (the same NLP and step bound η) from other joints: first the
finger's IK at the goal itself, then about η of tip travel along the joint-space line from the
finger's joints to that IK (`tip_ik.finger_reach_ik`, the links ignored: from the finger's joints, else
from the goal grasp's, else from mid-range), which go around what the tip's straight line runs into
(measured: the mug pair of seed 1, svd, ring 41.5 mm from its goal: from its joints and from part of the
way OPT1 moved it η with a transit 0.11 mm closer to the mug than its floor; from the IK, clear).
When the object itself lies between the tip and its goal (a contact inside a bowl whose goal is
outside), `surface_gait` aims OPT1 at the way point η ahead on the way over the surface
(`surface_way.SurfaceWay`: over the rim). The gaits' exact checks and their lift-off / transit /
touch-down paths (`certified_round.accept_gait`) judge them like any other gait.

    >>> moved = long_gait(run, "ring")        # run: the planner's `_Run`, stalled
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.certified_round import accept_gait
from regrasp_casadi.stall_report import REACH_TOL
from regrasp_casadi.surface_way import SurfaceWay
from regrasp_casadi.tip_ik import finger_reach_ik

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.planner import _Run

__all__ = ["long_gait", "surface_gait", "way_target", "SurfaceProgress", "MIN_WAY"]

MIN_WAY = 0.001
"""Least shortening (m) of a finger's way to its goal over the surface for a surface gait to count."""


def long_gait(run: _Run, finger: str) -> bool:
    """One gait of `finger` towards its goal tip centre, started at its IK there at the current object
    pose, else from the joints a part of the way to that IK (see the module docstring); when neither is
    taken and the object lies between the finger's tip and its goal, one gait along the way over the
    surface (`surface_gait`, which needs no reach of the goal). True when a gait is taken. The IK starts
    are not tried when the goal is out of the finger's reach at this pose (its IK,
    `tip_ik.finger_reach_ik`, ends farther than `stall_report.REACH_TOL`)."""
    r, hand, T = run.fingers.index(finger), run.hand, run.T_palm_object
    goal_object = run.goal_tips[r]
    way = float(np.linalg.norm(goal_object - run.tips_object()[r]))
    if way <= 0.0:
        return False
    q_goal, e = finger_reach_ik(hand, run.q, finger, T[:3, :3] @ goal_object + T[:3, 3], [run.q_goal],
                                tol=REACH_TOL)  # from its joints, else the goal grasp's, else mid-range
    eta = run.options.finger_gait.eta
    starts = (q_goal, run.q + min(1.0, eta / way) * (q_goal - run.q))  # at its IK, then η on the way
    for q_init in starts if float(np.linalg.norm(e)) <= REACH_TOL else ():
        res = _solve(run, finger, goal_object, q_init)
        contact, _ = run.obj.closest_points(res.p_object_tip[None])
        closer = np.linalg.norm(contact[0] - run.goal_contacts[r]) < run.steps[-1].contact_error[r]
        if res.success and closer and accept_gait(run, finger, res):
            return True
    line = run.tips_object()[r] + np.linspace(0.0, 1.0, 41)[:, None] * (goal_object - run.tips_object()[r])
    return bool(np.min(run.obj.exact_signed_distance(line)) < 0.0) and surface_gait(run, finger)


def _solve(run: _Run, finger: str, p_object_tip_goal: NDArray, q_init: NDArray | None = None):
    """OPT1 of `finger` towards `p_object_tip_goal` (3,), object frame, m, from `q_init` (n,) rad, with
    its time and solves counted in `run`."""
    res = run.gait_nlps[finger].solve(run.q, run.T_palm_object, p_object_tip_goal, q_init=q_init)
    run.timing["opt1"] += res.solve_time
    run.solves["opt1"] += res.solves
    return res


@dataclass
class SurfaceProgress:
    """A plan's ways over the surface (`_Run.surface`): the object's `SurfaceWay`, each finger's distance
    field to its goal contact and the shortest way to it a surface gait has left, and whether a surface
    gait got a finger nearer its goal than before since the planner last asked (`made_way`)."""

    way: SurfaceWay
    fields: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    best: dict[str, float] = field(default_factory=dict)
    made_way: bool = False

    def take_made_way(self) -> bool:
        """Whether a surface gait made way since the last call (and forget it)."""
        made, self.made_way = self.made_way, False
        return made


def surface_gait(run: _Run, finger: str) -> bool:
    """One gait of `finger` aimed at a way point η ahead of its contact on the way over the surface to its
    goal contact (`way_target`: a mesh point within η of the contact over the surface, nearest the goal
    by the distance over the surface; the tip-centre target ρ above it along its normal), taken
    when it brings the contact at least `MIN_WAY` nearer the goal over the surface and its path passes
    (`certified_round.accept_gait`). A gait that leaves the finger nearer its goal over the surface than any
    before it sets `made_way` (progress for the planner's stall count)."""
    if run.surface is None:
        run.surface = SurfaceProgress(SurfaceWay(run.obj.mesh))
    sp, r = run.surface, run.fingers.index(finger)
    to_goal = sp.fields.get(finger)
    if to_goal is None:
        to_goal = sp.fields[finger] = sp.way.field(run.goal_contacts[r])
    contact = np.asarray(run.steps[-1].contacts_object[r], dtype=float)
    here = sp.way.distance(to_goal, contact)
    target = way_target(sp.way, run.obj, to_goal, contact, run.goal_tips[r],
                        reach=run.options.finger_gait.eta, tip_radius=run.hand.tip_radius)
    res = _solve(run, finger, target)
    if not res.success:
        return False
    moved, _ = run.obj.closest_points(res.p_object_tip[None])
    there = sp.way.distance(to_goal, moved[0])
    if there > here - MIN_WAY or not accept_gait(run, finger, res):
        return False
    if there < sp.best.get(finger, here) - MIN_WAY:
        sp.made_way = True
    sp.best[finger] = min(there, sp.best.get(finger, here))
    return True


def way_target(way: SurfaceWay, obj: ObjectModel, to_goal: NDArray, contact: NDArray, goal_tip: NDArray, *,
               reach: float, tip_radius: float) -> NDArray[np.float64]:
    """The tip-centre target (3,), object frame, m, of a surface gait from the surface point `contact`
    (3,): `tip_radius` along the normal above the mesh vertex within `reach` (m) of it over the surface
    nearest the goal by `to_goal` (`SurfaceWay.field`), among those at least `MIN_WAY` nearer than
    `contact` from whose tip centre the straight line to `goal_tip` (3,) stays out of the object, if any
    (over the rim first: on a bowl the way along the inner face and then over the rim is as long as over
    the rim and along the outer face, and only the second leaves OPT1 a straight pull to a goal
    outside); else the nearest of all (`SurfaceWay.way_point`)."""
    ids = way.within(contact, reach)
    tips = way.mesh.vertices[ids] + tip_radius * way.mesh.vertex_normals[ids]
    s = np.linspace(0.0, 1.0, 21)[1:-1, None]
    lines = tips[:, None, :] + s[None] * (goal_tip - tips)[:, None, :]
    free = np.min(obj.exact_signed_distance(lines.reshape(-1, 3)).reshape(len(ids), -1), axis=1) > 0.0
    free &= to_goal[ids] <= way.distance(to_goal, contact) - MIN_WAY
    pick = ids[free] if np.any(free) else ids
    k = int(pick[np.argmin(to_goal[pick])])
    return way.mesh.vertices[k] + tip_radius * way.mesh.vertex_normals[k]
