"""The planner's options (`PlannerOptions`): the paper's values as defaults, the NLPs' and the stability
checks' options nested, and the keyword overrides `plan_regrasp` accepts.

    >>> options = PlannerOptions(method="sd").with_overrides(eta=0.008, stability="none")
    >>> plan = plan_regrasp(grasp0, grasp_goal, options=options)
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from typing import TYPE_CHECKING, ClassVar, Literal

import numpy as np

from regrasp_casadi.certificates import GRAVITY
from regrasp_casadi.constants import ZETA
from regrasp_casadi.finger_gait import FingerGaitOptions
from regrasp_casadi.holding import STABILITY_KINDS, HoldingOptions
from regrasp_casadi.in_grasp import InGraspOptions

if TYPE_CHECKING:
    from regrasp_casadi.grasp import Grasp

__all__ = ["PlannerOptions", "RESTARTS_CERTIFIED", "RESTARTS_UNCERTIFIED", "input_problem", "number_problem",
           "stability_problem"]

RESTARTS_UNCERTIFIED = 3
"""Default `PlannerOptions.restarts` of the paper's planner (stability "none"). Measured (2026-12-08,
`benchmarks/objects.py`, 240 plans of 120 generated pairs): 10 of its 20 failing plans converge on a
restart, 8 with the gait reversed, 1 with the other gait order, 1 with η × 0.7."""
RESTARTS_CERTIFIED = 1
"""Default `PlannerOptions.restarts` with a stability certificate: the gait reversed alone. Measured
(2026-12-08, `benchmarks/regression.py --stability force_closure`, the 50 YCB and 12 shipped plans):
3 of the 58 failing certified plans converge on a restart, all 3 with the gait reversed; the other two
variants converge none. The plans' summed time: 807 s without restarts, 1,619 s with this one,
3,124 s with three."""


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
    gait_order: Literal["pattern", "stability", "search"] = "pattern"
    """"pattern": the fingers of P in its order (the paper; with `stability` on, the next finger of P
    whose lift is certified); "stability": each next gait is the finger of P, not yet moved in this
    iteration, whose lift leaves the other fingers with the largest force-closure margin
    (`stability.holding_quality`, μ = 0.5); "search" (needs `stability` on): the certified lift with
    the best progress + margin score (`_Run.search_score`)."""
    stability: Literal["force_closure", "gravity", "none"] = "force_closure"
    """The certificate every step must have (`holding`): "force_closure" of the fingers that hold the
    object, "gravity" (they hold its weight, `gravity_palm` × `object_mass`), or "none" (the paper: no
    stability test, the plans of the paper's algorithm). With a certificate, a finger whose lift is
    not certified waits for a later turn of the round or slides (`holding.slide`), and every step stores
    its certificate (`PlanStep.certificate`)."""
    gravity_palm: tuple[float, float, float] = (0.0, 0.0, -GRAVITY)
    """Gravitational acceleration in the palm frame, m/s² (stability "gravity")."""
    object_mass: float | None = None
    """The object's mass, kg (stability "gravity"; None: mesh volume × `holding.density`); a problem
    file states it as `object.mass` (`RegraspProblem.object_mass`)."""
    holding: HoldingOptions = field(default_factory=HoldingOptions)
    """The stability checks' and sliding steps' options (μ, margins, slide step, lookahead)."""
    final_move: bool = True
    """Finish with in-grasp moves to the desired object pose (Algorithm 1, last lines; `final_moves`:
    each accepted move brings the object closer to it)."""
    final_regait: bool = True
    """When the final moves stop short of the desired pose (the next one would take a contact farther
    than ζ from its goal, as rolling tips carry their contacts along, `InGraspOptions.rolling`, or it was
    refused), repose towards the desired pose anyway (accepted when it brings the object closer) and go
    on with gait rounds, which bring the contacts back, then try the final moves again (within
    `max_iters`; `final_rounds.regait`). False: stop there."""
    final_polish: int = 2
    """When the final moves stop short of the desired pose with the contacts within ζ but not at their
    goals, this many more gait rounds (each followed by the final moves again) bring the contacts to
    their goals first (`final_rounds.polish`); a grasp nearer the desired one leaves the final moves less in
    their way (its joints, the fingers' self-clearance). Not after a contact drift (`final_regait`'s
    case). 0: none."""
    final_reposture: int = 3
    """When the final moves stop short of the desired pose and the `final_polish` rounds are spent or
    moved no finger, this many rounds of re-posture gaits (each followed by the final moves again): a
    finger farther than `reposture.POSTURE_TOL` from the goal grasp's posture is lifted and put down on
    its goal contact in that posture (`reposture`; the final moves stall against the joint limits of a
    finger bent unlike the goal grasp's). 0: none."""
    final_max_iterations: int = 15_000
    """IPOPT iterations the OPT2 solves of one run of the final in-grasp moves may take (retries
    included): a bound in work, not time, so that a plan does not depend on the machine's speed.
    Measured on the objects table (`benchmarks/objects.py`, seeds 0–19: 240 plans, 426 runs of the final
    moves): the most one run of a converged plan took was 9,675 iterations (the cup pair of seed 12,
    svd: 43 s on the 2-core benchmark machine, 4.5 ms an iteration); the one plan that had stopped on
    the 60 s wall-clock budget this replaces (the bowl pair of seed 15, sd, failing either way) made
    13,219 in 60 s."""
    final_time_budget: float | None = None
    """Time one run of the final in-grasp moves may take, s; None (default): no wall-clock bound (a plan
    that reaches it depends on the machine's speed)."""
    final_pose_tol: float = 5e-4
    """Stop the final moves when the object is this close to the desired pose, m
    (`final_moves.pose_distance`: translation plus rotation angle times the object's radius)."""
    final_min_gain: float = 2e-5
    """A final move that brings the object less than this closer to the desired pose ends them, m."""
    pose_tol_position: float = 2e-3
    """A "converged" plan's object is within this distance of the desired position, m."""
    pose_tol_rotation: float = float(np.radians(2.0))
    """... and within this angle of the desired orientation, rad (2°)."""
    stall_tol: float = 1e-3
    """An iteration makes progress when the largest contact error drops by more than this, m (a gait
    moves a tip up to η = 10 mm: less than 1 mm means the fingers are blocked where they are)."""
    stall_escape: int = 2
    """After this many iterations without progress, reposings move towards the desired object pose
    (an addition to the paper: the desired grasp is feasible there, so its contacts become reachable;
    refused for the whole way, for 1/2 and 1/4 of it), and each finger still beyond ζ also tries a gait
    started on the joint-space way to its goal (`long_gait`: out of OPT1's local minimum at an edge)."""
    stall_limit: int = 10
    """After this many iterations without progress the plan stops with status "stalled"."""
    surface_routes: bool = True
    """A finger whose straight line to its goal passes through the object (its goal behind a thin
    wall's rim, round an edge) aims each gait η along the shortest way over the surface instead
    (`surface_route.gait_target`; an addition to the paper, whose OPT1 stalls such a finger on the
    wrong side). False: the goal tip centre, as in the paper."""
    route_after: int = 1
    """Surface routes are taken once the plan has gone this many iterations without progress: taken
    from the first iteration, the middle and ring of the shipped cup_regrasp (SD) followed theirs into a
    stall 74 mm from the ring's goal, where the straight pull converges (routes are the stall's remedy,
    not the default)."""
    sd_escape_gain: float | None = 2e-3
    """Method "sd": a stall escape that brings the object less than this closer to the desired pose
    (`final_moves.pose_distance`, m) is followed, in the same iteration, by a reposing towards the SVD
    target (`in_grasp.svd_target`: the goal contacts brought towards the tips); None: never. An addition
    to the paper: the workspaces' target cannot pull a goal that is inside a finger's workspace hull but
    out of its reach, and the desired pose can be blocked by the grasp on the way (the generated cup pair
    of seed 4 stalled so with SD, its escapes creeping < 1 mm per iteration; it converges with it)."""
    free_after: int | None = 9
    """After this many iterations without progress, a finger beyond ζ whose goal is out of its reach or
    reached only with a link in the object, and which `long_gait` and `make_way` did not move, has the
    object reposed towards a few other poses until its goal is within reach cleanly, then takes a gait
    (`free_finger`; once per stall; an addition to the paper). For a plan that does not converge without
    it, a re-posture round searches so too for a finger whose goal posture is obstructed, from where
    the re-posture rounds first moved no finger (`final_rounds.free_postures`,
    `reposture.posture_obstruction`). None: neither."""
    restarts: int | None = None
    """A plan that does not converge ("stalled", "iteration_limit", "pose_not_reached",
    "solver_failure") is planned again from the start with up to this many variants of these options,
    in order (`restarts.VARIANTS`: the gait pattern reversed, the other gait order, η × 0.7); the first
    that converges is the plan, else the first plan with the restarts' statuses in its detail
    (`restarts.restarted`; an addition to the paper: the plans are local and amplify small
    differences, so a stall is often a draw, not a verdict). 0: none. None (the default):
    `RESTARTS_UNCERTIFIED` with stability "none", `RESTARTS_CERTIFIED` with a certificate
    (`restart_count`; `Plan.options["restarts"]` is that number, 0 in a plan a restart returned: its
    variant's options make none)."""
    skip_tol: float = 1e-4
    """A finger whose contact is this close to its goal is not moved, m."""
    finger_gait: FingerGaitOptions = field(default_factory=FingerGaitOptions)
    """OPT1's options (η, β, exact-contact tolerance, ...)."""
    in_grasp: InGraspOptions = field(default_factory=InGraspOptions)
    """OPT2's options (k1, k2, β, trust region, ...)."""
    trajectories: bool = True
    """Give every step its motion from the step before (`trajectory.attach_trajectories`: lift-off,
    transit and touch-down of gaits, reposing paths; β and self-clearance of the finger gait); False:
    static steps only."""

    OVERRIDES: ClassVar[dict[str, tuple[str, ...]]] = {
        "eta": ("finger_gait",),
        "surface_tol": ("finger_gait",),
        "k_pos": ("in_grasp",),
        "k_orient": ("in_grasp",),
        "beta": ("finger_gait", "in_grasp"),
        "tau": ("finger_gait", "in_grasp"),
        "print_level": ("finger_gait", "in_grasp"),
        "self_clearance": ("finger_gait", "in_grasp"),
        "mu": ("holding",),
        "max_normal_force": ("holding",),
        "min_normal_force": ("holding",),
        "min_load_share": ("holding",),
        "max_joint_torque": ("holding",),
        "rolling": ("in_grasp",),
        "gravity_margin": ("holding",),
        "slide_drag_range": ("holding",),
        "min_margin": ("holding",),
        "slide": ("holding",),
        "lookahead": ("holding",),
    }
    """Keyword overrides that set fields of the NLPs' options: name → the sub-options that get it."""

    def __post_init__(self) -> None:
        if self.gait is not None:  # a list from the CLI or JSON: stored as a tuple
            object.__setattr__(self, "gait", tuple(self.gait))
        object.__setattr__(self, "gravity_palm", tuple(float(g) for g in self.gravity_palm))

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

    @property
    def restart_count(self) -> int:
        """The restarts a plan of these options makes: `restarts`, or its default for the stability."""
        if self.restarts is not None:
            return self.restarts
        return RESTARTS_UNCERTIFIED if self.stability == "none" else RESTARTS_CERTIFIED

    def to_dict(self) -> dict:
        """The options as plain data (nested dicts for the NLPs' options; the gait as a list or None;
        `restarts` the number used, `restart_count`), as written into `Plan.options`."""
        opts = asdict(self)
        opts["restarts"] = self.restart_count
        opts["gait"] = list(opts["gait"]) if opts["gait"] is not None else None
        opts["gravity_palm"] = list(opts["gravity_palm"])
        return opts


def stability_problem(options: PlannerOptions) -> str:
    """Why the stability options cannot be planned with ("" when they can)."""
    if options.stability not in STABILITY_KINDS:
        return f"unknown stability {options.stability!r} (use {', '.join(map(repr, STABILITY_KINDS))})"
    if options.gait_order == "search" and options.stability == "none":
        return "gait_order 'search' searches over certified gaits: it needs stability on"
    if options.stability == "gravity" and not (np.all(np.isfinite(options.gravity_palm))
                                                and np.linalg.norm(options.gravity_palm) > 0):
        return f"gravity_palm must be a non-zero acceleration (m/s²), got {options.gravity_palm}"
    if options.object_mass is not None and not options.object_mass > 0:
        return f"object_mass must be > 0 kg, got {options.object_mass}"
    return ""


def number_problem(options: PlannerOptions) -> str:  # noqa: PLR0911
    """Why the planner's numeric options cannot be planned with ("" when they can): a chain of checks,
    each returning its message."""
    gait, in_grasp = options.finger_gait, options.in_grasp
    if not (options.zeta > 0 and gait.eta > 0 and gait.beta >= 0 and in_grasp.beta >= 0
            and options.max_iters >= 0):
        return "zeta and eta must be positive, beta and max_iters non-negative"
    if any(c is not None and not c >= 0 for c in (gait.self_clearance, in_grasp.self_clearance)):
        return "self_clearance must be non-negative or None (no self-collision constraints)"
    free_after = options.free_after
    if free_after is not None and not (isinstance(free_after, int) and free_after >= 0):
        return f"free_after must be a non-negative number of iterations or None, got {options.free_after!r}"
    budget = options.final_max_iterations
    if not (isinstance(budget, int) and budget >= 0):
        return f"final_max_iterations must be a non-negative number of iterations, got {budget!r}"
    if options.final_time_budget is not None and not options.final_time_budget >= 0:
        return f"final_time_budget must be non-negative (s) or None, got {options.final_time_budget}"
    if options.sd_escape_gain is not None and not options.sd_escape_gain >= 0:
        return f"sd_escape_gain must be non-negative (m) or None, got {options.sd_escape_gain}"
    restarts = options.restarts
    if restarts is not None and not (isinstance(restarts, int) and restarts >= 0):
        return f"restarts must be a non-negative number of plans or None, got {restarts!r}"
    return ""


def input_problem(grasp0: Grasp, grasp_goal: Grasp, options: PlannerOptions) -> str:  # noqa: PLR0911
    """Why the input cannot be planned ("" when it can): a chain of checks, each returning its message
    (hence the returns beyond PLR0911's limit)."""
    if grasp0.q is None:
        return "the initial grasp has no joint angles (build it with Grasp.from_joints)"
    if grasp_goal.hand is not grasp0.hand and grasp_goal.hand.spec() != grasp0.hand.spec():
        return "the initial and desired grasps use different hands"
    if grasp_goal.obj is not grasp0.obj and grasp_goal.obj.spec != grasp0.obj.spec:
        return "the initial and desired grasps use different objects"
    if options.method not in ("svd", "sd"):
        return f"unknown method {options.method!r} (use 'svd' or 'sd')"
    if options.gait_order not in ("pattern", "stability", "search"):
        return f"unknown gait_order {options.gait_order!r} (use 'pattern', 'stability' or 'search')"
    stability = stability_problem(options)
    if stability:
        return stability
    if options.gait is not None:
        unknown = [f for f in options.gait if f not in grasp0.hand.fingers]
        if unknown:
            return f"gait names unknown fingers {unknown}; the hand has {list(grasp0.hand.fingers)}"
    numbers = number_problem(options)
    if numbers:
        return numbers
    return grasp0.inconsistency("grasp0")
