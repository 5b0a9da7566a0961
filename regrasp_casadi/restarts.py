"""Restarts: a plan that does not converge is planned again from the start with a variant of its options.

The planner is a local method: each gait and reposing is a local optimum of its NLP, and the next one
starts where it ended, so a plan amplifies small differences. Measured: the same code (525e128) and
the same generated pairs gave 116 of 120 converged plans on the objects table's seeds 0–9
(`benchmarks/objects.py`) on one VM and 113 on another of the same CPU family (kernel builds v1272 and
v1300), plans failing on one machine converging on the other (bowl 6 SVD, cup 0 SVD, sphere 0 SD). A
plan that stalls so is a draw of a chaotic process more than a verdict on the pair, and a draw with
other, equally valid choices often converges. Of the 20 of 240 plans of both seed sets (0–19) that did
not converge on the second VM (stability "none"), planned again: 8 converge with the gait pattern
reversed (sphere 0 and 7 SD, bowl 6 both methods, cup 11 SD, flat tool 11 both, holed box 12 SD), one
more with the stability gait order (bowl 15 SD) and one more with η × 0.7 (cup 0 SVD); the other 10
(bowl 5, 16 and 19, cup 15 and mug 10, both methods: a finger whose goal is across a wall or the
handle) fail with all three, and cost four plans' time (mug 10 SD: 888 s against 157 s for its first).

`restarted` makes up to `PlannerOptions.restart_count` such draws (3 for the paper's planner, 1 with a
stability certificate, by default), in the order of `VARIANTS`, each a whole
plan from the initial grasp, and returns the first that converges; if none does, the first plan, with
what the restarts ended in added to its status detail. A plan that converges the first time is the
same plan as without restarts. Every draw is deterministic, so the call still is: the same input gives
the same plan. The plan's options are its variant's (planned again with them, without restarts, they
give the same plan); `Plan.options["restart"]` names the variant ("" for the first plan),
`Plan.options["attempts"]` counts the plans made, `Plan.options["iterations_all"]` their iterations,
and `Plan.timing` and `Plan.options["solves"]` are the whole call's. The planner's progress callback
counts on through the restarts (`continued`): a restart's iterations follow the earlier plans', so a
progress bar goes on rather than back to the start.

    >>> plan = restarted(first_plan, options, replan)   # replan(options, done) -> Plan, one more whole
    ...                                                 # plan, its progress counted after `done` iterations
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import Plan
    from regrasp_casadi.planner_options import PlannerOptions

__all__ = ["RESTART_STATUSES", "VARIANTS", "continued", "restart_options", "restarted"]

RESTART_STATUSES = ("stalled", "iteration_limit", "pose_not_reached", "solver_failure")
"""The statuses after which a plan is planned again (not "converged", "interrupted", "invalid_input")."""


def _reversed_gait(options: PlannerOptions, gait_used: tuple[str, ...]) -> PlannerOptions:
    """The gait pattern the first plan used, in reverse order."""
    return replace(options, gait=tuple(reversed(gait_used)))


def _other_order(options: PlannerOptions, gait_used: tuple[str, ...]) -> PlannerOptions:
    """The gait pattern in the stability order (each round's next gait the finger whose lift leaves the
    best-held grasp, `PlannerOptions.gait_order`); the pattern's own order when the first plan used
    another."""
    return replace(options, gait_order="stability" if options.gait_order == "pattern" else "pattern")


def _shorter_gaits(options: PlannerOptions, gait_used: tuple[str, ...]) -> PlannerOptions:
    """OPT1's step bound η × `ETA_FACTOR`."""
    return options.with_overrides(eta=ETA_FACTOR * options.finger_gait.eta)


ETA_FACTOR = 0.7
"""The shorter gaits' η, as a fraction of the first plan's."""

VARIANTS: tuple[tuple[str, Callable[[PlannerOptions, tuple[str, ...]], PlannerOptions]], ...] = (
    ("gait reversed", _reversed_gait),
    ("the other gait order", _other_order),
    ("shorter gaits", _shorter_gaits),
)
"""(name, make) of each restart, in order: `make(options, gait_used)` gives the variant's options from
the first plan's options and the gait pattern it used (`Plan.options["gait_used"]`)."""


def restart_options(options: PlannerOptions, gait_used: tuple[str, ...]) -> list[tuple[str, PlannerOptions]]:
    """The first `options.restart_count` variants (name, options), each with no restarts of its own."""
    return [(name, replace(make(options, gait_used), restarts=0))
            for name, make in VARIANTS[:options.restart_count]]


def continued(progress: Callable[[int, int, float], None] | None,
              done: int) -> Callable[[int, int, float], None] | None:
    """The planner's ``progress(iteration, max_iters, average_error_m)`` for a plan made after `done`
    iterations of earlier ones: both counts shifted by `done` (None stays None)."""
    if progress is None or done == 0:
        return progress
    return lambda iteration, max_iters, error_m: progress(done + iteration, done + max_iters, error_m)


def restarted(first: Plan, options: PlannerOptions, replan: Callable[[PlannerOptions, int], Plan]) -> Plan:
    """The first converged plan of the restarts of `first` (a plan of `options` whose status is in
    `RESTART_STATUSES`), each made by `replan(variant_options, done)` (`done`: the iterations of the
    plans before it); else `first`, its detail naming what the restarts ended in, its status
    "interrupted" when a Ctrl-C stopped a restart. The plan returned has the whole call's timing (s,
    summed per key)."""
    plans = [first]
    tried = []
    for name, variant in restart_options(options, tuple(first.options.get("gait_used") or ())):
        plan = replan(variant, sum(p.iterations for p in plans))
        plans.append(plan)
        tried.append(f"{name}: {plan.status}")
        if plan.status == "converged":
            detail = f"{plan.status_detail}; restart ({name}) after the first plan ended {first.status}"
            return _whole_call(plan, plans, name, detail)
        if plan.status == "interrupted":  # Ctrl-C: the first plan, whole, comes back as interrupted
            detail = (f"interrupted (Ctrl-C) during restart {len(plans) - 1} ({name}); the steps are the "
                      f"first plan's, which ended {first.status}: {first.status_detail}")
            return _whole_call(replace(first, status="interrupted"), plans, "", detail)
        if plan.status not in RESTART_STATUSES:  # invalid_input (a variant refused): stop there
            break
    detail = first.status_detail + (f"; restarts did not converge ({'; '.join(tried)})" if tried else "")
    return _whole_call(first, plans, "", detail)


def _whole_call(plan: Plan, plans: list[Plan], name: str, detail: str) -> Plan:
    """`plan` with `detail`, the restart's name in its options, and the timing (s), iterations and solve
    counts (`options["solves"]`) of all `plans` summed per key, as the planner's own retries count them."""
    return replace(plan, status_detail=detail, timing=_summed([p.timing for p in plans]),
                   options={**plan.options, "restart": name, "attempts": len(plans),
                            "iterations_all": sum(p.iterations for p in plans),
                            "solves": _summed([p.options.get("solves") or {} for p in plans])})


def _summed(counts: list[dict]) -> dict:
    """The values of `counts` summed per key (keys in first-seen order)."""
    total: dict = {}
    for c in counts:
        for key, value in c.items():
            total[key] = total.get(key, 0) + value
    return total
