"""The `regrasp simulate` subcommand: execute a plan in MuJoCo (`regrasp_casadi.simulate`).

    regrasp simulate plan.json [--gravity X Y Z | plan | support] [--html sim.html] [--json report.json]

Exit codes (`regrasp_casadi.cli`): 0 the object is held within the tolerances, 1 it is dropped or deviates,
2 bad input (missing or unreadable plan, bad number, unwritable output).
"""

from __future__ import annotations

import argparse
import functools
import json
from collections.abc import Callable

from regrasp_casadi.cli_tools import UserError, check_output, gravity_values

__all__ = ["add_simulate_parser", "cmd_simulate"]

EXIT_OK, EXIT_FAILED = 0, 1


def cmd_simulate(args: argparse.Namespace, load_plan: Callable) -> int:
    """Execute a plan in MuJoCo; print the summary line and the first departure from the plan; write the
    JSON report and the HTML replay when asked. Exit 0 when the object is held within tolerance, 1 when
    dropped or deviating (bad input raises, the caller maps it to 2)."""
    from regrasp_casadi.simulate import SimOptions, simulate

    gravity = gravity_values("--gravity", args.gravity, ("plan", "support")) or (0.0, 0.0, 0.0)
    out = check_output("--json", args.json)
    html = check_output("--html", args.html)
    plan = load_plan(args.plan)
    if gravity == "plan":
        gravity = certified_gravity(plan, args.plan)
    elif gravity == "support":
        gravity = supporting_gravity_of(plan)
    report = simulate(plan, options=SimOptions(gravity_palm=gravity))
    print(report.summary())
    opts = report.options
    for rec in report.steps:
        if (rec.deviation_mm > opts["tol_position"] * 1e3 or rec.deviation_deg > opts["tol_rotation"]
                or len(rec.fingers_touching) < opts["min_fingers"]):
            print(f"  first departure: step {rec.step} ({rec.kind}{' ' + rec.finger if rec.finger else ''}) "
                  f"at t = {rec.time:.2f} s: {rec.deviation_mm:.2f} mm / {rec.deviation_deg:.2f} deg, "
                  f"touching: {', '.join(rec.fingers_touching) or 'none'}")
            break
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(report.to_dict(), indent=1))
        print(f"wrote {out}")
    if html is not None:
        from regrasp_casadi.sim_replay import write_sim_html

        print(f"wrote {write_sim_html(report, plan, html)} (the simulated motion; the planned object pose "
              "as a green ghost)")
    return EXIT_OK if report.held else EXIT_FAILED


def certified_gravity(plan, shown: str) -> tuple[float, float, float]:
    """The gravity (palm frame, m/s²) `plan` was certified for (`PlannerOptions.gravity_palm` of a
    "gravity" plan).

    Raises:
        UserError: the plan (file `shown`) was not planned with stability "gravity".
    """
    stability = plan.options.get("stability")
    if stability != "gravity" or "gravity_palm" not in plan.options:
        raise UserError(f"--gravity plan: {shown} was planned with stability {stability!r}, not 'gravity': "
                        "give the gravity as X Y Z")
    return tuple(float(g) for g in plan.options["gravity_palm"])


def supporting_gravity_of(plan) -> tuple[float, float, float]:
    """The gravity (palm frame, m/s²) that presses the object of `plan`'s initial grasp onto the fingers
    opposite the one that alone opposes the others (`hand_orientation.supporting_gravity`; the Allegro's
    thumb): the orientation `regrasp plan --gravity support` certifies for."""
    from regrasp_casadi.grasp import Grasp
    from regrasp_casadi.hand_orientation import supporting_gravity
    from regrasp_casadi.problem import plan_models

    hand, obj = plan_models(plan)
    first = Grasp.from_joints(hand, obj, plan.steps[0].q, plan.steps[0].T_palm_object)
    return tuple(float(g) for g in supporting_gravity(first))


def add_simulate_parser(add, *, load_plan: Callable) -> None:
    """The `simulate` subcommand (``add(name, help)`` makes a subparser); ``load_plan(path) -> Plan`` the
    CLI's plan reader."""
    sp = add("simulate", "execute a plan in physics (MuJoCo) and report whether the object is held")
    sp.add_argument("plan", metavar="PLAN.json", help="plan file (JSON)")
    sp.add_argument("--gravity", nargs="+", metavar="X Y Z|plan|support",
                    help="gravity in the palm frame, m/s^2 (default: off; e.g. 0 0 -9.81); 'plan': the "
                         "gravity the plan was certified for (a plan of --stability gravity); 'support': "
                         "pressing the object of the plan's first step onto the fingers opposite the thumb")
    sp.add_argument("--html", metavar="SIM.html", help="write a self-contained replay of the simulated "
                    "motion, the planned object pose as a ghost")
    sp.add_argument("--json", metavar="REPORT.json", help="write the simulation report as JSON")
    sp.set_defaults(func=functools.partial(cmd_simulate, load_plan=load_plan))
