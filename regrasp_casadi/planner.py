"""The regrasp planner (Algorithm 1 of Sundaralingam & Hermans, ICRA 2018): alternate finger gaits
(OPT1) and in-grasp reposing (OPT2) until every contact is within ζ of its goal, then move the object to
the desired pose.

    >>> plan = plan_regrasp(grasp0, grasp_goal, method="svd")
    >>> plan.status, plan.iterations, plan.final_error
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.certificates import Certificate
from regrasp_casadi.certified_round import accept_gait, certified_round
from regrasp_casadi.final_moves import (
    SETTLED_STOPS,
    FinalMoves,
    aimed_moves,
    decide_status,
    part_way,
    pose_distance,
    run_final_moves,
)
from regrasp_casadi.final_rounds import REGAIT_REACH, EndRounds, Fallback, regait
from regrasp_casadi.finger_gait import FingerGaitNLP
from regrasp_casadi.free_finger import free_finger
from regrasp_casadi.grasp import require_grasp
from regrasp_casadi.grasp_metrics import tip_frames, tip_slip
from regrasp_casadi.hand_orientation import pinned_opposer_hint
from regrasp_casadi.holding import Holding
from regrasp_casadi.in_grasp import InGraspNLP
from regrasp_casadi.in_grasp_targets import svd_target, trust_region
from regrasp_casadi.interrupts import InterruptRequest, deferred_interrupts
from regrasp_casadi.long_gait import long_gait
from regrasp_casadi.make_way import make_way
from regrasp_casadi.nlp_cache import NLPCache, clear_built_solvers
from regrasp_casadi.plan import Plan, PlanStep
from regrasp_casadi.planner_options import PlannerOptions, input_problem
from regrasp_casadi.reposture import posture_report
from regrasp_casadi.restarts import RESTART_STATUSES, continued, restarted
from regrasp_casadi.stability import holding_quality, torque_reference
from regrasp_casadi.stall_report import reached_through_others, stalled_fingers
from regrasp_casadi.surface_route import fingers_across, gait_target
from regrasp_casadi.trajectory import TrajectoryOptions, attach_trajectories, motion_context, step_path

if TYPE_CHECKING:
    from regrasp_casadi.grasp import Grasp
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.motion import StepPath

__all__ = ["PlannerOptions", "plan_regrasp", "gait_pattern", "clear_nlp_cache", "NLPCache"]

_log = logging.getLogger(__name__)

ProgressCallback = Callable[[int, int, float], None]
_NLP = TypeVar("_NLP")


def gait_pattern(hand: Hand, contacts_object: NDArray[np.float64],
                 goal_contacts_object: NDArray[np.float64]) -> tuple[str, ...]:
    """The paper's gait-pattern rule (§IV) on the hand's forward order `hand.gait_forward` (Allegro, from
    its hand.yaml: index, middle, ring, thumb): forward when the first finger's goal contact is farther from
    the second finger's contact than from the first finger's own, else reversed (thumb, ring, middle,
    index). A hand whose metadata does not make the order reversible (a URDF without hand.yaml) always
    uses its forward order.
    """
    forward = tuple(hand.gait_forward)
    if not hand.metadata.gait_reversible or len(forward) < 2:
        return forward
    i, m = hand.fingers.index(forward[0]), hand.fingers.index(forward[1])
    goal = goal_contacts_object[i]
    if np.linalg.norm(goal - contacts_object[m]) > np.linalg.norm(goal - contacts_object[i]):
        return forward
    return tuple(reversed(forward))


_DEFAULT_CACHE = NLPCache(max_size=64)
"""The process-wide NLP cache of `plan_regrasp` calls that do not pass their own."""


def clear_nlp_cache() -> None:
    """Forget every NLP of the process-wide cache and every solver `build_solver` keeps (they are rebuilt
    on the next plan)."""
    _DEFAULT_CACHE.clear()
    clear_built_solvers()


class _ProgressWatch:
    """Counts the iterations since the largest contact error last dropped by more than `stall_tol`."""

    def __init__(self, options: PlannerOptions, error: float):
        self.options = options
        self.best = error
        """The largest contact error at the last progress, m."""
        self.stalled = 0
        """Iterations since then."""

    def update(self, error: float) -> None:
        """Record the largest contact error (m) after an iteration."""
        if error < self.best - self.options.stall_tol:
            self.best, self.stalled = error, 0
        else:
            self.stalled += 1

    @property
    def escape(self) -> bool:
        """Reposings should move towards the desired object pose (`stall_escape`)."""
        return self.stalled >= self.options.stall_escape

    @property
    def exhausted(self) -> bool:
        """The plan should stop as stalled (`stall_limit`)."""
        return self.stalled >= self.options.stall_limit


class _Run:
    """One planning run of Algorithm 1: the current grasp (q, T_palm_object), the steps so far, the NLPs
    it uses, timing and solve counts; its methods are the algorithm's named steps."""

    def __init__(self, grasp0: Grasp, grasp_goal: Grasp, options: PlannerOptions, cache: NLPCache):
        self.hand, self.obj, self.options, self.cache = grasp0.hand, grasp0.obj, options, cache
        self.goal_contacts = np.asarray(grasp_goal.contacts_object, dtype=float)
        self.goal_tips = np.asarray(grasp_goal.tip_centers_object, dtype=float)
        self.T_palm_object_goal = np.asarray(grasp_goal.T_palm_object, dtype=float)
        self.q_goal = None if grasp_goal.q is None else np.asarray(grasp_goal.q, dtype=float)
        """(n,) the goal grasp's joints, rad, when it gives them (a start of the reach IKs), else None."""
        self.fingers = tuple(self.hand.fingers)
        self.steps: list[PlanStep] = []
        self.timing = {"build": 0.0, "opt1": 0.0, "opt2": 0.0, "other": 0.0, "total": 0.0}
        self.solves = {"opt1": 0, "opt2": 0}
        self.failures: list[str] = []  # rejected solves of the current iteration ("<what>: IPOPT <status>")
        self.com, self.length = torque_reference(self.obj.mesh)  # of the stability-aware gait order
        self.holding = None if options.stability == "none" else Holding(
            self.hand, self.obj, options.stability, options.holding, options.object_mass,
            options.gravity_palm)
        """The stability checks (None: stability "none")."""
        self.q = np.asarray(grasp0.q, dtype=float)
        self.T_palm_object = np.asarray(grasp0.T_palm_object, dtype=float)
        step = self.add_step("initial", None, "", 0.0, self.grasp_certificate())
        self.errors = [float(np.mean(step.contact_error))]  # mean contact error after each iteration
        self.iterations = 0
        self.stalled = 0
        """Iterations since the largest contact error last dropped (`_ProgressWatch.stalled`)."""
        self.staging_on = False
        """Whether the certified round stages pinned fingers (`staging`): a stalled plan's last resort."""
        self.staging = None
        """The support configuration the certified round is moving towards (`staging.Staging`), or None."""
        self.staging_failed: dict[str, int] = {}
        """Pinned fingers whose staging search found nothing → the iteration it was tried."""
        self.motion = None if not options.trajectories else _trajectory_context(self.hand, self.obj, options)
        """The trajectories' context (`trajectory.motion_context`) of the paths computed before a step is
        accepted (`unrealisable`); None without trajectories."""
        self.routes = None
        """The ways over the surface to the goal contacts (`surface_route.SurfaceRoutes`), once needed."""
        self.gait = options.gait or gait_pattern(self.hand, step.contacts_object, self.goal_contacts)
        self.gait_nlps = {f: self.gait_nlp(f) for f in self.gait}
        self.svd_nlp = self.in_grasp_nlp("svd")  # SVD reposing, stall escape and final moves
        self.repose_nlp = self.svd_nlp if options.method == "svd" else self.in_grasp_nlp("sd")
        for nlp in [*self.gait_nlps.values(), self.svd_nlp, self.repose_nlp]:
            nlp.reset()  # same input, same plan: no warm start carried over from another plan

    # ------------------------------------------------------------------------------------------ NLPs
    def gait_nlp(self, finger: str) -> FingerGaitNLP:
        o = self.options.finger_gait
        return self.cache.get("finger_gait", self.hand, self.obj, (finger, o),
                              self._timed(lambda: FingerGaitNLP(self.hand, self.obj, finger, o)))

    def in_grasp_nlp(self, method: str) -> InGraspNLP:
        o = self.options.in_grasp
        return self.cache.get("in_grasp", self.hand, self.obj, (method, o),
                              self._timed(lambda: InGraspNLP(self.hand, self.obj, method, o)))

    def warm_starts(self) -> list:
        """The warm starts (`solver.WarmStart`) of the run's NLPs: the gaits', the SVD and the
        reposing NLP's (kept and restored with a state the run goes back to, `final_rounds.EndRounds`)."""
        return [nlp.warm_start for nlp in (*self.gait_nlps.values(), self.svd_nlp, self.repose_nlp)]

    def _timed(self, build: Callable[[], _NLP]) -> Callable[[], _NLP]:
        """`build`, adding its time to the run's build time (a cache hit adds nothing)."""

        def timed_build() -> _NLP:
            t0 = time.perf_counter()
            nlp = build()
            self.timing["build"] += time.perf_counter() - t0
            return nlp

        return timed_build

    # ----------------------------------------------------------------------------------------- steps
    def tips_object(self, q: NDArray | None = None, T_palm_object: NDArray | None = None) -> NDArray:
        """Tip-sphere centres (m, 3), object frame, of the current grasp, or of the hand at q (n,) rad
        holding the object at `T_palm_object` (4, 4)."""
        q = self.q if q is None else q
        T = self.T_palm_object if T_palm_object is None else T_palm_object
        return (self.hand.tip_positions(q) - T[:3, 3]) @ T[:3, :3]

    def take_repose(self, res) -> str:
        """Add the OPT2 result `res` (from the current grasp) as a reposing step once its certificate
        (`uncertified`) and then its path from the step before (`unrealisable`) pass; "" when it was
        taken, else why not (the run unchanged)."""
        bad, path = self.uncertified(res.q, res.T_palm_object), None
        if not bad:
            bad, path = self.unrealisable(res.q, res.T_palm_object)
        if not bad:
            self.q, self.T_palm_object = res.q, res.T_palm_object
            self.add_step("repose", None, res.status, res.solve_time, self.grasp_certificate(), path)
        return bad

    def add_step(self, kind: str, finger: str | None, status: str, solve_time: float,
                 certificate: Certificate | None = None, path: StepPath | None = None) -> PlanStep:
        """Append the current grasp as a step of `kind`, with its contacts, contact errors, the
        certificate of its holding set (None without stability) and its path when already computed
        (`unrealisable`; None: `attach_trajectories` computes it)."""
        contacts, _ = self.obj.closest_points(self.tips_object())
        error = np.linalg.norm(contacts - self.goal_contacts, axis=1)
        step = PlanStep(kind=kind, finger=finger, q=np.array(self.q, dtype=float),
                        T_palm_object=np.array(self.T_palm_object, dtype=float),
                        contacts_object=np.asarray(contacts, dtype=float), contact_error=error,
                        solver_status=status, solve_time=float(solve_time),
                        certificate=None if certificate is None else certificate.to_dict(), path=path)
        self.steps.append(step)
        return step

    def grasp_certificate(self, q: NDArray | None = None, T_palm_object: NDArray | None = None
                          ) -> Certificate | None:
        """The certificate of every finger holding the object in the grasp (default: the current one);
        None without stability."""
        if self.holding is None:
            return None
        return self.holding.grasp(self.q if q is None else q,
                                  self.T_palm_object if T_palm_object is None else T_palm_object)

    def uncertified(self, q: NDArray, T_palm_object: NDArray) -> str:
        """Why an in-grasp move to the grasp (q, T_palm_object) would not be certified, "" when it would
        (always "" without stability): its grasp has no certificate, or a tip slides over the object by
        more than `HoldingOptions.max_contact_slip` (`grasp_metrics.tip_slip`; the certificate is of the
        contacts it ends with, which a rolling tip moves)."""
        if self.holding is None:
            return ""
        cert = self.grasp_certificate(q, T_palm_object)
        if not self.holding.certified(cert):
            return f"its grasp is not certified ({cert.detail})"
        last = self.steps[-1]
        (p_a, R_a), (p_b, R_b) = (tip_frames(self.hand, last.q, last.T_palm_object),
                                  tip_frames(self.hand, q, T_palm_object))
        n_a = self.holding.contacts(last.q, last.T_palm_object)[1]
        n_b = self.holding.contacts(q, T_palm_object)[1]
        slip = tip_slip(p_a, R_a, p_b, R_b, n_a + n_b, self.hand.tip_radius)  # the one slip definition
        if np.max(slip) > self.holding.options.max_contact_slip:
            return f"a tip slides {np.max(slip) * 1e3:.2f} mm over the object"
        return ""

    def unrealisable(self, q: NDArray, T_palm_object: NDArray, kind: str = "repose",
                     finger: str | None = None) -> tuple[str, StepPath | None]:
        """The path (`trajectory.step_path`) from the last step to a step of `kind` (`finger`'s for a
        gait) ending in (q, T_palm_object), the one `attach_trajectories` would give it, and why the hand
        could not follow it: the path's own checks (a link in the object, fingers touching, a tip off
        the surface, a slip, a joint limit, a gap in the IK); ("", None) without trajectories. An
        accepted step keeps the path (`add_step`), so it is computed once."""
        if self.motion is None:
            return "", None
        a = self.steps[-1]
        b = replace(a, kind=kind, finger=finger, q=np.asarray(q, float),
                    T_palm_object=np.asarray(T_palm_object, float), path=None, certificate=None)
        path = step_path(self.motion, a, b)
        return ("" if path.ok else f"its path fails its checks ({path.detail})"), path

    def start_staging(self) -> bool:
        """Turn on the staging of pinned fingers (`staging`) when the plan has stalled; False when it is
        already on, stability is off or `HoldingOptions.staging` is off (the plan then stops)."""
        if self.holding is None or self.staging_on or not self.holding.options.staging:
            return False
        self.staging_on = True
        _log.debug("stalled after %d iterations: staging pinned fingers", self.iterations)
        return True

    def largest_error(self) -> float:
        """The largest contact error of the last step, m."""
        return float(np.max(self.steps[-1].contact_error))

    def across(self) -> list[int]:
        """Rows of the fingers within ζ of their goals but across the object from them (a wall between
        the tip and its goal, `surface_route.fingers_across`), at the current grasp."""
        return fingers_across(self.obj, self.tips_object(), self.goal_tips, self.steps[-1].contact_error,
                              self.options.zeta)

    def at_goals(self) -> bool:
        """Every contact within ζ of its goal contact, and none across the object from it (`across`)."""
        return self.largest_error() <= self.options.zeta and not self.across()

    def unmet(self) -> str:
        """Why the contacts are not at their goals (`at_goals` False), for a status detail."""
        err = self.largest_error()
        if err > self.options.zeta:
            return f"largest contact error {err * 1e3:.2f} mm > ζ"
        names = [self.fingers[r] for r in self.across()]
        who = f"the {names[0]} tip is" if len(names) == 1 else f"the {', '.join(names)} tips are"
        return (f"largest contact error {err * 1e3:.2f} mm ≤ ζ = {self.options.zeta * 1e3:.1f} mm but {who} "
                f"across the object from {'its goal' if len(names) == 1 else 'their goals'}")

    # ----------------------------------------------------------------------- Algorithm 1, named steps
    def gait_round(self) -> None:
        """One finger gait (OPT1) for each finger of the gait pattern not yet at its goal, in the
        pattern's order or the stability order; a rejected gait leaves the finger where it is; once the
        plan has made no progress for `stall_escape` iterations, a finger still beyond ζ also tries
        `long_gait`, then `make_way`, and once, after `free_after` iterations, `free_finger`. With
        stability on, only certified moves
        (`certified_round.certified_round`)."""
        if self.holding is not None:
            certified_round(self)
            return
        todo = list(self.gait)
        while todo:
            finger = todo.pop(0) if self.options.gait_order == "pattern" else self._most_stable_gait(todo)
            r = self.fingers.index(finger)
            if self.steps[-1].contact_error[r] <= self.options.skip_tol:
                continue
            res = self.gait_nlps[finger].solve(self.q, self.T_palm_object, gait_target(self, r))
            self.timing["opt1"] += res.solve_time
            self.solves["opt1"] += res.solves
            if not res.success:  # the finger stays where it is, which is feasible
                self.failures.append(f"finger gait of {finger} at step {len(self.steps)} rejected by the "
                                     f"exact checks (surface error {res.surface_error * 1e3:.3f} mm, "
                                     f"clearance {res.min_clearance * 1e3:.3f} mm; IPOPT: {res.status})")
                _log.debug("%s; the finger stays", self.failures[-1])
            else:
                moved = np.linalg.norm(self.hand.tip_positions(res.q)[r] - self.hand.tip_positions(self.q)[r])
                if moved >= 1e-5:
                    accept_gait(self, finger, res)  # unless its path fails its checks
            o = self.options
            if self.stalled >= o.stall_escape and self.steps[-1].contact_error[r] > o.zeta:
                # from its IK at the goal: out of OPT1's local minimum; else past a finger in its way
                moved = long_gait(self, finger) or make_way(self, finger)
                if not moved and self.stalled == o.free_after:  # once per stall: a search of object poses
                    free_finger(self, finger)

    def _most_stable_gait(self, todo: list[str]) -> str:
        """Remove and return the finger of `todo` whose lift leaves the best-held grasp."""
        tips = self.tips_object()
        contacts, _ = self.obj.closest_points(tips)
        fingers = list(self.fingers)
        eps = [holding_quality(contacts, tips, fingers.index(f), self.com, self.length) for f in todo]
        return todo.pop(int(np.argmax(eps)))

    def repose(self, escape: bool, reach: float = 1.0, contacts_target: bool = False) -> None:
        """One in-grasp reposing (OPT2) towards the method's target: the SVD target pose, the fingers'
        workspaces, or (`escape`, after iterations without progress) the desired object pose (`reach` < 1:
        that part of the way within the trust region, `final_moves.part_way`), then accepted only if it
        brings the object closer to it (monotone, as the final moves); a rejected reposing leaves the
        object where it is. `contacts_target`: the SVD target pose whatever the method."""
        nlp = self.repose_nlp
        if escape:  # repose towards the desired object pose
            T_target = self.T_palm_object_goal if reach >= 1.0 else part_way(
                self.T_palm_object, self.T_palm_object_goal, trust_region(self.svd_nlp.options), reach)
            nlp, target = self.svd_nlp, {"T_target": T_target}
        elif self.options.method == "svd" or contacts_target:
            T_target = svd_target(self.T_palm_object, self.steps[-1].contacts_object, self.goal_contacts,
                                  self.T_palm_object_goal, self.svd_nlp.goal_pull)
            nlp, target = self.svd_nlp, {"T_target": T_target}
        else:
            target = {"p_object_tips_goal": self.goal_tips}
        res = nlp.solve(self.q, self.T_palm_object, self.tips_object(), **target)
        self.timing["opt2"] += res.solve_time
        self.solves["opt2"] += 1
        goal = self.T_palm_object_goal
        farther = escape and res.success and (pose_distance(res.T_palm_object, goal, self.obj)
                                              >= pose_distance(self.T_palm_object, goal, self.obj))
        if farther:  # refused whatever its path: not computed
            way = "" if reach >= 1.0 else f"{reach:g} of the way "
            self.failures.append(f"reposing {way}towards the desired pose at step {len(self.steps)} would "
                                 f"not bring the object closer; the object stays")
        elif res.success:
            bad = self.take_repose(res)
            if bad:  # the object stays where it is
                self.failures.append(f"reposing at step {len(self.steps)} rejected: {bad}")
        else:  # the object stays where it is
            self.failures.append(f"reposing at step {len(self.steps)} rejected by the exact checks "
                                 f"(clearance {res.min_clearance * 1e3:.3f} mm, slip "
                                 f"{res.max_slip * 1e3:.3f} mm, surface error {res.surface_error * 1e3:.3f} "
                                 f"mm; IPOPT: {res.status})")
            _log.debug("%s; the object stays", self.failures[-1])


def plan_regrasp(grasp0: Grasp, grasp_goal: Grasp, *, options: PlannerOptions | None = None,
                 progress: ProgressCallback | None = None, cache: NLPCache | None = None,
                 **overrides) -> Plan:
    """Plan an in-hand regrasp from `grasp0` to `grasp_goal` (Algorithm 1).

    Args:
        grasp0: the initial grasp; it must carry joint angles (`Grasp.from_joints`).
        grasp_goal: the desired grasp: contacts (object frame) and desired object pose.
        options: a `PlannerOptions`; keyword `overrides` replace its fields (e.g. ``method="sd"``) or
            set the NLPs' options (e.g. ``eta=0.008``, see `PlannerOptions.with_overrides`).
        progress: optional callable ``progress(iteration, max_iters, average_error_m)`` called after
            every iteration; through restarts both counts go on from the earlier plans' iterations.
        cache: where the NLPs are kept between plans (default: the process-wide cache that
            `clear_nlp_cache` clears).

    Raises:
        TypeError: `grasp0` or `grasp_goal` is not a `Grasp` (the message names the argument).

    Returns:
        A `Plan` whose `status` says why it stopped: "converged" (contacts within ζ, none across the
        object from its goal, and the object within `pose_tol_position` / `pose_tol_rotation` of the
        desired pose), "pose_not_reached" (contacts within ζ, the object farther: the distance in
        `status_detail`), "iteration_limit",
        "stalled" (no progress for `stall_limit` iterations), "solver_failure" (with the step and
        IPOPT's status in `status_detail`), "interrupted" (Ctrl-C: the current solve finishes, the plan
        holds the steps so far; a second Ctrl-C raises KeyboardInterrupt) or "invalid_input". A failed
        solve never raises: the plan ends with the steps so far.
    """
    t_start = time.perf_counter()
    require_grasp(grasp0, "grasp0")
    require_grasp(grasp_goal, "grasp_goal")
    options = (options or PlannerOptions()).with_overrides(**overrides)
    problems = input_problem(grasp0, grasp_goal, options)
    if problems:
        return _make_plan(grasp0, grasp_goal, options, t_start, None, "invalid_input", problems)
    run = _Run(grasp0, grasp_goal, options, _DEFAULT_CACHE if cache is None else cache)
    if run.holding is not None and not run.holding.certified(Certificate.from_dict(run.steps[0].certificate)):
        return _make_plan(grasp0, grasp_goal, options, t_start, run, "invalid_input",
                          f"the initial grasp is not certified ({run.steps[0].certificate['detail']}); "
                          f"plan with stability='none' to plan without a stability certificate")
    with deferred_interrupts() as stop:
        plan = _iterate(grasp0, grasp_goal, options, t_start, run, progress, stop)
        if options.restart_count and plan.status in RESTART_STATUSES:  # planned again with a variant
            plan = restarted(plan, options, lambda o, done: _iterate(
                grasp0, grasp_goal, o, time.perf_counter(), _Run(grasp0, grasp_goal, o, run.cache),
                continued(progress, done), stop))
    return plan


def _iterate(grasp0: Grasp, grasp_goal: Grasp, options: PlannerOptions, t_start: float, run: _Run,
             progress: ProgressCallback | None, stop: InterruptRequest) -> Plan:
    """Algorithm 1's loop (`_iterate_from`); a plan that does not converge goes back to where the
    re-posture rounds first moved no finger, for a round with the object reposed for an obstructed
    posture (`EndRounds.free_from_branch`), and on; the plan of that try when it converges, else the
    first plan (its timing and solve counts the whole call's)."""
    rounds = EndRounds()
    plan = _iterate_from(grasp0, grasp_goal, options, t_start, run, progress, stop, rounds=rounds)
    if plan.status in ("converged", "interrupted") or rounds.branch is None:
        return plan
    n_branch = rounds.branch[0].n_steps
    if rounds.free_from_branch(run, options):
        retry = _iterate_from(grasp0, grasp_goal, options, t_start, run, progress, stop, rounds=rounds)
        if retry.status == "converged":
            return retry
    detail = (f"{plan.status_detail}; from step {n_branch}, a re-posture round with the object reposed for "
              f"an obstructed posture did not lead to convergence: the plan is the one before it")
    # the whole call's time and solves, the try's included
    return replace(plan, status_detail=detail, timing=_timing(run, t_start),
                   options={**plan.options, "solves": dict(run.solves)})


def _iterate_from(grasp0: Grasp, grasp_goal: Grasp, options: PlannerOptions, t_start: float, run: _Run,
                  progress: ProgressCallback | None, stop: InterruptRequest, *, rounds: EndRounds) -> Plan:
    """Algorithm 1's loop from the run's grasp: gait rounds and reposings until the contacts are within
    ζ, then the final moves (and, when they stop short, the `rounds` of `final_rounds`: `polish`, else
    re-posture gaits, or once `free_postures`, and the final moves again, or `regait` and on), the
    iteration limit, a stall, or a Ctrl-C (`stop`: the plan so far, status "interrupted")."""
    watch = _ProgressWatch(options, run.largest_error())
    back: Fallback | None = None  # the run's state before the last `regait`

    def end(status: str, detail: str) -> Plan:  # a plan that did not converge: before a failed regait
        if back is None:
            return _make_plan(grasp0, grasp_goal, options, t_start, run, status, detail)
        return _finish(grasp0, grasp_goal, options, t_start, run, back.restore(run, status))

    while run.iterations < options.max_iters:
        if run.at_goals():
            outcome = run_final_moves(run, options) if options.final_move else FinalMoves("not_run", 0, ())
            if rounds.next(run, options, outcome):  # a polish or re-posture round moved a finger
                continue
            state = Fallback(len(run.steps), run.q, run.T_palm_object, outcome, run.iterations)
            if not regait(run, options, outcome):
                return _finish(grasp0, grasp_goal, options, t_start, run, outcome)
            back, watch = state, _ProgressWatch(options, run.largest_error())
        run.failures.clear()
        n_steps_before = len(run.steps)
        run.stalled = watch.stalled
        run.gait_round()
        if not run.at_goals():
            _repose(run, watch.escape)
        run.iterations += 1
        run.errors.append(float(np.mean(run.steps[-1].contact_error)))
        if progress is not None:
            progress(run.iterations, options.max_iters, run.errors[-1])
        watch.update(run.largest_error())
        if stop.requested:
            return _make_plan(grasp0, grasp_goal, options, t_start, run, "interrupted",
                              f"interrupted (Ctrl-C) after {run.iterations} iterations; largest contact "
                              f"error {run.largest_error() * 1e3:.2f} mm")
        if watch.exhausted and run.start_staging():
            watch.stalled = 0  # the last resort gets `stall_limit` more iterations
        elif watch.exhausted:
            hint = pinned_opposer_hint(run.obj, run.fingers, run.steps[-1], options.zeta) \
                if options.stability == "force_closure" else ""
            hint += stalled_fingers(run.hand, run.obj, run.q, run.T_palm_object, run.goal_tips,
                                    run.steps[-1].contact_error, options.zeta, q_goal=run.q_goal,
                                    eta=options.finger_gait.eta, across=run.across())
            if run.failures and len(run.steps) == n_steps_before:  # the last iteration could not move
                return end("solver_failure", "; ".join(run.failures) + hint)
            return end("stalled", f"{run.unmet()}: no progress in the last {watch.stalled} iterations{hint}")
    if back is not None and not run.at_goals():
        return end("iteration_limit", "")
    return _finish(grasp0, grasp_goal, options, t_start, run)


def _repose(run: _Run, escape: bool) -> None:
    """The iteration's reposing (`_Run.repose`); a stall escape refused for the whole way to the desired
    pose is asked again for part of it (`REGAIT_REACH`), as `final_rounds.regait` does. With method
    "sd", an escape that brings the object less than `PlannerOptions.sd_escape_gain` closer to the
    desired pose is followed by a reposing towards the SVD target (the goal contacts brought to the
    tips); so is any escape after which a finger reaches its goal only through another finger
    (`stall_report.reached_through_others`): the generated sphere pair of seed 19 (SD) stalled with the
    middle held off its goal by the index while the escapes turned the object about 0.5° at a time."""
    n_steps, gain = len(run.steps), run.options.sd_escape_gain
    fallback = escape and run.options.method == "sd" and gain is not None
    before = pose_distance(run.T_palm_object, run.T_palm_object_goal, run.obj) if fallback else 0.0
    for reach in REGAIT_REACH if escape else (1.0,):
        run.repose(escape=escape, reach=reach)
        if len(run.steps) > n_steps:
            break
    if fallback and before - pose_distance(run.T_palm_object, run.T_palm_object_goal, run.obj) < gain:
        run.repose(escape=False, contacts_target=True)
    if escape and run.options.method == "sd" and reached_through_others(
            run.hand, run.q, run.T_palm_object, run.goal_tips, run.steps[-1].contact_error, run.options.zeta,
            run.q_goal):
        run.repose(escape=False, contacts_target=True)


def _finish(grasp0: Grasp, grasp_goal: Grasp, options: PlannerOptions, t_start: float, run: _Run,
            outcome: FinalMoves | None = None) -> Plan:
    """The plan of a run whose iterations ended: the final moves (`outcome`, when they have run) if the
    contacts are reached and, when they stopped short with one component of the pose within tolerance,
    moves towards the other alone (`final_moves.aimed_moves`), then "converged", "pose_not_reached" or
    "iteration_limit" (`final_moves.decide_status`; "pose_not_reached" names the fingers bent unlike the
    goal grasp, `reposture.posture_report`)."""
    if outcome is None:
        outcome = FinalMoves("not_run", 0, ())
        if options.final_move and run.at_goals():
            outcome = run_final_moves(run, options)
    if outcome.stop not in SETTLED_STOPS and run.at_goals():
        outcome = aimed_moves(run, options, outcome)  # one pose component within tolerance, the other not
    if run.largest_error() <= options.zeta and run.across():  # within ζ, a finger across the object
        status, detail = "iteration_limit", f"{run.unmet()} after {run.iterations} iterations"
    else:
        status, detail = decide_status(run, options, outcome)
    if status == "pose_not_reached":
        detail += posture_report(run)
    return _make_plan(grasp0, grasp_goal, options, t_start, run, status, detail)


def _make_plan(grasp0: Grasp, grasp_goal: Grasp, options: PlannerOptions, t_start: float, run: _Run | None,
               status: str, detail: str) -> Plan:
    """The `Plan` of a run (None: no run, e.g. invalid input), with its timing and the options used."""
    hand, obj = grasp0.hand, grasp0.obj
    timing = _timing(run, t_start)
    opts = options.to_dict()
    if run is not None:
        opts["gait_used"] = list(run.gait)
        opts["solves"] = dict(run.solves)
    plan = Plan(steps=tuple(run.steps) if run else (),
                goal_contacts_object=np.asarray(grasp_goal.contacts_object, dtype=float),
                goal_T_palm_object=np.asarray(grasp_goal.T_palm_object, dtype=float),
                fingers=tuple(hand.fingers), hand_spec=hand.spec(), object_spec=dict(obj.spec),
                method=options.method, status=status, status_detail=detail,
                iterations=run.iterations if run else 0,
                iteration_errors=np.asarray(run.errors if run else [], dtype=float), timing=timing,
                options=opts)
    if options.trajectories and len(plan.steps) > 1:
        gait = options.finger_gait
        plan = attach_trajectories(plan, hand, obj, TrajectoryOptions(beta=gait.beta,
                                                                      self_clearance=gait.self_clearance))
    return plan


def _timing(run: _Run | None, t_start: float) -> dict[str, float]:
    """The run's time so far, s: NLP builds, OPT1, OPT2, the rest and the total since `t_start`."""
    timing = dict(run.timing) if run else {"build": 0.0, "opt1": 0.0, "opt2": 0.0, "other": 0.0}
    timing["total"] = time.perf_counter() - t_start
    timing["other"] = max(0.0, timing["total"] - timing["build"] - timing["opt1"] - timing["opt2"])
    return timing


def _trajectory_context(hand: Hand, obj, options: PlannerOptions):
    """The trajectories' context of a run (`trajectory.motion_context`, with the options `_make_plan`
    attaches the paths with)."""
    gait = options.finger_gait
    return motion_context(hand, obj, TrajectoryOptions(beta=gait.beta, self_clearance=gait.self_clearance))
