"""Behaviour fingerprint of the planner: status, iterations, step kinds and errors of every plan.

The planner is deterministic, so a refactor that claims "the plans come out the same" can be checked:
record a fingerprint before the change, another after, and compare them.

    python benchmarks/regression.py --out before.json                 # shipped problems + YCB pairs
    python benchmarks/regression.py --out after.json --compare before.json
    python benchmarks/regression.py --no-ycb --out quick.json          # shipped problems only (~20 s)
    python benchmarks/regression.py --no-self-collision --out off.json --compare before.json
    python benchmarks/regression.py --stability none --out paper.json  # no stability certificate

`--no-self-collision` plans with ``self_clearance=None`` (no self-collision constraints, the planner as it
was before them) and judges "verified" without verify's self-collision checks, so it reproduces a
fingerprint recorded before they existed; "self_collision_steps" (steps where verify's sphere check
fails) is recorded either way and not compared.

Each record holds the problem, method, status, iterations, the step kinds in order, the mean and largest
final contact error (mm, rounded to 1 µm) and whether `verify` passes. `--compare` prints a before/after
table and exits 1 when any status, iteration count, step sequence or error differs. Measures; asserts
nothing by itself.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))


def _problem_files(ycb: bool) -> list[pathlib.Path]:
    files = sorted((REPO / "problems").glob("*.yaml"))
    ycb_dir = REPO.parent / "shared" / "reference" / "ycb"
    if ycb and ycb_dir.is_dir():
        files += sorted((HERE / "problems").glob("*.yaml"))
    return files


_SELF_CHECKS = ("self_collision", "self_collision_mesh")


def fingerprint(path: str, method: str, self_collision: bool = True, stability: str | None = None,
                restarts: int | None = None) -> dict:
    """Plan one problem with one method; return its fingerprint (never raises). `self_collision=False`:
    plan without self-collision constraints and leave verify's self-collision checks out of "verified";
    `stability`, `restarts`: `PlannerOptions.stability` and `.restarts` of the plan (None: the planner's
    default)."""
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem
    from regrasp_casadi.verify import verify

    rec = {"problem": pathlib.Path(path).stem, "method": method}
    try:
        problem = RegraspProblem.load(path)
        extra = {} if self_collision else {"self_clearance": None}
        if stability is not None:
            extra["stability"] = stability
        if restarts is not None:
            extra["restarts"] = restarts
        plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method, **extra)
        report = verify(plan, problem.hand, problem.obj)
        counted = [v for v in report.violations if self_collision or v.check not in _SELF_CHECKS]
        ok = not counted
        self_steps = len({v.step for v in report.violations if v.check == "self_collision"})
    except Exception as exc:  # recorded, not raised
        rec.update(status=f"exception: {type(exc).__name__}: {exc}")
        return rec
    err = plan.steps[-1].contact_error if plan.steps else np.array([np.nan])
    rec.update(status=plan.status, iterations=int(plan.iterations),
               steps="".join(s.kind[0] for s in plan.steps),
               mean_error_mm=round(float(np.mean(err)) * 1e3, 3),
               max_error_mm=round(float(np.max(err)) * 1e3, 3), verified=ok,
               time_s=round(float(plan.timing.get("total", 0.0)), 2), self_collision_steps=self_steps,
               attempts=int(plan.options.get("attempts", 1)), restart=plan.options.get("restart", ""))
    return rec


def _key(rec: dict) -> tuple[str, str]:
    return rec["problem"], rec["method"]


_COMPARED = ("status", "iterations", "steps", "mean_error_mm", "max_error_mm", "verified")


def compare(before: list[dict], after: list[dict]) -> int:
    """Print a before/after markdown table; return the number of records that differ."""
    old = {_key(r): r for r in before}
    print("| problem | method | status | iterations | steps (g/r/f) | mean / max error (mm) | verified | same |")
    print("|---|---|---|---|---|---|---|---|")
    n_diff = 0
    for rec in after:
        ref = old.get(_key(rec), {})
        same = all(ref.get(k) == rec.get(k) for k in _COMPARED)
        n_diff += not same

        def both(k, rec=rec, ref=ref):
            a, b = ref.get(k, "—"), rec.get(k, "—")
            return f"{a}" if a == b else f"{a} → {b}"

        s = rec.get("steps", "")
        counts = f"{s.count('g')}/{s.count('r')}/{s.count('f')}"
        print(f"| {rec['problem']} | {rec['method']} | {both('status')} | {both('iterations')} | {counts} | "
              f"{both('mean_error_mm')} / {both('max_error_mm')} | {both('verified')} | "
              f"{'yes' if same else 'NO'} |")
    return n_diff


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=pathlib.Path, required=True, help="fingerprint JSON to write")
    ap.add_argument("--compare", type=pathlib.Path, help="an earlier fingerprint to compare with")
    ap.add_argument("--no-ycb", action="store_true", help="shipped problems only")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-self-collision", action="store_true",
                    help="plan with self_clearance=None; 'verified' without the self-collision checks")
    ap.add_argument("--stability", choices=("force_closure", "gravity", "none"),
                    help="PlannerOptions.stability of every plan (default: the planner's)")
    ap.add_argument("--restarts", type=int,
                    help="PlannerOptions.restarts of every plan (default: the planner's)")
    args = ap.parse_args(argv)
    from machine import machine_info

    on = not args.no_self_collision
    jobs = [(str(p), m, on, args.stability, args.restarts)
            for p in _problem_files(not args.no_ycb) for m in ("svd", "sd")]
    with ProcessPoolExecutor(args.workers) as pool:
        records = list(pool.map(fingerprint, *zip(*jobs, strict=True)))
    machine = machine_info()
    args.out.write_text(json.dumps({"machine": machine, "records": records}, indent=1))
    if args.compare:
        recorded = json.loads(args.compare.read_text())
        n_diff = compare(recorded["records"], records)
        print(f"{n_diff} of {len(records)} plans differ")
        cpu_then = recorded.get("machine", {}).get("cpu")
        if cpu_then and cpu_then != machine["cpu"]:  # measured: 7 of 10 shipped plans (AMD EPYC -> Intel Xeon)
            print(f"(recorded on {cpu_then}, run on {machine['cpu']}: another CPU's floating point alone changes "
                  f"plans)")
        return 1 if n_diff else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
