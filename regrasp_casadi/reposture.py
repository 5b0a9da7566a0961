"""Re-posture gaits: a finger put back on its goal contact in the goal grasp's posture, when the final
moves stop short of the desired object pose.

A finger of the Allegro hand reaches a point with a one-parameter family of postures (three flexion
joints for a point in the finger's plane), and the planner's gaits keep the posture they start from:
OPT1 is local, so a finger that came to its goal contact bent at its distal joint stays bent, where the
goal grasp has it straight. The contacts are then within ζ of their goals but the hand is not in the
goal grasp's configuration, and the final moves (OPT2 towards the desired pose, the contacts held)
stall against a joint limit of such a finger: measured on the generated objects, ten pairs per class,
SVD, paper planner (`benchmarks/objects.py`), mug seeds 5 and 9 and flat tool seed 8 ended
"pose_not_reached" 4.85 mm / 9.95°, 2.75 mm / 1.89° and 9.53 mm / 6.14° from the desired pose, each
with one finger 0.96–1.81 rad from its goal posture at a joint (mug 9: the ring's third joint at its
lower limit, the final moves gaining 0.04 mm per move). Turning the finger in place is not a way out:
its tip would slide its material over the object by ρ θ (`grasp_metrics.tip_slip`).

`reposture_round` lifts each such finger (largest posture difference first) and puts it down on its
goal contact again (OPT1 towards the goal tip centre, started at the finger's IK there from the goal
grasp's joints, `tip_ik.finger_reach_ik`), a gait like any other: its exact checks, its lift-off /
transit / touch-down path (`certified_round.accept_gait`) and, with stability on, a certified holding
set while it is lifted. The planner then runs the final moves again (`planner._iterate`; the rounds come
after `_polish`'s, which on the paper benchmark leaves 29 of its 50 plans as they were, against 24
with the rounds first). Measured on one machine, back to back (`benchmarks/README.md`): mug seed 5
and flat tool seed 8 (SVD) converge with it, 111 of the generated classes' 120 plans against 109.

Two bent fingers can jam: each, in the goal's posture, overlaps the other where it is (measured: the
generated mug pair of seed 9, svd, the ring and the middle, 1.1 and 0.2 mm into each other's collision
spheres; the goal grasp has them 1.0 mm apart). Without stability, a finger whose re-posture gait is
refused so has that neighbour move its contact aside first, within ζ of its goal
(`make_way.move_aside`), and is tried again; the mug pair then converges (0.18 mm / 0.23° from the
desired pose, against "pose_not_reached" 2.35 mm / 1.33°).

A finger whose goal posture at this object pose is out of reach, has a link in the object, or is no
nearer the goal's than its posture now (`posture_obstruction`) has the object reposed first, towards
the desired pose or a turned or shifted pose until that posture is clear (`free_finger.reposed_until`)
in the round `freeing` asks for (`final_rounds.free_postures`: once, for a plan that does not converge
without it, from where the rounds first moved no finger; without stability; `PlannerOptions.free_after`
None turns it off). Measured: the generated bowl
pair of seed 19 (SVD) ended "pose_not_reached" 27.5 mm / 14.1° from the desired pose, the middle's goal
posture out of reach, the ring's and the thumb's no nearer; with that round the ring and the thumb are
re-postured after the object's moves, and the plan converges (0.11 mm / 0.07°).

    >>> moved = reposture_round(run, outcome)  # run: the planner's `_Run`; outcome: its final moves'
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from regrasp_casadi.certified_round import accept_gait
from regrasp_casadi.final_moves import SETTLED_STOPS
from regrasp_casadi.free_finger import reposed_until
from regrasp_casadi.make_way import move_aside
from regrasp_casadi.stall_report import REACH_TOL, ik_obstruction, through_others
from regrasp_casadi.tip_ik import finger_reach_ik

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.final_moves import FinalMoves
    from regrasp_casadi.planner import _Run

__all__ = ["POSTURE_TOL", "POSTURE_GAIN", "posture_distance", "reposture_round", "posture_report"]

POSTURE_TOL = 0.3
"""A finger whose joints are farther than this from the goal grasp's (largest joint difference) is
re-postured, rad."""
POSTURE_GAIN = 0.1
"""A re-posture gait is taken only when it brings the finger's largest joint difference from the goal
grasp's down by at least this much, rad."""


def posture_distance(run: _Run, q: np.ndarray, finger: str) -> float:
    """Largest |q_j − q_goal_j| over `finger`'s joints (q (n,) rad against the goal grasp's), rad."""
    idx = run.hand.finger_joints[finger]
    return float(np.max(np.abs(q[idx] - run.q_goal[idx])))


def reposture_round(run: _Run, outcome: FinalMoves, freeing: bool = False) -> bool:
    """After final moves that stopped short of the desired pose (`outcome`), one re-posture gait for
    every finger farther than `POSTURE_TOL` from the goal grasp's posture, the farthest first, with the
    object reposed for it first where its goal posture is obstructed when `freeing` (see the module
    docstring); True when one was taken (an iteration of the run's own: the planner's loop ends
    within `max_iters`). Nothing is tried without the goal grasp's joints or iterations left."""
    if (outcome.stop in SETTLED_STOPS or run.q_goal is None
            or run.iterations >= run.options.max_iters):
        return False
    far = {f: posture_distance(run, run.q, f) for f in run.fingers}
    moved = False
    for finger in sorted((f for f in far if far[f] > POSTURE_TOL), key=lambda f: -far[f]):
        if _reposture(run, finger):
            moved = True
        elif run.holding is None and move_aside(run, finger, _goal_posture_ik(run, finger)[0]):
            moved = True  # a neighbour in the way moved aside (uncertified: without stability only)
            _reposture(run, finger)
        elif freeing and run.holding is None and _freed_reposture(run, finger):
            moved = True  # the object reposed until the goal posture was clear, then the gait
    if moved:
        run.iterations += 1
        run.errors.append(float(np.mean(run.steps[-1].contact_error)))
    return moved


def _reposture(run: _Run, finger: str) -> bool:
    """The re-posture gait of `finger`; True when it was taken. Not tried when the goal tip centre is out
    of reach from the goal grasp's joints at this object pose, or that IK is no nearer the goal posture;
    with stability on, when the other fingers do not hold the object without it."""
    r, T = run.fingers.index(finger), run.T_palm_object
    certificate = None
    if run.holding is not None:
        certificate = run.holding.lift(run.q, T, finger)
        if not run.holding.certified(certificate):
            return False
    before = posture_distance(run, run.q, finger)
    q_init, e = _goal_posture_ik(run, finger)
    if float(np.linalg.norm(e)) > REACH_TOL or posture_distance(run, q_init, finger) > before - POSTURE_GAIN:
        return False
    res = run.gait_nlps[finger].solve(run.q, T, run.goal_tips[r], q_init=q_init)
    run.timing["opt1"] += res.solve_time
    run.solves["opt1"] += res.solves
    if not res.success or posture_distance(run, res.q, finger) > before - POSTURE_GAIN:
        return False
    contact, _ = run.obj.closest_points(res.p_object_tip[None])
    if float(np.linalg.norm(contact[0] - run.goal_contacts[r])) > run.options.zeta:
        return False
    return accept_gait(run, finger, res, certificate)


def _freed_reposture(run: _Run, finger: str) -> bool:
    """Repose the object towards other poses until `finger`'s goal posture at its goal is clear
    (`posture_obstruction`), then its re-posture gait (`free_finger.reposed_until`); True when the gait
    was taken. Not tried when only another finger is in the way (`move_aside`'s case) or
    `PlannerOptions.free_after` is None."""
    if run.options.free_after is None:
        return False
    if posture_obstruction(run, finger, run.q, run.T_palm_object) in ("", "finger"):
        return False
    return reposed_until(run, lambda q, T: posture_obstruction(run, finger, q, T),
                         lambda: _reposture(run, finger))


def posture_obstruction(run: _Run, finger: str, q: np.ndarray, T_palm_object: np.ndarray) -> str:
    """What keeps `finger`'s re-posture gait from the grasp (`q` (n,) rad, `T_palm_object` (4, 4)):
    "reach" (its goal out of reach from the goal grasp's joints), "object" (reached with a link in the
    object), "finger" (through another finger; these three by `stall_report.ik_obstruction`),
    "posture" (the IK no nearer the goal posture by `POSTURE_GAIN`) or "" (nothing)."""
    q_init, e = _goal_posture_ik(run, finger, q, T_palm_object)
    why = ik_obstruction(run.hand, run.obj, q_init, e, T_palm_object, finger)
    if why:
        return why
    if posture_distance(run, q_init, finger) > posture_distance(run, q, finger) - POSTURE_GAIN:
        return "posture"
    return ""


def _goal_posture_ik(run: _Run, finger: str, q: np.ndarray | None = None,
                     T_palm_object: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """`finger`'s IK at its goal tip centre (object pose `T_palm_object` (4, 4), default the run's),
    started from the goal grasp's joints (`tip_ik.finger_reach_ik`): q (n,) rad, the other fingers as in
    `q` (default the run's), and the tip error (3,) m."""
    r = run.fingers.index(finger)
    T = run.T_palm_object if T_palm_object is None else T_palm_object
    q_start = (run.q if q is None else q).copy()
    idx = run.hand.finger_joints[finger]
    q_start[idx] = run.q_goal[idx]
    return finger_reach_ik(run.hand, q_start, finger, T[:3, :3] @ run.goal_tips[r] + T[:3, 3], tol=REACH_TOL)


def posture_report(run: _Run) -> str:
    """"; bent unlike the goal grasp: <finger> <gap> rad (<why>) | ..." for the fingers farther than
    `POSTURE_TOL` from the goal grasp's posture, for a plan whose final moves stopped short of the desired
    pose ("" without the goal grasp's joints or such a finger). Why a re-posture gait could not put one
    back: in the goal's posture its tip does not reach its goal at this object pose, or it reaches it only
    through another finger (`stall_report.through_others`): measured on the generated mug pair of seed 9
    and cup pair of seed 3 (svd), the ring and the middle each overlap the other in the goal's posture
    while the other is bent (mug: 1.1 and 0.2 mm), where the goal grasp has the two 1.0 mm apart. The
    claim is the sphere model's, which the planner plans with: on the vendor link meshes (python-fcl) the
    ring of `tests/data/mug_ring_bent_at_goal.yaml`, whose spheres overlap the middle's 3.4 mm in the
    goal's posture, is 1.06 mm from it (the cover is conservative)."""
    if run.q_goal is None:
        return ""
    parts = []
    for finger in run.fingers:
        gap = posture_distance(run, run.q, finger)
        if gap <= POSTURE_TOL:
            continue
        q_init, e = _goal_posture_ik(run, finger)
        why = through_others(run.hand, q_init, finger, "in the goal's posture its tip reaches the goal")
        if float(np.linalg.norm(e)) > REACH_TOL:
            why = ["in the goal's posture its tip does not reach the goal at this object pose"]
        parts.append(f"{finger} {gap:.2f} rad" + (f" ({why[0]})" if why else ""))
    return "; bent unlike the goal grasp: " + " | ".join(parts) if parts else ""
