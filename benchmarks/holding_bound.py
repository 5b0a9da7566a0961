"""Can the given grasps hold the object's weight? An upper bound on any plan's held rate under gravity.

A plan starts in the problem's initial grasp and, when it converges, ends in its desired grasp. Where one
of them cannot hold the object's weight in a hand orientation, no plan between them is held there. For
each problem and hand orientation (fingers up, palm up, palm down: gravity along −z, −x, +x of the palm
frame, as `simulate.py`), this asks the planner's gravity certificate (`holding.Holding.grasp`: an SOCP
over the contact forces, friction cones of μ, each contact's normal force ≤ a bound, each holding
finger's joint torques Jᵀf within a bound) of the initial and the desired grasp, for several (μ, torque
bound) settings, and reports how many (problem, orientation) cases hold at the start, at the end and at
both: the first is a bound on the share of cases any plan can even start held in. Records machine and
commit; asserts nothing.

    python benchmarks/holding_bound.py --out benchmarks/results/holding_bound.json
"""

from __future__ import annotations

import argparse
import glob
import json
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent
ORIENTATIONS = {"fingers_up": (0.0, 0.0, -9.81), "palm_up": (-9.81, 0.0, 0.0), "palm_down": (9.81, 0.0, 0.0)}
"""Gravity (m/s², palm frame) of the three hand orientations of `simulate.py`."""
SETTINGS = (  # (label, μ, joint-torque bound N·m or None, normal-force bound N)
    ("planner default: mu 0.5, 80 % of 0.7 N·m, <= 10 N", 0.5, 0.56, 10.0),
    ("mu 0.5, the Allegro's 0.7 N·m, no force bound (the simulation's mu and motors)", 0.5, 0.7, 1e4),
    ("mu 1.0, 0.7 N·m, no force bound", 1.0, 0.7, 1e4),
    ("mu 0.5, no torque or force bound (friction alone)", 0.5, None, 1e4),
)


def holds(problem, grasp, gravity, mu, torque, force) -> bool:
    """Whether `grasp` of `problem` holds the object's weight under `gravity` (palm frame, m/s²)."""
    from regrasp_casadi.holding import Holding, HoldingOptions

    options = HoldingOptions(mu=mu, max_joint_torque=torque, max_normal_force=force)
    holding = Holding(problem.hand, problem.obj, "gravity", options, mass=problem.object_mass,
                      gravity_palm=gravity)
    return bool(holding.certified(holding.grasp(grasp.q, grasp.T_palm_object)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", default=str(HERE / "problems" / "*.yaml"), help="glob of problem files")
    ap.add_argument("--out", type=pathlib.Path, help="JSON of every case and the counts")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from machine import machine_info

    from regrasp_casadi.problem import RegraspProblem

    files = sorted(glob.glob(args.problems))
    if not files:
        print(f"no problem files match {args.problems}", file=sys.stderr)
        return 2
    problems = [RegraspProblem.load(f) for f in files]
    cases, summary = [], []
    for label, mu, torque, force in SETTINGS:
        counts = {"setting": label, "cases": 0, "start": 0, "end": 0, "both": 0}
        for problem in problems:
            for name, gravity in ORIENTATIONS.items():
                start = holds(problem, problem.grasp0, gravity, mu, torque, force)
                end = holds(problem, problem.grasp_goal, gravity, mu, torque, force)
                cases.append({"setting": label, "problem": problem.name, "orientation": name, "start": start,
                              "end": end})
                counts["cases"] += 1
                counts["start"] += start
                counts["end"] += end
                counts["both"] += start and end
        summary.append(counts)
        n = counts["cases"]
        print(f"{label}: the initial grasp holds in {counts['start']} / {n} cases, the desired one in "
              f"{counts['end']} / {n}, both in {counts['both']} / {n}", flush=True)
    if args.out:
        args.out.write_text(json.dumps({"machine": machine_info(), "problems": files, "summary": summary,
                                        "cases": cases}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
