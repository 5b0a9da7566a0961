"""Plans made by another checkout, judged by this checkout's `verify`.

When verify learns a new check (e.g. the fingertips' slide over the object, 2026-12-02), the plans of
the code before it can be judged by it: the other checkout plans the shipped problems (both methods, in
a child process with that checkout first on `sys.path`), this one verifies them and prints, per plan,
its status, whether it passes, its largest slide and the checks it fails.

    git worktree add ../before 96e4a3a
    python benchmarks/reverify.py --checkout ../before --stability none --out before.json

Measures; asserts nothing.
"""

from __future__ import annotations

import argparse
import collections
import json
import pathlib
import pickle
import subprocess
import sys
import tempfile

REPO = pathlib.Path(__file__).resolve().parent.parent

_PLAN = """
import pickle, sys, pathlib
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.planner import plan_regrasp
plans = {}
for path in sorted(pathlib.Path(sys.argv[1]).glob("problems/*.yaml")):
    problem = RegraspProblem.load(path)
    for method in ("svd", "sd"):
        plans[(path.stem, method)] = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method,
                                                  stability=sys.argv[2])
pickle.dump(plans, open(sys.argv[3], "wb"))
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkout", type=pathlib.Path, required=True, help="the checkout that plans")
    ap.add_argument("--stability", default="none", help="PlannerOptions.stability of the plans")
    ap.add_argument("--out", type=pathlib.Path, help="JSON file for the records")
    args = ap.parse_args(argv)
    checkout = args.checkout.resolve()
    with tempfile.TemporaryDirectory() as tmp:
        pk = pathlib.Path(tmp) / "plans.pkl"
        env_path = str(checkout)
        subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {env_path!r}); exec({_PLAN!r})",
                        str(checkout), args.stability, str(pk)], check=True)
        plans = pickle.loads(pk.read_bytes())
    from regrasp_casadi.problem import RegraspProblem
    from regrasp_casadi.verify import verify

    records = []
    for (name, method), plan in plans.items():
        problem = RegraspProblem.load(REPO / "problems" / f"{name}.yaml")
        report = verify(plan, problem.hand, problem.obj)
        checks = collections.Counter(v.check for v in report.violations)
        rec = {"problem": name, "method": method, "status": plan.status, "verified": report.ok,
               "max_slip_mm": round(report.metrics["max_slip"] * 1e3, 2),
               "motion_max_slip_mm": round(report.metrics.get("motion_max_slip", 0.0) * 1e3, 2),
               "violations": dict(checks)}
        records.append(rec)
        print(f"{name:18s} {method:3s} {plan.status:16s} verified={report.ok!s:5s} "
              f"slide {rec['max_slip_mm']:6.2f} mm (motion {rec['motion_max_slip_mm']:6.2f}) {dict(checks)}")
    print(f"verified: {sum(r['verified'] for r in records)} of {len(records)}")
    if args.out:
        args.out.write_text(json.dumps({"checkout": str(checkout), "stability": args.stability,
                                        "records": records}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
