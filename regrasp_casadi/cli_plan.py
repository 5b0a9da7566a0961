"""Planning for the `regrasp plan` and `regrasp demo` commands: the planner's options from the flags, its
progress bar (counting on through the planner's restarts), and the line that says a plan was restarted.

    plan = run_plan(problem, "svd", max_iters=None, show_progress=True, restarts=1)
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from regrasp_casadi.cli_tools import non_negative_int, plan_gravity_palm, plan_progress, progress_bar

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import Plan

__all__ = ["add_planner_arguments", "restart_line", "run_plan"]


def add_planner_arguments(sp: argparse.ArgumentParser) -> None:
    """`regrasp plan`'s planner flags: --method, --stability, --gravity, --max-iters, --restarts."""
    sp.add_argument("--method", choices=("svd", "sd"), default="svd",
                    help="in-grasp objective E_des: svd (Kabsch pose) or sd (workspace distance)")
    sp.add_argument("--stability", choices=("force_closure", "gravity", "none"), default=None,
                    help="certificate every step must have: force closure of the holding fingers (default), "
                         "gravity hold of the object's weight (--gravity), or none (the paper's planner)")
    sp.add_argument("--gravity", nargs="+", metavar="X Y Z|support",
                    help="gravity of --stability gravity (implied), palm frame, m/s^2 (default: the problem "
                         "file's gravity, else 0 0 -9.81); 'support': pressing the object onto the fingers "
                         "opposite the thumb")
    sp.add_argument("--max-iters", type=non_negative_int, metavar="N",
                    help="planner iteration limit (default: 50, the planner's)")
    sp.add_argument("--restarts", type=non_negative_int, metavar="N",
                    help="plans made again with other gait choices if one does not converge (default: 3 "
                         "with --stability none, 1 with a certificate; 0: one plan, a failing plan costs "
                         "one plan's time)")


def run_plan(problem, method: str, max_iters: int | None, show_progress: bool,
             stability: str | None = None, gravity_palm: tuple | None = None,
             restarts: int | None = None) -> Plan:
    """`plan_regrasp` on a `RegraspProblem` with the flags given (None: the planner's default), with a
    progress bar on stderr when `show_progress`. `gravity_palm` is `--gravity`'s value (X Y Z m/s², palm
    frame, or "support")."""
    from regrasp_casadi.planner import PlannerOptions, plan_regrasp

    kwargs = {"method": method}
    for key, value in (("max_iters", max_iters), ("stability", stability), ("restarts", restarts)):
        if value is not None:
            kwargs[key] = value
    if gravity_palm is not None:
        kwargs["gravity_palm"] = plan_gravity_palm(gravity_palm, problem.grasp0)
    if getattr(problem, "object_mass", None) is not None:
        kwargs["object_mass"] = problem.object_mass
    n_max = max_iters if max_iters is not None else PlannerOptions.max_iters
    with progress_bar("planning", show_progress, total=n_max) as bar:
        plan = plan_regrasp(problem.grasp0, problem.grasp_goal, progress=plan_progress(bar), **kwargs)
        if bar is not None:   # the bar ends where the plan stopped (its restarts included), at 100 %
            bar.total = bar.n = max(bar.n, plan.iterations)
            bar.refresh()
    return plan


def restart_line(plan: Plan) -> str | None:
    """One line naming the restart a converged plan came from, how many plans a failed one took, or
    the restart a Ctrl-C stopped; None for a plan made once."""
    attempts = plan.options.get("attempts", 1)
    if attempts <= 1:
        return None
    n, total = attempts - 1, plan.options.get("iterations_all", plan.iterations)
    if plan.options.get("restart"):
        return (f"restarted: the first plan did not converge; this is restart {n} "
                f"({plan.options['restart']}), {attempts} plans and {total} iterations in all")
    if plan.status == "interrupted":
        return f"interrupted during restart {n}: the first plan is kept ({total} iterations in all)"
    return (f"{n} restart{'s' if n > 1 else ''}, none converged: the first plan is kept "
            f"({total} iterations in all)")
