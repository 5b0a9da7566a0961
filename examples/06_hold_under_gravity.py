"""A regrasp that holds the object at every step, under gravity, executed in physics (MuJoCo).

On the shipped box problem the thumb alone opposes the other three fingers, and its goal is 3 cm away:
with force closure alone it can neither lift nor slide (`stability="force_closure"` stalls). Oriented so
that gravity presses the box onto the other fingers (`hand_orientation.supporting_gravity`), they carry
it while the thumb moves. This example plans with that gravity certificate and a force reserve the
simulated servos can give (μ 0.4, at most 3 N per finger), checks the plan with `verify`, and executes
it in MuJoCo under the same gravity. The planner's certificate is a static one; the simulation says
whether the hand really holds the box along the way (see benchmarks/README.md, "simulate.py").
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np

from regrasp_casadi import RegraspProblem, plan_regrasp, verify
from regrasp_casadi.hand_orientation import opposing_finger, supporting_gravity

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default=str(PROBLEMS / "box_rotate.yaml"), help="problem file")
    parser.add_argument("--method", choices=("svd", "sd"), default="svd")
    parser.add_argument("--no-simulate", action="store_true", help="plan and verify only")
    args = parser.parse_args(argv)

    problem = RegraspProblem.load(args.problem)
    g_palm = supporting_gravity(problem.grasp0)
    print(f"{opposing_finger(problem.grasp0)} opposes the others; gravity (palm frame) "
          f"[{' '.join(f'{g:.3f}' for g in g_palm)}] m/s^2")
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=args.method, stability="gravity",
                        gravity_palm=tuple(g_palm), object_mass=problem.object_mass, mu=0.4,
                        max_normal_force=3.0)
    report = verify(plan, problem.hand, problem.obj)
    kinds = Counter(step.kind for step in plan.steps)
    largest_mm = 1e3 * float(np.max(plan.steps[-1].contact_error))
    print(f"plan: {plan.status}, {len(plan.steps)} steps ({kinds['gait']} gaits, {kinds['slide']} slides, "
          f"{kinds['repose']} reposings); final contact error max {largest_mm:.2f} mm")
    print(f"verify: {'ok' if report.ok else 'FAILED'}; certified steps: "
          f"{sum(bool(s.certificate and s.certificate['ok']) for s in plan.steps)} of {len(plan.steps)}")
    if not args.no_simulate:
        from regrasp_casadi.simulate import SimOptions, simulate

        sim = simulate(plan, problem.hand, problem.obj, SimOptions(gravity_palm=tuple(g_palm)))
        print(sim.summary().splitlines()[0])


if __name__ == "__main__":
    main()
