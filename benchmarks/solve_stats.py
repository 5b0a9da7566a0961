"""Per-solve statistics of the planner on a few problem files, serially: OPT1/OPT2 time per IPOPT call,
iterations per call, the share of OPT2 time spent on moves the exact checks rejected, plan time and the
time outside the solvers.

It measures by wrapping `solver.solve` and `InGraspNLP.solve` (not `solve_log`), so the same script
measures an older checkout too — a before/after comparison on the same machine in the same run:

    PYTHONPATH=<old checkout> python benchmarks/solve_stats.py --out before.json benchmarks/problems/mustard_0.yaml ...
    PYTHONPATH=. python benchmarks/solve_stats.py --out after.json benchmarks/problems/mustard_0.yaml ...

Every plan is judged by `verify`. Measures and records (with machine and commit); asserts nothing.

Compiled NLPs (`regrasp_casadi.compiled`) follow ``$REGRASP_COMPILE``; the output's "compiled" records
the switch and every compiled solver built (name, compile or cache-load time):

    REGRASP_COMPILE=0 python benchmarks/solve_stats.py --out interpreted.json P...
    REGRASP_COMPILE=1 python benchmarks/solve_stats.py --out compiled.json P...   # twice: cold, then cached
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))


def _pct(values, q):
    return float(np.percentile(values, q)) if len(values) else float("nan")


def measure(paths: list[str], methods: list[str]) -> dict:
    """Plan every problem with every method (NLPs built once per object, then cached) and collect."""
    from regrasp_casadi import in_grasp
    from regrasp_casadi import solver as solver_module
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem
    from regrasp_casadi.verify import verify

    calls: list[tuple[str, float, int]] = []
    moves: list[tuple[float, bool]] = []
    solve, nlp_solve = solver_module.solve, in_grasp.InGraspNLP.solve

    def wrapped(solver, **kwargs):
        res = solve(solver, **kwargs)
        kind = "opt1" if solver.name().startswith("finger_gait") else "opt2"
        calls.append((kind, res.time, res.iterations))
        return res

    def wrapped_move(self, *args, **kwargs):
        res = nlp_solve(self, *args, **kwargs)
        moves.append((res.solve_time, bool(res.success)))
        return res

    solver_module.solve, in_grasp.InGraspNLP.solve = wrapped, wrapped_move
    plans = []
    try:
        for path in paths:
            problem = RegraspProblem.load(path)
            for method in methods:
                n_calls = len(calls)
                t0 = time.perf_counter()
                plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method)
                total = time.perf_counter() - t0
                solver_time = sum(c[1] for c in calls[n_calls:])
                plans.append({"problem": pathlib.Path(path).stem, "method": method, "status": plan.status,
                              "verified": bool(verify(plan, problem.hand, problem.obj).ok),
                              "time_s": total, "build_s": plan.timing.get("build", 0.0),
                              "outside_solvers_s": total - solver_time - plan.timing.get("build", 0.0)})
                print(f"{plans[-1]['problem']} {method}: {plan.status} verified={plans[-1]['verified']} "
                      f"{total:.1f} s", file=sys.stderr, flush=True)
    finally:
        solver_module.solve, in_grasp.InGraspNLP.solve = solve, nlp_solve
    out: dict = {"plans": plans}
    for kind in ("opt1", "opt2"):
        t = [c[1] for c in calls if c[0] == kind]
        it = [c[2] for c in calls if c[0] == kind and c[2] >= 0]
        out[kind] = {"calls": len(t), "call_median_ms": _pct(t, 50) * 1e3, "call_p95_ms": _pct(t, 95) * 1e3,
                     "iterations_median": _pct(it, 50), "iterations_p95": _pct(it, 95),
                     "ms_per_iteration": 1e3 * sum(t) / max(1, sum(it))}
    move_time = sum(m[0] for m in moves)
    rejected = sum(m[0] for m in moves if not m[1])
    out["opt2"].update(moves=len(moves), move_median_ms=_pct([m[0] for m in moves], 50) * 1e3,
                       rejected=sum(not m[1] for m in moves),
                       rejected_share=rejected / move_time if move_time > 0 else float("nan"))
    warm = plans  # build time excluded from "outside the solvers"
    out["plan_time_median_s"] = _pct([p["time_s"] for p in warm], 50)
    out["outside_solvers_share"] = (sum(p["outside_solvers_s"] for p in warm)
                                    / max(1e-9, sum(p["time_s"] - p["build_s"] for p in warm)))
    return out


def _compiled_builds() -> dict | None:
    """The compile switch and the compiled solvers built in this process (None: a checkout without
    `regrasp_casadi.compiled`)."""
    try:
        from regrasp_casadi import compiled
    except ImportError:
        return None
    builds = [dataclasses.asdict(r) for r in compiled.build_records()]
    return {"enabled": compiled.enabled(None), "mode": compiled.mode(None), "compiles": compiled.compile_count(), "builds": builds,
            "compile_s": sum(b["seconds"] for b in builds if b["compiled"]),
            "cache_load_s": sum(b["seconds"] for b in builds if not b["compiled"])}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problems", nargs="+", help="problem files")
    ap.add_argument("--methods", nargs="+", default=["svd"], choices=["svd", "sd"])
    ap.add_argument("--out", type=pathlib.Path, required=True)
    args = ap.parse_args(argv)
    from machine import machine_info

    load_start = os.getloadavg()[0]
    out = measure(args.problems, args.methods)
    out["compiled"] = _compiled_builds()
    out["machine"] = machine_info()
    out["machine"]["load_1min_start"] = load_start
    args.out.write_text(json.dumps(out, indent=1))
    for kind in ("opt1", "opt2"):
        k = out[kind]
        print(f"{kind}: {k['calls']} calls, median {k['call_median_ms']:.1f} ms, p95 {k['call_p95_ms']:.1f} ms, "
              f"iterations median {k['iterations_median']:.0f} p95 {k['iterations_p95']:.0f}, "
              f"{k['ms_per_iteration']:.1f} ms/iteration")
    o = out["opt2"]
    print(f"opt2 moves {o['moves']}, median {o['move_median_ms']:.0f} ms, rejected {o['rejected']} "
          f"({o['rejected_share'] * 100:.1f} % of OPT2 move time); plan median {out['plan_time_median_s']:.1f} s, "
          f"outside the solvers {out['outside_solvers_share'] * 100:.1f} % (builds excluded)")
    if out["compiled"] and out["compiled"]["builds"]:
        c = out["compiled"]
        print(f"compiled solvers: {len(c['builds'])}, {c['compiles']} compiled in {c['compile_s']:.1f} s, "
              f"cache loads {c['cache_load_s']:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
