"""Freeing a finger: reposings, all four fingers on, that move the object until a stalled finger's goal is
within its reach with its links clear of the object, then that finger's `long_gait`.

A finger can stall because its goal is out of its reach at the object's pose, or reached only with one of
its links in the object (`stall_report`: "reaches the goal only with a link 3.2 mm in the object").
The stall escape reposes the object towards the desired pose, where the goal grasp is feasible, but the
grasp on the way can keep it from getting there (measured: the generated bowl pair of seed 7, SD,
stalled with the thumb 28 mm from its goal, reached only with a link 3.0–3.2 mm in the bowl, through 10
iterations of escapes). Other object poses free the finger: the desired pose, then a turn of
`FREE_TURN` about each palm axis and a shift of `FREE_SHIFT` along it, each way. `free_finger` makes up
to `FREE_MOVES` OPT2 moves (the SVD NLP towards each of these poses, its trust region bounding each move)
and after each asks the finger's IK at its goal (`stall_report.reach_obstruction`); at the first pose
where nothing obstructs it, the moves become reposing steps (their paths computed and checked in
order, `_Run.unrealisable`) and the finger takes `long_gait`. If a path fails or the gait is not taken,
the run is put back as it was, and the next pose is tried.

Every step it adds is a plain reposing or gait, judged as any other (the NLPs' exact checks, the paths'
checks, `verify`). A finger that another finger's links are in the way of is not this function's case:
moving the object moves both goals (`make_way` moves the other finger).

    >>> freed = free_finger(run, "thumb")        # run: the planner's `_Run`, stalled, without stability
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.long_gait import long_gait
from regrasp_casadi.stall_report import reach_obstruction
from regrasp_casadi.transforms import make_T, rot_axis_angle

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.planner import _Run

__all__ = ["FREE_MOVES", "FREE_SHIFT", "FREE_TURN", "free_finger", "freeing_poses", "reposed_until"]

FREE_TURN = 0.5
"""Turn of the candidate poses about each palm axis, rad."""
FREE_SHIFT = 0.03
"""Shift of the candidate poses along each palm axis, m."""
FREE_MOVES = 6
"""OPT2 moves made towards each candidate pose (each within OPT2's trust region)."""


def freeing_poses(T_palm_object: NDArray, T_palm_object_goal: NDArray) -> list[NDArray]:
    """The object poses (4, 4), palm frame, m, `free_finger` moves towards, in order: the desired pose
    `T_palm_object_goal`, then for each palm axis x, y, z the current pose `T_palm_object` turned by
    −/+`FREE_TURN` about it (about the object's origin) and shifted by −/+`FREE_SHIFT` along it."""
    R, t = np.asarray(T_palm_object, float)[:3, :3], np.asarray(T_palm_object, float)[:3, 3]
    poses = [np.asarray(T_palm_object_goal, float)]
    for axis in np.eye(3):
        poses += [make_T(rot_axis_angle(axis, sign * FREE_TURN) @ R, t) for sign in (-1.0, 1.0)]
        poses += [make_T(R, t + sign * FREE_SHIFT * axis) for sign in (-1.0, 1.0)]
    return poses


def free_finger(run: _Run, finger: str) -> bool:
    """Repose the object until `finger`'s goal is within its reach with its links clear of the object,
    then take its `long_gait` (see the module docstring); True when the gait was taken. Not tried (False)
    when its goal is already reached cleanly at this pose, or only through another finger."""
    goal_tip = run.goal_tips[run.fingers.index(finger)]

    def obstruction(q: NDArray, T_palm_object: NDArray) -> str:
        return reach_obstruction(run.hand, run.obj, q, T_palm_object, goal_tip, finger, run.q_goal)

    if obstruction(run.q, run.T_palm_object) in ("", "finger"):
        return False
    return reposed_until(run, obstruction, lambda: long_gait(run, finger))


def reposed_until(run: _Run, obstruction: Callable[[NDArray, NDArray], str], then: Callable[[], bool]
                  ) -> bool:
    """Towards each of `freeing_poses` in turn, up to `FREE_MOVES` OPT2 moves (the SVD NLP, each from the
    last) until `obstruction(q, T_palm_object)` ((n,) rad, (4, 4)) is "" after one; then those moves
    become reposing steps (`_take`) and `then()` is called; True when it returns True. Otherwise the
    run's steps, joints and object pose are put back as they were and the next pose is tried."""
    n_steps, q0, T0 = len(run.steps), run.q, run.T_palm_object
    for T_target in freeing_poses(T0, run.T_palm_object_goal):
        moves = _moves_until_clear(run, obstruction, T_target)
        if moves and _take(run, moves) and then():
            return True
        del run.steps[n_steps:]  # back to the grasp it started from
        run.q, run.T_palm_object = q0, T0
    return False


def _moves_until_clear(run: _Run, obstruction: Callable[[NDArray, NDArray], str], T_target: NDArray
                       ) -> list:
    """Up to `FREE_MOVES` OPT2 solves (the SVD NLP) from the run's grasp towards `T_target`, each from the
    last: the solves up to the first after which `obstruction` is "", [] when there is none (or a solve
    fails first). The run's grasp is not changed."""
    q, T = run.q, run.T_palm_object
    moves = []
    for _ in range(FREE_MOVES):
        res = run.svd_nlp.solve(q, T, run.tips_object(q, T), T_target=T_target)
        run.timing["opt2"] += res.solve_time
        run.solves["opt2"] += 1
        if not res.success:
            return []
        moves.append(res)
        q, T = res.q, res.T_palm_object
        if not obstruction(q, T):
            return moves
    return []


def _take(run: _Run, moves: list) -> bool:
    """Add `moves` (OPT2 results, each from the last) as reposing steps, each once its certificate and its
    path from the step before pass (`_Run.take_repose`); False at the first that fails (the steps added
    so far stay: the caller removes them)."""
    for res in moves:
        bad = run.take_repose(res)
        if bad:
            run.failures.append(f"freeing reposing at step {len(run.steps)} rejected: {bad}")
            return False
    return True
