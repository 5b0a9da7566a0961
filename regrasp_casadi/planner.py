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
from dataclasses import asdict, dataclass, field, fields, replace
from typing import TYPE_CHECKING, ClassVar, Literal, TypeVar

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.constants import ZETA
from regrasp_casadi.finger_gait import FingerGaitNLP, FingerGaitOptions
from regrasp_casadi.in_grasp import InGraspNLP, InGraspOptions, svd_target
from regrasp_casadi.plan import Plan, PlanStep
from regrasp_casadi.solver import NLPCache
from regrasp_casadi.stability import holding_quality, torque_reference
from regrasp_casadi.transforms import rotation_angle

if TYPE_CHECKING:
    from regrasp_casadi.grasp import Grasp
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel

__all__ = ["PlannerOptions", "plan_regrasp", "gait_pattern", "clear_nlp_cache", "NLPCache"]

_log = logging.getLogger(__name__)

ProgressCallback = Callable[[int, int, float], None]
T = TypeVar("T")


@dataclass(frozen=True)
class PlannerOptions:
    """Options of `plan_regrasp`; the paper's values are the defaults (SI units).

    The knobs of the two NLPs are their own options, held here (`finger_gait`, `in_grasp`); the common
    ones can be given to `plan_regrasp` / `with_overrides` by name (``eta=0.008``, ``beta=...``), see
    `OVERRIDES`.
    """

    method: Literal["svd", "sd"] = "svd"
    """OPT2's E_des: "svd" (target pose by Kabsch, `in_grasp.svd_target`) or "sd" (distance to the
    workspace hulls)."""
    zeta: float = ZETA
    """ζ, threshold on the largest contact error, m (paper: 6 mm)."""
    max_iters: int = 50
    """Largest number of gait/reposing iterations (paper: 50)."""
    gait: tuple[str, ...] | None = None
    """Gait pattern P (finger order); None: the paper's rule (see `gait_pattern`)."""
    gait_order: Literal["pattern", "stability"] = "pattern"
    """"pattern": the fingers of P in its order (the paper); "stability": each next gait is the finger of
    P, not yet moved in this iteration, whose lift leaves the other fingers with the largest
    force-closure margin (`stability.holding_quality`, μ = 0.5) — an answer to the paper's open
    problems of gait order and grasp stability."""
    final_move: bool = True
    """Finish with in-grasp moves to the desired object pose (Algorithm 1, last lines)."""
    max_final_moves: int = 6
    """Largest number of final in-grasp moves (each bounded by the OPT2 trust region)."""
    final_pose_tol: float = 1e-3
    """Stop the final moves when the object is this close to the desired pose (m, and rad × 0.1 m)."""
    stall_tol: float = 1e-3
    """An iteration makes progress when the largest contact error drops by more than this, m (a gait
    moves a tip up to η = 10 mm: less than 1 mm means the fingers are blocked where they are)."""
    stall_escape: int = 2
    """After this many iterations without progress, reposings move towards the desired object pose
    (an addition to the paper: the desired grasp is feasible there, so its contacts become reachable)."""
    stall_limit: int = 10
    """After this many iterations without progress the plan stops with status "stalled"."""
    skip_tol: float = 1e-4
    """A finger whose contact is this close to its goal is not moved, m."""
    finger_gait: FingerGaitOptions = field(default_factory=FingerGaitOptions)
    """OPT1's options (η, β, exact-contact tolerance, ...)."""
    in_grasp: InGraspOptions = field(default_factory=InGraspOptions)
    """OPT2's options (k1, k2, β, trust region, ...)."""

    OVERRIDES: ClassVar[dict[str, tuple[str, ...]]] = {
        "eta": ("finger_gait",),
        "surface_tol": ("finger_gait",),
        "k_pos": ("in_grasp",),
        "k_orient": ("in_grasp",),
        "beta": ("finger_gait", "in_grasp"),
        "tau": ("finger_gait", "in_grasp"),
        "print_level": ("finger_gait", "in_grasp"),
    }
    """Keyword overrides that set fields of the NLPs' options: name → the sub-options that get it."""

    def __post_init__(self) -> None:
        if self.gait is not None:  # a list from the CLI or JSON: stored as a tuple
            object.__setattr__(self, "gait", tuple(self.gait))

    def with_overrides(self, **overrides) -> PlannerOptions:
        """A copy with `overrides` applied: this class's own fields (``method="sd"``, ``max_iters=5``,
        ``finger_gait=FingerGaitOptions(...)``) first, then the names of `OVERRIDES` (``eta=0.008``),
        which set that field of each sub-options listed there.

        Raises:
            TypeError: for a name that is neither a field nor in `OVERRIDES`.
        """
        own = {k: v for k, v in overrides.items() if k not in self.OVERRIDES}
        unknown = sorted(set(own) - {f.name for f in fields(self)})
        if unknown:
            raise TypeError(f"unknown planner options {unknown}; the options are "
                            f"{[f.name for f in fields(self)] + list(self.OVERRIDES)}")
        options = replace(self, **own)
        for name, value in overrides.items():
            for sub in self.OVERRIDES.get(name, ()):
                options = replace(options, **{sub: replace(getattr(options, sub), **{name: value})})
        return options

    def to_dict(self) -> dict:
        """The options as plain data (nested dicts for the NLPs' options; the gait as a list or None),
        as written into `Plan.options`."""
        opts = asdict(self)
        opts["gait"] = list(opts["gait"]) if opts["gait"] is not None else None
        return opts


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
    """Forget every NLP of the process-wide cache (they are rebuilt on the next plan)."""
    _DEFAULT_CACHE.clear()


class _Run:
    """State of one planning run: the steps so far, timing, and the NLPs it uses."""

    def __init__(self, hand: Hand, obj: ObjectModel, goal_contacts: NDArray, goal_tips: NDArray,
                 options: PlannerOptions, cache: NLPCache):
        self.hand, self.obj, self.options, self.cache = hand, obj, options, cache
        self.goal_contacts, self.goal_tips = goal_contacts, goal_tips
        self.steps: list[PlanStep] = []
        self.timing = {"build": 0.0, "opt1": 0.0, "opt2": 0.0, "other": 0.0, "total": 0.0}
        self.solves = {"opt1": 0, "opt2": 0}
        self.gait: tuple[str, ...] = tuple(hand.fingers)
        self.com, self.length = torque_reference(obj.mesh)  # of the stability-aware gait order

    def gait_nlp(self, finger: str) -> FingerGaitNLP:
        o = self.options.finger_gait
        return self.cache.get("finger_gait", self.hand, self.obj, (finger, o),
                              self._timed(lambda: FingerGaitNLP(self.hand, self.obj, finger, o)))

    def in_grasp_nlp(self, method: str) -> InGraspNLP:
        o = self.options.in_grasp
        return self.cache.get("in_grasp", self.hand, self.obj, (method, o),
                              self._timed(lambda: InGraspNLP(self.hand, self.obj, method, o)))

    def _timed(self, build: Callable[[], T]) -> Callable[[], T]:
        """`build`, adding its time to the run's build time (a cache hit adds nothing)."""

        def timed_build() -> T:
            t0 = time.perf_counter()
            nlp = build()
            self.timing["build"] += time.perf_counter() - t0
            return nlp

        return timed_build

    def most_stable_gait(self, q: NDArray, T_palm_object: NDArray, todo: list[str]) -> str:
        """Remove and return the finger of `todo` whose lift leaves the best-held grasp."""
        tips = self.tips_object(q, T_palm_object)
        contacts, _ = self.obj.closest_points(tips)
        fingers = list(self.hand.fingers)
        eps = [holding_quality(contacts, tips, fingers.index(f), self.com, self.length) for f in todo]
        return todo.pop(int(np.argmax(eps)))

    def tips_object(self, q: NDArray, T_palm_object: NDArray) -> NDArray:
        """Tip-sphere centres (m, 3) in the object frame."""
        return (self.hand.tip_positions(q) - T_palm_object[:3, 3]) @ T_palm_object[:3, :3]

    def add_step(self, kind: str, finger: str | None, q: NDArray, T_palm_object: NDArray, status: str,
                 solve_time: float) -> PlanStep:
        contacts, _ = self.obj.closest_points(self.tips_object(q, T_palm_object))
        error = np.linalg.norm(contacts - self.goal_contacts, axis=1)
        step = PlanStep(kind=kind, finger=finger, q=np.array(q, dtype=float),
                        T_palm_object=np.array(T_palm_object, dtype=float),
                        contacts_object=np.asarray(contacts, dtype=float), contact_error=error,
                        solver_status=status, solve_time=float(solve_time))
        self.steps.append(step)
        return step


def plan_regrasp(grasp0: Grasp, grasp_goal: Grasp, *, options: PlannerOptions | None = None,
                 progress: ProgressCallback | None = None, cache: NLPCache | None = None,
                 **overrides) -> Plan:
    """Plan an in-hand regrasp from `grasp0` to `grasp_goal` (Algorithm 1).

    Args:
        grasp0: the initial grasp; it must carry joint angles (`Grasp.from_joints`).
        grasp_goal: the desired grasp: contacts (object frame) and desired object pose.
        options: a `PlannerOptions`; keyword `overrides` replace its fields (e.g. ``method="sd"``).
        progress: optional callable ``progress(iteration, max_iters, average_error_m)`` called after
            every iteration.
        cache: where the NLPs are kept between plans (default: the process-wide cache that
            `clear_nlp_cache` clears).

    Returns:
        A `Plan` whose `status` says why it stopped: "converged", "iteration_limit", "stalled" (no
        progress for `stall_limit` iterations), "solver_failure" (with the step and IPOPT's status in
        `status_detail`) or "invalid_input". A failed solve never raises: the plan ends with the steps
        so far.
    """
    t_start = time.perf_counter()
    options = (options or PlannerOptions()).with_overrides(**overrides)
    hand, obj = grasp0.hand, grasp0.obj
    goal_contacts = np.asarray(grasp_goal.contacts_object, dtype=float)
    goal_T = np.asarray(grasp_goal.T_palm_object, dtype=float)
    fingers = tuple(hand.fingers)

    def make_plan(run: _Run | None, status: str, detail: str, iterations: int, errors: list[float]) -> Plan:
        steps = tuple(run.steps) if run else ()
        timing = dict(run.timing) if run else {"build": 0.0, "opt1": 0.0, "opt2": 0.0, "other": 0.0}
        timing["total"] = time.perf_counter() - t_start
        timing["other"] = max(0.0, timing["total"] - timing["build"] - timing["opt1"] - timing["opt2"])
        opts = options.to_dict()
        if run is not None:
            opts["gait_used"] = list(run.gait)
            opts["solves"] = dict(run.solves)
        return Plan(steps=steps, goal_contacts_object=goal_contacts, goal_T_palm_object=goal_T,
                    fingers=fingers, hand_spec=hand.spec(), object_spec=dict(obj.spec), method=options.method,
                    status=status, status_detail=detail, iterations=iterations,
                    iteration_errors=np.asarray(errors, dtype=float), timing=timing, options=opts)

    problems = _check_input(grasp0, grasp_goal, options)
    if problems:
        return make_plan(None, "invalid_input", problems, 0, [])

    goal_tips = np.asarray(grasp_goal.tip_centers_object, dtype=float)
    run = _Run(hand, obj, goal_contacts, goal_tips, options, _DEFAULT_CACHE if cache is None else cache)
    q = np.asarray(grasp0.q, dtype=float)
    T = np.asarray(grasp0.T_palm_object, dtype=float)
    step = run.add_step("initial", None, q, T, "", 0.0)
    run.gait = options.gait or gait_pattern(hand, step.contacts_object, goal_contacts)
    gait_nlps = {f: run.gait_nlp(f) for f in run.gait}
    pose_nlp = run.in_grasp_nlp("svd")  # SVD reposing, stall escape and final moves
    repose_nlp = pose_nlp if options.method == "svd" else run.in_grasp_nlp("sd")
    for nlp in [*gait_nlps.values(), pose_nlp, repose_nlp]:
        nlp.reset()  # same input, same plan: no warm start carried over from another plan
    errors = [float(np.mean(step.contact_error))]
    err = float(np.max(step.contact_error))
    n = 0
    failures: list[str] = []  # rejected solves of the current iteration ("<what>: IPOPT <status>")
    best_err, stalled = err, 0  # progress watch: iterations since the largest error last dropped
    while err > options.zeta and n < options.max_iters:
        failures.clear()
        n_steps_before = len(run.steps)
        todo = list(run.gait)
        while todo:
            finger = todo.pop(0) if options.gait_order == "pattern" else run.most_stable_gait(q, T, todo)
            r = fingers.index(finger)
            if run.steps[-1].contact_error[r] <= options.skip_tol:
                continue
            res = gait_nlps[finger].solve(q, T, goal_tips[r])
            run.timing["opt1"] += res.solve_time
            run.solves["opt1"] += res.solves
            if not res.success:  # the finger stays where it is, which is feasible
                failures.append(f"finger gait of {finger} at step {len(run.steps)} rejected by the exact "
                                f"checks (surface error {res.surface_error * 1e3:.3f} mm, clearance "
                                f"{res.min_clearance * 1e3:.3f} mm; IPOPT: {res.status})")
                _log.debug("%s; the finger stays", failures[-1])
                continue
            moved = np.linalg.norm(hand.tip_positions(res.q)[r] - hand.tip_positions(q)[r])
            if moved < 1e-5:
                continue
            q = res.q
            run.add_step("gait", finger, q, T, res.status, res.solve_time)
        err = float(np.max(run.steps[-1].contact_error))
        if err > options.zeta:
            tips = run.tips_object(q, T)
            nlp = repose_nlp
            if stalled >= options.stall_escape:  # escape: repose towards the desired object pose
                nlp, target = pose_nlp, {"T_target": goal_T}
            elif options.method == "svd":
                target = {"T_target": svd_target(T, run.steps[-1].contacts_object, goal_contacts)}
            else:
                target = {"p_object_tips_goal": goal_tips}
            res2 = nlp.solve(q, T, tips, **target)
            run.timing["opt2"] += res2.solve_time
            run.solves["opt2"] += 1
            if res2.success:
                q, T = res2.q, res2.T_palm_object
                step = run.add_step("repose", None, q, T, res2.status, res2.solve_time)
                err = float(np.max(step.contact_error))
            else:  # the object stays where it is
                failures.append(f"reposing at step {len(run.steps)} rejected by the exact checks (clearance "
                                f"{res2.min_clearance * 1e3:.3f} mm, slip {res2.max_slip * 1e3:.3f} mm, "
                                f"surface error {res2.surface_error * 1e3:.3f} mm; IPOPT: {res2.status})")
                _log.debug("%s; the object stays", failures[-1])
        n += 1
        errors.append(float(np.mean(run.steps[-1].contact_error)))
        if progress is not None:
            progress(n, options.max_iters, errors[-1])
        if err < best_err - options.stall_tol:
            best_err, stalled = err, 0
        else:
            stalled += 1
            if stalled >= options.stall_limit:
                if failures and len(run.steps) == n_steps_before:  # the last iteration could not move
                    return make_plan(run, "solver_failure", "; ".join(failures), n, errors)
                return make_plan(run, "stalled", f"largest contact error {err * 1e3:.2f} mm > ζ: no progress "
                                 f"in the last {stalled} iterations", n, errors)
    converged = err <= options.zeta
    final_note = ""
    if options.final_move and converged:
        for _ in range(options.max_final_moves):
            if _pose_distance(T, goal_T, obj) <= options.final_pose_tol:
                break
            res3 = pose_nlp.solve(q, T, run.tips_object(q, T), T_target=goal_T)
            run.timing["opt2"] += res3.solve_time
            run.solves["opt2"] += 1
            if not res3.success:  # the contacts are reached; the object stays where it is
                final_note = (f"; the final in-grasp move towards the desired pose was rejected by the "
                              f"exact checks (slip {res3.max_slip * 1e3:.2f} mm, clearance "
                              f"{res3.min_clearance * 1e3:.2f} mm; IPOPT: {res3.status})")
                break
            progress_made = _pose_distance(T, goal_T, obj) - _pose_distance(res3.T_palm_object, goal_T, obj)
            q, T = res3.q, res3.T_palm_object
            run.add_step("final", None, q, T, res3.status, res3.solve_time)
            if progress_made < 1e-4:
                break
        err = float(np.max(run.steps[-1].contact_error))
        converged = err <= options.zeta
    if converged:
        detail = (f"largest contact error {err * 1e3:.2f} mm ≤ ζ = {options.zeta * 1e3:.1f} mm; object "
                  f"{_pose_distance(T, goal_T, obj) * 1e3:.2f} mm from the desired pose{final_note}")
        return make_plan(run, "converged", detail, n, errors)
    return make_plan(run, "iteration_limit",
                     f"largest contact error {err * 1e3:.2f} mm > ζ after {n} iterations", n, errors)


def _pose_distance(T_a: NDArray, T_b: NDArray, obj: ObjectModel) -> float:
    """Pose distance, m: translation plus rotation angle times the object's radius."""
    radius = 0.5 * float(np.linalg.norm(obj.mesh.extents))
    return float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3]) + radius * rotation_angle(T_a[:3, :3], T_b[:3, :3]))


def _check_input(grasp0: Grasp, grasp_goal: Grasp, options: PlannerOptions) -> str:
    """Why the input cannot be planned ("" when it can)."""
    if grasp0.q is None:
        return "the initial grasp has no joint angles (build it with Grasp.from_joints)"
    if grasp_goal.hand is not grasp0.hand and grasp_goal.hand.spec() != grasp0.hand.spec():
        return "the initial and desired grasps use different hands"
    if grasp_goal.obj is not grasp0.obj and grasp_goal.obj.spec != grasp0.obj.spec:
        return "the initial and desired grasps use different objects"
    if options.method not in ("svd", "sd"):
        return f"unknown method {options.method!r} (use 'svd' or 'sd')"
    if options.gait_order not in ("pattern", "stability"):
        return f"unknown gait_order {options.gait_order!r} (use 'pattern' or 'stability')"
    if options.gait is not None:
        unknown = [f for f in options.gait if f not in grasp0.hand.fingers]
        if unknown:
            return f"gait names unknown fingers {unknown}; the hand has {list(grasp0.hand.fingers)}"
    gait, in_grasp = options.finger_gait, options.in_grasp
    if not (options.zeta > 0 and gait.eta > 0 and gait.beta >= 0 and in_grasp.beta >= 0
            and options.max_iters >= 0):
        return "zeta and eta must be positive, beta and max_iters non-negative"
    return ""
