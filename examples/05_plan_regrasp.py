"""A full regrasp: plan, verify, save, and write a browser replay.

Loads a shipped problem (a box held by the Allegro hand, and a desired grasp whose contacts are on
average more than 3 cm away and whose object pose is turned), plans the regrasp with alternating finger
gaits and reposings, checks the plan with the exact verifier, saves it as JSON and writes a
self-contained HTML replay. Open the HTML file in a browser: green dots are the desired contacts.
By default the paper's planner (`--stability none`); `--stability force_closure` certifies that the
fingers hold the box at every step, and stalls on this problem (see the README's limitations).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from regrasp_casadi import RegraspProblem, plan_regrasp, verify

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default=str(PROBLEMS / "box_rotate.yaml"), help="problem file")
    parser.add_argument("--method", choices=("svd", "sd"), default="svd")
    parser.add_argument("--stability", choices=("force_closure", "gravity", "none"), default="none")
    parser.add_argument("--out", default="plan.json", help="where to save the plan")
    parser.add_argument("--html", default=None, help="write an HTML replay here (e.g. replay.html)")
    args = parser.parse_args(argv)

    problem = RegraspProblem.load(args.problem)
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=args.method, stability=args.stability)
    report = verify(plan, problem.hand, problem.obj)
    plan.save(args.out)
    if args.html:
        from regrasp_casadi.viewer import write_html

        write_html(plan, args.html, problem.hand, problem.obj)

    print(plan.summary())
    print(f"verify: {'ok' if report.ok else 'FAILED'}; plan saved to {args.out}"
          + (f", replay in {args.html}" if args.html else ""))


if __name__ == "__main__":
    main()
