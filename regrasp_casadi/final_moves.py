"""The planner's last phase (Algorithm 1, last lines): in-grasp moves (OPT2, SVD form) from the grasp
whose contacts are within ζ to the desired object pose, and the plan's status decision.

The moves are monotone: a move is accepted only when it brings the object closer to the desired pose
(`pose_distance`, m) and keeps every contact within ζ of its goal; the loop runs until the object is within
`final_pose_tol`, a move is rejected or gains less than `final_min_gain`, or its OPT2 solves have taken
`final_max_iterations` IPOPT iterations (or `final_time_budget` seconds have passed, when it is set: a
wall-clock bound makes a plan depend on the machine's speed, so it is off by default). A plan is "converged"
only when its contacts are within ζ *and* its object is within `pose_tol_position` / `pose_tol_rotation` of
the desired pose (the paper's desired grasp G_d = (X_d, o_d) has both); contacts within ζ with the object
elsewhere is "pose_not_reached". Once the object is within that tolerance, a move that would take it out is
not accepted ("in_tolerance"): the pose distance adds translation and rotation, so a move can lower it while
leaving the tolerance on one of them (measured: the generated mug pair of seed 9, svd, planned with a
variant of the re-posture gaits, passed 1.8 mm / 1.8° and ended 2.5 mm / 1.2°, "pose_not_reached").
Conversely, when the moves stop with one of the two within its tolerance and the other not, the plan's end
(`planner._finish`) makes up to `AIMED_MOVES` moves towards the desired value of the other alone
(`aimed_moves`).

    >>> outcome = run_final_moves(run, options)      # run: the planner's `_Run`
    >>> status, detail = decide_status(run, options, outcome)
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.grasp_metrics import pose_error
from regrasp_casadi.in_grasp_targets import clip_pose, trust_region
from regrasp_casadi.transforms import exp_so3, interpolate_pose, log_SO3, make_T

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.in_grasp import InGraspNLP
    from regrasp_casadi.motion import StepPath
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import PlanStep
    from regrasp_casadi.planner import PlannerOptions

__all__ = ["FinalMoves", "run_final_moves", "aimed_moves", "decide_status", "pose_distance", "part_way"]

FinalStop = Literal["reached", "small_gain", "no_gain", "in_tolerance", "rejected", "contact_drift",
                    "uncertified", "unrealisable", "iteration_budget", "time_budget", "not_run"]
"""Why the final moves ended: the object is within `final_pose_tol`; the last move gained less than
`final_min_gain` (accepted) or nothing (not accepted); the object is within the plan's pose tolerance
(`pose_tol_position` / `pose_tol_rotation`) and the move would take it out (not accepted); OPT2's exact
checks rejected the move; the move would take a contact farther than ζ from its goal (not accepted); the
moved grasp would have no stability certificate (`planner._Run.uncertified`; not accepted); its path from
the last step fails its checks (`planner._Run.unrealisable`; not accepted); the OPT2 solves took
`final_max_iterations` IPOPT iterations; the time budget (`final_time_budget`) ran out; not run."""

BUDGET_STOPS = ("iteration_budget", "time_budget")
"""Final-move stops on a budget."""
SETTLED_STOPS = ("reached", "not_run", *BUDGET_STOPS)
"""Final-move stops after which nothing more is tried: the pose is reached, no move was tried, or a
budget ran out (no polish, re-posture or aimed moves: `final_rounds`, `reposture`, `planner._finish`)."""


class FinalMoveRun(Protocol):
    """What the final moves read and change of a planning run (`planner._Run`)."""

    hand: Hand
    q: NDArray
    T_palm_object: NDArray
    T_palm_object_goal: NDArray
    goal_contacts: NDArray
    obj: ObjectModel
    svd_nlp: InGraspNLP
    timing: dict[str, float]
    solves: dict[str, int]
    steps: list[PlanStep]
    iterations: int

    def tips_object(self) -> NDArray: ...

    def add_step(self, kind: str, finger: str | None, status: str, solve_time: float,
                 certificate=None, path: StepPath | None = None) -> PlanStep: ...

    def grasp_certificate(self): ...

    def uncertified(self, q: NDArray, T_palm_object: NDArray) -> str: ...

    def unrealisable(self, q: NDArray, T_palm_object: NDArray, kind: str = "repose"
                     ) -> tuple[str, StepPath | None]: ...

    def largest_error(self) -> float: ...


@dataclass(frozen=True)
class FinalMoves:
    """The outcome of the final moves."""

    stop: FinalStop
    """Why they ended (`FinalStop`)."""
    moves: int
    """Accepted moves."""
    distances: tuple[float, ...]
    """Pose distance (m, `pose_distance`) before the first move and after each accepted one."""
    note: str = ""
    """Why the last move was not accepted, for the status detail ("" when every move was)."""
    aimed: int = 0
    """Moves accepted after them towards one component of the desired pose alone (`aimed_moves`)."""
    aimed_at: str = ""
    """That component: "position" or "orientation" ("" when none was tried)."""


def pose_distance(T_a: NDArray, T_b: NDArray, obj: ObjectModel) -> float:
    """Pose distance, m: translation plus rotation angle times the object's radius (half its bounding-box
    diagonal)."""
    radius = 0.5 * float(np.linalg.norm(obj.mesh.extents))
    position, rotation = pose_error(T_a, T_b)
    return position + radius * rotation


def part_way(T_now: NDArray, T_goal: NDArray, trust: tuple[float, float], reach: float) -> NDArray:
    """The pose (4, 4) `reach` ∈ (0, 1] of the way from `T_now` to `T_goal`, or to where the trust
    region `trust` (`in_grasp_targets.trust_region`) ends on the way when that is nearer."""
    return interpolate_pose(T_now, clip_pose(T_now, T_goal, *trust), reach)


def run_final_moves(run: FinalMoveRun, options: PlannerOptions) -> FinalMoves:
    """In-grasp moves towards `run.T_palm_object_goal` (see the module docstring); each accepted move is
    a "final" step of `run`.

    OPT2 lands the object a fraction ρ of the way to its target (E_des against the relaxed rigidity), so
    each move is asked for a target stretched beyond the desired pose, by s = 1/ρ measured on the last
    move, separately for translation and rotation (`_Stretch`); a move that would not bring the object
    closer is not accepted and retried with half the stretch, then ends the moves ("no_gain")."""
    t_start, T_goal, zeta = time.perf_counter(), run.T_palm_object_goal, options.zeta
    distances = [pose_distance(run.T_palm_object, T_goal, run.obj)]
    stretch = _Stretch(trust=trust_region(run.svd_nlp.options))
    iterations = 0  # IPOPT iterations of this run's OPT2 solves
    while True:
        if distances[-1] <= options.final_pose_tol:
            return FinalMoves("reached", len(distances) - 1, tuple(distances))
        if iterations >= options.final_max_iterations:
            return FinalMoves("iteration_budget", len(distances) - 1, tuple(distances))
        budget = options.final_time_budget
        if budget is not None and time.perf_counter() - t_start >= budget:
            return FinalMoves("time_budget", len(distances) - 1, tuple(distances))
        T_target = stretch.target(run.T_palm_object, T_goal)
        res = run.svd_nlp.solve(run.q, run.T_palm_object, run.tips_object(), T_target=T_target)
        run.timing["opt2"] += res.solve_time
        run.solves["opt2"] += 1
        iterations += res.iterations
        stop, note, path = _judge(run, res, distances[-1], zeta)
        if stop is None and _within(run.T_palm_object, T_goal, options) and not _within(
                res.T_palm_object, T_goal, options):
            stop, note = "in_tolerance", "the next final move would take the object out of the pose tolerance"
        if stop is not None and stretch.shrink():
            continue  # retried with half the stretch
        if stop is not None:
            return FinalMoves(stop, len(distances) - 1, tuple(distances), note)
        stretch.update(run.T_palm_object, T_target, res.T_palm_object)
        run.q, run.T_palm_object = res.q, res.T_palm_object
        run.add_step("final", None, res.status, res.solve_time, run.grasp_certificate(), path)
        distances.append(pose_distance(run.T_palm_object, T_goal, run.obj))
        if distances[-2] - distances[-1] < options.final_min_gain:
            return FinalMoves("small_gain", len(distances) - 1, tuple(distances))


class _Stretch:
    """How far beyond the desired pose the next final move aims: factors s_t (translation) and s_r
    (rotation) ≥ 1 on the remaining displacement, from the response of the last accepted move."""

    MAX = 50.0
    """Largest stretch."""
    DAMPING = 1.0
    """s = DAMPING/ρ (measured on the shipped bottle problem: 0.6 stalled a move that 1.0 did not)."""
    MAX_ANGLE = np.pi / 3
    """Largest rotation from the current pose a stretched target may ask, rad (no wrap-around)."""

    MIN_REACH = 0.25
    """Smallest part of the way to the desired pose a move asks for once the stretch is 1."""

    def __init__(self, radius: float = 0.1, trust: tuple[float, float] = (np.inf, np.inf)) -> None:
        self.s_t = self.s_r = 1.0
        self.reach = 1.0
        """Part of a move's way the moves ask for (halved after a refused move at stretch 1, down to
        `MIN_REACH`: a shorter move rolls the contacts less far and its path slides less)."""
        self.radius = radius
        self.trust = trust
        """OPT2's trust region (largest translation, m, and rotation, rad, of one move): a move's way."""

    def target(self, T_now: NDArray, T_goal: NDArray) -> NDArray:
        """The stretched target pose (4, 4), palm frame; with a reach below 1, that part of the way to
        the desired pose within the trust region."""
        if self.reach < 1.0:
            return part_way(T_now, T_goal, self.trust, self.reach)
        w = log_SO3(T_now[:3, :3].T @ T_goal[:3, :3])
        s_r = min(self.s_r, self.MAX_ANGLE / max(float(np.linalg.norm(w)), 1e-12))
        t = T_now[:3, 3] + self.s_t * (T_goal[:3, 3] - T_now[:3, 3])
        return make_T(T_now[:3, :3] @ exp_so3(s_r * w), t)

    def update(self, T_before: NDArray, T_target: NDArray, T_after: NDArray) -> None:
        """Set s = 1/ρ per component, ρ the fraction of the requested displacement the move achieved."""
        asked_t, got_t = T_target[:3, 3] - T_before[:3, 3], T_after[:3, 3] - T_before[:3, 3]
        asked_r = log_SO3(T_before[:3, :3].T @ T_target[:3, :3])
        got_r = log_SO3(T_before[:3, :3].T @ T_after[:3, :3])
        r = self.radius
        self.s_t = self.s_r = self._next(self.s_t, np.concatenate([asked_t, r * asked_r]),
                                         np.concatenate([got_t, r * got_r]))

    def _next(self, s: float, asked: NDArray, got: NDArray) -> float:
        """1/ρ (clipped to [1, MAX]); `s` unchanged when nothing was asked."""
        size = float(asked @ asked)
        if size < 1e-16:  # nothing asked (that component is already there): keep the factor
            return s
        rho = float(got @ asked) / size  # achieved fraction of the request
        return float(np.clip(self.DAMPING / rho, 1.0, self.MAX)) if rho > 0 else 1.0

    def shrink(self) -> bool:
        """Halve the stretch after a move that could not be accepted, or, once it is 1, the reach; False
        when both are at their least."""
        if self.s_t <= 1.0 and self.s_r <= 1.0:
            if self.reach <= self.MIN_REACH:
                return False
            self.reach = max(self.MIN_REACH, 0.5 * self.reach)
            return True
        self.s_t, self.s_r = max(1.0, 0.5 * self.s_t), max(1.0, 0.5 * self.s_r)
        return True


AIMED_MOVES = 4
"""Most moves `aimed_moves` makes."""


def aimed_moves(run: FinalMoveRun, options: PlannerOptions, outcome: FinalMoves) -> FinalMoves:
    """After final moves that stopped short of the desired pose with one of its components within the
    plan's tolerance (`pose_tol_position`, `pose_tol_rotation`) and the other not: in-grasp moves (OPT2,
    SVD form) towards the desired value of that other component alone, the first kept where it is (the
    target (R, t*) or (R*, t)), each accepted when it lowers the component out of tolerance, leaves the
    first within it and passes the final moves' checks (ζ, certificate, path); up to `AIMED_MOVES`, until
    both are within tolerance. The final moves judge a move by `pose_distance`, which adds the two, and
    the plan's status tests each (`decide_status`): measured on the generated cup pair of seed 11 (SVD),
    the final moves stopped at 2.00 mm / 0.82° from the desired pose (the thumb at two joint limits), and
    a move towards the desired position alone lands at 1.73 mm / 1.24°. Returns `outcome` with the moves
    counted (`FinalMoves.aimed`)."""
    G, tol_t, tol_r = run.T_palm_object_goal, options.pose_tol_position, options.pose_tol_rotation
    position, rotation = pose_error(run.T_palm_object, G)
    if (position <= tol_t) == (rotation <= tol_r):
        return outcome  # within tolerance (converged), or out of it both ways: not this case
    aim = "position" if rotation <= tol_r else "orientation"
    aimed = 0
    while aimed < AIMED_MOVES and (position > tol_t or rotation > tol_r):
        T = run.T_palm_object
        T_target = make_T(T[:3, :3], G[:3, 3]) if aim == "position" else make_T(G[:3, :3], T[:3, 3])
        res = run.svd_nlp.solve(run.q, T, run.tips_object(), T_target=T_target)
        run.timing["opt2"] += res.solve_time
        run.solves["opt2"] += 1
        p_new, r_new = pose_error(res.T_palm_object, G)
        if aim == "position":
            better = p_new < position and r_new <= tol_r
        else:
            better = r_new < rotation and p_new <= tol_t
        stop, _, path = _judge(run, res, np.inf, options.zeta) if better else ("no_gain", "", None)
        if stop is not None:
            break
        run.q, run.T_palm_object = res.q, res.T_palm_object
        run.add_step("final", None, res.status, res.solve_time, run.grasp_certificate(), path)
        position, rotation, aimed = p_new, r_new, aimed + 1
    return replace(outcome, aimed=aimed, aimed_at=aim)


def _within(T_palm_object: NDArray, T_goal: NDArray, options: PlannerOptions) -> bool:
    """Whether the object pose (4, 4) is within the plan's pose tolerance of `T_goal` (`decide_status`'s
    "converged" test)."""
    position, rotation = pose_error(T_palm_object, T_goal)
    return position <= options.pose_tol_position and rotation <= options.pose_tol_rotation


def _judge(run: FinalMoveRun, res, distance: float, zeta: float
           ) -> tuple[FinalStop | None, str, StepPath | None]:
    """Whether OPT2's result `res` may be accepted: (None, "", its reposing path, None without
    trajectories) if so, else (the stop, why not, None)."""
    if not res.success:
        return "rejected", (f"the final in-grasp move was rejected by the exact checks (slip "
                            f"{res.max_slip * 1e3:.2f} mm, a tip {res.surface_error * 1e3:.2f} mm off the "
                            f"surface, clearance {res.min_clearance * 1e3:.2f} mm; IPOPT: "
                            f"{res.status})"), None
    after = pose_distance(res.T_palm_object, run.T_palm_object_goal, run.obj)
    if after >= distance:
        return "no_gain", (f"the next final move would not bring the object closer ({after * 1e3:.2f} mm "
                           f"≥ {distance * 1e3:.2f} mm)"), None
    tips = (run.hand.tip_positions(res.q) - res.T_palm_object[:3, 3]) @ res.T_palm_object[:3, :3]
    contacts, _ = run.obj.closest_points(tips)
    worst = float(np.max(np.linalg.norm(contacts - run.goal_contacts, axis=1)))
    if worst > zeta:
        return "contact_drift", (f"the next final move would take a contact {worst * 1e3:.2f} mm from its "
                                 f"goal (> ζ)"), None
    bad = run.uncertified(res.q, res.T_palm_object)
    if bad:
        return "uncertified", f"the next final move was rejected: {bad}", None
    bad, path = run.unrealisable(res.q, res.T_palm_object, "final")
    if bad:
        return "unrealisable", f"the next final move was rejected: {bad}", None
    return None, "", path


def decide_status(run: FinalMoveRun, options: PlannerOptions, outcome: FinalMoves) -> tuple[str, str]:
    """The plan's (status, detail) once the iterations ended: "converged" (contacts within ζ and the
    object within the pose tolerance), "pose_not_reached" (contacts within ζ, the object not) or
    "iteration_limit" (contacts not within ζ after `max_iters`). The planner calls it only with no finger
    across the object from its goal (`planner._Run.at_goals`; it decides that case itself)."""
    err = run.largest_error()
    if err > options.zeta:
        return "iteration_limit", (f"largest contact error {err * 1e3:.2f} mm > ζ after "
                                   f"{run.iterations} iterations")
    position, rotation = pose_error(run.T_palm_object, run.T_palm_object_goal)
    pose = (f"object {position * 1e3:.2f} mm / {np.degrees(rotation):.2f}° from the desired pose "
            f"(tolerance {options.pose_tol_position * 1e3:.1f} mm / "
            f"{np.degrees(options.pose_tol_rotation):.1f}°)")
    moves = _describe(outcome)
    contacts = f"largest contact error {err * 1e3:.2f} mm ≤ ζ = {options.zeta * 1e3:.1f} mm"
    if _within(run.T_palm_object, run.T_palm_object_goal, options):
        return "converged", f"{contacts}; {pose}{moves}"
    return "pose_not_reached", f"{contacts} but the {pose}{moves}"


def _describe(outcome: FinalMoves) -> str:
    """The final moves' part of the status detail."""
    if outcome.stop == "not_run":
        return "; no final moves (final_move off)"
    text = f"; {outcome.moves} final moves, stopped: {outcome.stop.replace('_', ' ')}"
    text += f" ({outcome.note})" if outcome.note else ""
    if outcome.aimed_at:
        moves = "1 move" if outcome.aimed == 1 else f"{outcome.aimed} moves"
        text += f"; then {moves} towards the desired {outcome.aimed_at} alone"
    return text
