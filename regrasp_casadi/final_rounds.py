"""The rounds of a plan's end, after the final moves stopped short of the desired pose (`planner._iterate`):
one more gait round to bring the contacts to their goals (`polish`), a reposing towards the desired pose
and gait rounds from there (`regait`, with the run's state to fall back to, `Fallback`), and, for a plan
that does not converge so, a re-posture round with the object reposed for a finger whose goal posture
is obstructed (`free_postures`), made from where the re-posture rounds first moved no finger
(`EndRounds`).

    >>> if polish(run, options, outcome): ...      # run: the planner's `_Run`; outcome: its final moves'
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.final_moves import SETTLED_STOPS, FinalMoves, decide_status
from regrasp_casadi.reposture import reposture_round

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.planner import _Run
    from regrasp_casadi.planner_options import PlannerOptions

__all__ = ["EndRounds", "Fallback", "NO_POLISH_STOPS", "REGAIT_REACH", "REGAIT_STOPS", "free_postures",
           "polish", "regait"]


@dataclass(frozen=True)
class Fallback:
    """The run's state when the final moves stopped and `regait` went on: steps kept, joints, object
    pose, the final moves' outcome and the iterations then."""

    n_steps: int
    q: NDArray
    T_palm_object: NDArray
    outcome: FinalMoves
    iterations: int

    def restore(self, run: _Run, status: str) -> FinalMoves:
        """Drop the steps made since, return to that grasp; the outcome, noting how re-gaiting ended."""
        tried = run.iterations - self.iterations
        del run.steps[self.n_steps:]
        run.q, run.T_palm_object = self.q, self.T_palm_object
        note = (f"{self.outcome.note + '; ' if self.outcome.note else ''}re-gaiting towards the desired pose "
                f"ended {status.replace('_', ' ')} after {tried} iterations; the plan ends before it")
        return replace(self.outcome, note=note)


def regait(run: _Run, options: PlannerOptions, outcome: FinalMoves) -> bool:
    """After final moves that stopped short of the desired pose (`outcome`: the next would take a
    contact beyond ζ, or was refused), one reposing towards it (`_Run.repose`, accepted when it brings
    the object closer, wherever the contacts go); True when it was accepted and iterations remain, so
    that gait rounds bring the contacts back (`PlannerOptions.final_regait`). Not when the object is
    within the pose tolerance already (the plan is converged; re-gaiting might end it elsewhere)."""
    if not (options.final_regait and outcome.stop in REGAIT_STOPS and run.iterations < options.max_iters):
        return False
    if decide_status(run, options, outcome)[0] == "converged":
        return False
    n_steps = len(run.steps)
    for reach in REGAIT_REACH:  # a shorter reposing where a longer one is refused
        run.repose(escape=True, reach=reach)
        if len(run.steps) > n_steps:
            break
    run.iterations += 1  # an iteration of its own: the loop ends within max_iters
    run.errors.append(float(np.mean(run.steps[-1].contact_error)))
    return len(run.steps) > n_steps


def polish(run: _Run, options: PlannerOptions, outcome: FinalMoves) -> bool:
    """After final moves that stopped short of the desired pose (`outcome`) with the contacts within ζ
    but not at their goals, one more gait round (OPT1 to the goal contacts at the current pose); True
    when it moved a finger and iterations remain, so that the final moves are tried again from grasps
    nearer the desired one (`PlannerOptions.final_polish`)."""
    if outcome.stop in NO_POLISH_STOPS or run.iterations >= options.max_iters:
        return False
    if run.largest_error() <= options.skip_tol:
        return False
    n_steps = len(run.steps)
    run.gait_round()
    run.iterations += 1  # an iteration of its own: the loop ends within max_iters
    run.errors.append(float(np.mean(run.steps[-1].contact_error)))
    return len(run.steps) > n_steps


NO_POLISH_STOPS = (*SETTLED_STOPS, "contact_drift")
"""Final-move stops after which `polish` does not run: the pose is reached, nothing was tried, a budget
ran out, or the contacts rolled away from their goals (`regait`'s case: a reposing towards the pose first)."""
REGAIT_REACH = (1.0, 0.5, 0.25)
"""Parts of the way to the desired pose `regait`'s reposing tries, longest first."""
REGAIT_STOPS = ("contact_drift", "rejected", "unrealisable", "uncertified", "no_gain")
"""Final-move stops after which `regait` tries a reposing towards the desired pose."""


def free_postures(run: _Run, options: PlannerOptions, outcome: FinalMoves) -> bool:
    """For a plan that did not converge, from where the re-posture rounds first moved no finger
    (`EndRounds.free_from_branch`, once per plan): a re-posture round in which a finger whose goal
    posture is obstructed has the object reposed for it first (`reposture_round` with `freeing`); True
    when it moved a finger. Not when the plan is converged, `free_after` is None, stability is on (the
    search runs without it only, as `make_way` does), or no iterations remain."""
    if options.free_after is None or run.holding is not None or run.iterations >= options.max_iters:
        return False
    if decide_status(run, options, outcome)[0] == "converged":
        return False
    return reposture_round(run, outcome, freeing=True)


class EndRounds:
    """The end rounds a plan has had (`polish`, `reposture_round`, `free_postures`), against their
    limits (`PlannerOptions.final_polish`, `final_reposture`; one `free_postures`), and the grasp where
    the re-posture rounds first moved no finger (`branch`). A plan that does not converge goes back there
    for the `free_postures` round (`free_from_branch`) and on; only then, because its reposings move the
    object away from the desired pose and its search costs seconds: measured with the round made at the
    branch itself, the generated flat tool pair of seed 8 (SVD) stalled after it where it converges by
    `regait`, and the paper benchmark's mustard pair 3 took 11.3 s (SVD) and 13.8 s (SD) against 5.5 and
    9.0 s."""

    def __init__(self) -> None:
        self.polished = self.repostured = self.freed = 0
        self.branch: tuple[Fallback, int, int, list] | None = None
        """The run's state, the polish and re-posture counts and the NLPs' warm starts
        (`_Run.warm_starts`) where the re-posture rounds first moved no finger, or None."""

    def next(self, run: _Run, options: PlannerOptions, outcome: FinalMoves) -> bool:
        """After final moves that stopped short (`outcome`): a `polish` round while they last, else a
        re-posture round; True when it moved a finger (the final moves are tried again). The first time
        a re-posture round moves none, the run's state is kept as `branch`."""
        if self.polished < options.final_polish and polish(run, options, outcome):
            self.polished += 1
            return True
        if self.repostured >= options.final_reposture:
            return False
        if reposture_round(run, outcome):
            self.repostured += 1
            return True
        if not self.freed and self.branch is None:
            self.branch = (Fallback(len(run.steps), run.q, run.T_palm_object, outcome, run.iterations),
                           self.polished, self.repostured, [w.saved() for w in run.warm_starts()])
        return False

    def free_from_branch(self, run: _Run, options: PlannerOptions) -> bool:
        """Once per plan: put the run back at `branch` (steps, joints, object pose, iterations, these
        counts and the NLPs' warm starts) and make the `free_postures` round there; True when it moved a
        finger (the plan goes on from there), False when there is no branch or the round moved nothing
        (the run stays at the branch)."""
        if self.branch is None or self.freed:
            return False
        before, self.polished, self.repostured, warm = self.branch
        self.branch, self.freed = None, 1
        del run.steps[before.n_steps:]
        run.q, run.T_palm_object, run.iterations = before.q, before.T_palm_object, before.iterations
        del run.errors[before.iterations + 1:]
        for w, saved in zip(run.warm_starts(), warm, strict=True):  # the NLPs' warm starts of then
            w.restore(saved)
        if not free_postures(run, options, before.outcome):
            return False
        self.repostured += 1
        return True
