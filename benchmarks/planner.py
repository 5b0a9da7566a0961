"""Benchmark: the regrasp planner on every shipped problem (problems/*.yaml), both methods.

For each problem and method: planning time of a cold plan (NLPs built in it) and the median of warm
plans (NLPs cached), the build time, iterations, steps, average point error (mean over fingers of the
distance between planned final and desired contact), status, `verify`'s verdict, and the median and
95th-percentile time and iterations of single IPOPT solves of OPT1 (finger gait) and OPT2 (reposing,
final moves) (`regrasp_casadi.solve_log`), the share of OPT2 time spent on moves the exact checks rejected
and the share of a warm plan spent outside the solvers.
Every plan is judged by the exact verifier. Prints a markdown table; writes
benchmarks/results/planner.json with the machine description.

    python benchmarks/planner.py [--repeats 3] [--methods svd sd] [--problems box_rotate ...]

Targets (issue 4, 2-core machine): OPT1 median ≤ 3 ms, OPT2 median ≤ 20 ms, a whole SVD plan ≤ 1 s
median. The paper needed 75 s (SVD) and 729 s (SD) median per plan.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from machine import REPO, machine_info  # noqa: E402

from regrasp_casadi.planner import clear_nlp_cache, plan_regrasp  # noqa: E402
from regrasp_casadi.problem import RegraspProblem  # noqa: E402
from regrasp_casadi.solve_log import recording, summarise  # noqa: E402
from regrasp_casadi.verify import verify  # noqa: E402

RESULTS = REPO / "benchmarks" / "results" / "planner.json"


def run(problem_path: pathlib.Path, method: str, repeats: int) -> dict:
    problem = RegraspProblem.load(problem_path)
    clear_nlp_cache()
    t0 = time.perf_counter()
    with recording() as cold_log:
        cold = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method)
    cold_time = time.perf_counter() - t0
    plan, warm_times, calls, moves, outside = cold, [], list(cold_log.calls), list(cold_log.moves), []
    for _ in range(repeats):
        t0 = time.perf_counter()
        with recording() as log:
            plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method)
        warm_times.append(time.perf_counter() - t0)
        calls += log.calls
        moves += log.moves
        outside.append(warm_times[-1] - sum(c.time for c in log.calls))
    stats = summarise(calls, moves)  # per call and per OPT2 move, cold and warm plans
    nan = float("nan")
    report = verify(plan, problem.hand, problem.obj)
    final_error = np.linalg.norm(plan.steps[-1].contacts_object - plan.goal_contacts_object, axis=1)
    kinds = [s.kind for s in plan.steps]

    return {
        "problem": problem_path.stem, "method": method, "status": plan.status, "verified": report.ok,
        "cold_time_s": cold_time, "build_time_s": cold.timing["build"],
        "warm_time_median_s": statistics.median(warm_times) if warm_times else float("nan"),
        "timing_split_s": plan.timing, "iterations": plan.iterations, "steps": len(plan.steps),
        "gaits": kinds.count("gait"), "reposes": kinds.count("repose"), "finals": kinds.count("final"),
        "avg_point_error_mm": float(np.mean(final_error) * 1e3),
        "max_point_error_mm": float(np.max(final_error) * 1e3),
        **{f"{kind}_{key}": stats.get(kind, {}).get(src, nan) for kind in ("opt1", "opt2")
           for key, src in (("median_ms", "call_median_ms"), ("p95_ms", "call_p95_ms"), ("n", "calls"),
                            ("iterations_p50", "iterations_median"), ("iterations_p95", "iterations_p95"))},
        "opt2_rejected_share": stats.get("opt2", {}).get("rejected_share", nan),
        "opt2_rejected_time_s": stats.get("opt2", {}).get("rejected_time_s", nan),
        "outside_solvers_share": statistics.median(outside) / statistics.median(warm_times) if outside else nan,
        "min_clearance_mm": report.metrics["min_clearance"] * 1e3,
        "max_surface_error_mm": report.metrics["max_surface_error"] * 1e3,
    }


def table(rows: list[dict]) -> str:
    head = ("| problem | method | status | verified | plan, warm (s) | cold (s) | build (s) | iters "
            "| steps (gait/repose/final) | avg / max point error (mm) | OPT1 median / p95 (ms) "
            "| OPT2 median / p95 (ms) | OPT2 iterations p95 | OPT2 rejected | outside solvers |")
    lines = [head, "|" + "---|" * 15]
    for r in rows:
        lines.append(
            f"| {r['problem']} | {r['method']} | {r['status']} | {'yes' if r['verified'] else 'NO'} | "
            f"{r['warm_time_median_s']:.2f} | {r['cold_time_s']:.2f} | {r['build_time_s']:.2f} | "
            f"{r['iterations']} | {r['steps']} ({r['gaits']}/{r['reposes']}/{r['finals']}) | "
            f"{r['avg_point_error_mm']:.2f} / {r['max_point_error_mm']:.2f} | "
            f"{r['opt1_median_ms']:.1f} / {r['opt1_p95_ms']:.1f} | {r['opt2_median_ms']:.1f} / "
            f"{r['opt2_p95_ms']:.1f} | {r['opt2_iterations_p95']:.0f} | {r['opt2_rejected_share'] * 100:.1f} % | "
            f"{r['outside_solvers_share'] * 100:.0f} % |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="warm plans per problem and method")
    parser.add_argument("--methods", nargs="+", default=["svd", "sd"], choices=["svd", "sd"])
    parser.add_argument("--problems", nargs="*", default=None, help="problem names (default: all)")
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS)
    args = parser.parse_args(argv)
    paths = sorted((REPO / "problems").glob("*.yaml"))
    if args.problems:
        paths = [p for p in paths if p.stem in args.problems]
    rows = []
    for path in paths:
        for method in args.methods:
            rows.append(run(path, method, args.repeats))
            r = rows[-1]
            print(f"{r['problem']:16s} {method:3s} {r['status']:10s} verified={r['verified']} "
                  f"warm {r['warm_time_median_s']:.2f} s", file=sys.stderr, flush=True)
    summary = {}
    for method in args.methods:
        mine = [r for r in rows if r["method"] == method]
        summary[method] = {
            "plan_time_median_s": statistics.median(r["warm_time_median_s"] for r in mine),
            "opt1_median_ms": statistics.median(r["opt1_median_ms"] for r in mine),
            "opt2_median_ms": statistics.median(r["opt2_median_ms"] for r in mine),
            "opt2_iterations_p95_max": max(r["opt2_iterations_p95"] for r in mine),
            "verified": sum(r["verified"] for r in mine), "runs": len(mine),
        }
    out = {"machine": machine_info(), "rows": rows, "summary": summary}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1))
    print(table(rows))
    for method, s in summary.items():
        print(f"\n{method}: median plan {s['plan_time_median_s']:.2f} s, OPT1 median "
              f"{s['opt1_median_ms']:.1f} ms, OPT2 median {s['opt2_median_ms']:.1f} ms, verified "
              f"{s['verified']}/{s['runs']}")
    m = out["machine"]
    print(f"\n{m['cpu']}, {m['cores']} cores (load {m['load_1min']:.1f}), Python {m['python']}, CasADi "
          f"{m['versions']['casadi']}, commit {m['git_commit'][:10]}{' (dirty)' if m['git_dirty'] else ''}")


if __name__ == "__main__":
    main()
