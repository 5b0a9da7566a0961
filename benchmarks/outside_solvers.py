"""Side by side: the same plans with two checkouts, interleaved plan by plan, and the time outside the solvers.

Two worker processes, one per checkout (``PYTHONPATH=<checkout>``), each load the problems and plan each
once to build (and cache) its NLPs; then the driver asks them in turn for the same plan (never both at
once, so they run at the same load), ``--repeat`` rounds over the problems × methods. Per plan: wall
time of `plan_regrasp`, time inside IPOPT (the wall time of every `solver.solve` call), NLP builds,
the 1-min load average before it, status, `verify` verdict and a SHA-256 of the plan (every step's
kind, finger, arrays and status and every path's arrays, phases, verdict and metrics, bit for bit): the
plans of both checkouts must hash the same. The exact distances remembered from earlier plans
(`ExactDistance.clear_cache`, where the checkout has it) are forgotten before every plan. Measures and
records (machine, commits); asserts nothing.

    git worktree add /tmp/wt-base <old commit>
    nice -n 10 python benchmarks/outside_solvers.py --old /tmp/wt-base --new . --out results/outside.json \
        benchmarks/problems/mustard_0.yaml benchmarks/problems/banana_0.yaml \
        benchmarks/problems/sugar-box_0.yaml problems/box_rotate.yaml
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pathlib
import subprocess
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent


# ----------------------------------------------------------------------------------------------- worker
def plan_hash(plan) -> str:
    """SHA-256 (hex) of a plan: status, every step's kind, finger, q, pose, contacts, errors and solver
    status, and its path's time stamps, knots, poses, phases, verdict, detail and metrics (floats as
    their hex form: bit for bit). Solve times are left out."""
    h = hashlib.sha256(plan.status.encode())
    for s in plan.steps:
        h.update(f"{s.kind}|{s.finger}|{s.solver_status}".encode())
        for a in (s.q, s.T_palm_object, s.contacts_object, s.contact_error):
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        p = s.path
        if p is not None:
            for a in (p.t, p.q, p.T_palm_object):
                h.update(np.ascontiguousarray(a, dtype=float).tobytes())
            metrics = sorted((k, float(v).hex()) for k, v in p.metrics.items())
            h.update(f"{p.phases}|{p.ok}|{p.detail}|{metrics}".encode())
    return h.hexdigest()


def worker(problems: list[str], methods: list[str], stability: str) -> None:
    """Serve plans over stdin / stdout (one JSON line each way): ``{"problem": i, "method": m}`` ->
    the plan's figures. Plans every problem with every method once first (NLP builds)."""
    from regrasp_casadi import solver as solver_module
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem
    from regrasp_casadi.verify import verify

    loaded = [RegraspProblem.load(p) for p in problems]
    for pr in loaded:
        for m in methods:
            plan_regrasp(pr.grasp0, pr.grasp_goal, method=m, stability=stability)
    inside: list[float] = []
    solve = solver_module.solve

    def timed(s, **kwargs):
        res = solve(s, **kwargs)
        inside.append(res.time)
        return res

    solver_module.solve = timed
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        ask = json.loads(line)
        pr = loaded[ask["problem"]]
        inside.clear()
        if hasattr(pr.obj.exact, "clear_cache"):  # no answers remembered from the warm-up plan
            pr.obj.exact.clear_cache()
        t0 = time.perf_counter()
        plan = plan_regrasp(pr.grasp0, pr.grasp_goal, method=ask["method"], stability=stability)
        total = time.perf_counter() - t0
        build = float(plan.timing.get("build", 0.0))
        print(json.dumps({"time_s": total, "solver_s": sum(inside), "build_s": build, "calls": len(inside),
                          "status": plan.status, "steps": len(plan.steps), "hash": plan_hash(plan),
                          "verified": bool(verify(plan, pr.hand, pr.obj).ok)}), flush=True)


# ----------------------------------------------------------------------------------------------- driver
class _Worker:
    def __init__(self, checkout: pathlib.Path, args: argparse.Namespace):
        env = {**os.environ, "PYTHONPATH": str(checkout)}
        cmd = [sys.executable, str(pathlib.Path(__file__).resolve()), "--serve", "--stability", args.stability,
               "--methods", *args.methods, "--", *[str(pathlib.Path(p).resolve()) for p in args.problems]]
        self.proc = subprocess.Popen(cmd, env=env, cwd=checkout, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True)
        self.checkout = checkout

    def ready(self) -> None:
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the worker of {self.checkout} ended")

    def plan(self, problem: int, method: str) -> dict:
        self.proc.stdin.write(json.dumps({"problem": problem, "method": method}) + "\n")
        self.proc.stdin.flush()
        return json.loads(self.proc.stdout.readline())

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


def _commit(checkout: pathlib.Path) -> str:
    out = subprocess.run(["git", "-C", str(checkout), "rev-parse", "--short", "HEAD"], capture_output=True,
                         text=True, check=False)
    dirty = subprocess.run(["git", "-C", str(checkout), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True, check=False).stdout.strip()
    return out.stdout.strip() + ("+dirty" if dirty else "")


def _outside_share(runs: list[dict]) -> float:
    """Time outside the solvers over plan time, builds excluded, summed over `runs`."""
    total = sum(r["time_s"] - r["build_s"] for r in runs)
    return sum(r["time_s"] - r["build_s"] - r["solver_s"] for r in runs) / max(total, 1e-9)


def summarise(rows: list[dict]) -> dict:
    """Per (problem, method): median old / new plan time, outside time and the speed-ups; overall."""
    keys = sorted({(r["problem"], r["method"]) for r in rows})
    per = []
    for key in keys:
        sel = [r for r in rows if (r["problem"], r["method"]) == key]
        o = [r["old"] for r in sel]
        n = [r["new"] for r in sel]
        t_old, t_new = float(np.median([x["time_s"] for x in o])), float(np.median([x["time_s"] for x in n]))
        out_old = float(np.median([x["time_s"] - x["solver_s"] - x["build_s"] for x in o]))
        out_new = float(np.median([x["time_s"] - x["solver_s"] - x["build_s"] for x in n]))
        per.append({"problem": key[0], "method": key[1], "same_plan": all(r["same"] for r in sel),
                    "status": n[0]["status"], "verified_old": all(x["verified"] for x in o),
                    "verified_new": all(x["verified"] for x in n), "time_old_s": t_old, "time_new_s": t_new,
                    "speedup": t_old / t_new, "outside_old_s": out_old, "outside_new_s": out_new,
                    "outside_speedup": out_old / max(out_new, 1e-9), "outside_share_old": _outside_share(o),
                    "outside_share_new": _outside_share(n)})
    old = [r["old"] for r in rows]
    new = [r["new"] for r in rows]
    return {"per_plan": per, "all_same": all(r["same"] for r in rows),
            "time_old_s": sum(x["time_s"] for x in old), "time_new_s": sum(x["time_s"] for x in new),
            "outside_share_old": _outside_share(old), "outside_share_new": _outside_share(new)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problems", nargs="+", help="problem files")
    ap.add_argument("--old", type=pathlib.Path, help="the old checkout (its root)")
    ap.add_argument("--new", type=pathlib.Path, default=HERE.parent, help="the new checkout")
    ap.add_argument("--methods", nargs="+", default=["svd", "sd"], choices=["svd", "sd"])
    ap.add_argument("--stability", default="none", choices=["none", "gravity", "force_closure"])
    ap.add_argument("--repeat", type=int, default=1, help="rounds over problems × methods")
    ap.add_argument("--out", type=pathlib.Path, help="JSON of every plan and the summary")
    ap.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.serve:
        worker(args.problems, args.methods, args.stability)
        return 0
    sys.path.insert(0, str(HERE))
    from machine import machine_info

    workers = {"old": _Worker(args.old.resolve(), args), "new": _Worker(args.new.resolve(), args)}
    for w in workers.values():  # one after the other: the warm-up plans do not overlap
        w.ready()
    rows = []
    for rnd in range(args.repeat):
        for i, path in enumerate(args.problems):
            for m in args.methods:
                row = {"round": rnd, "problem": pathlib.Path(path).stem, "method": m}
                for name in ("old", "new") if (len(rows) % 2 == 0) else ("new", "old"):
                    load = os.getloadavg()[0]
                    row[name] = {**workers[name].plan(i, m), "load_1min": load}
                row["same"] = row["old"]["hash"] == row["new"]["hash"]
                rows.append(row)
                o, n = row["old"], row["new"]
                print(f"{row['problem']} {m}: {o['time_s']:.2f} -> {n['time_s']:.2f} s, outside "
                      f"{o['time_s'] - o['solver_s'] - o['build_s']:.2f} -> {n['time_s'] - n['solver_s'] - n['build_s']:.2f}"
                      f" s, same plan {row['same']}, {n['status']}, verified {o['verified']}/{n['verified']}, "
                      f"load {o['load_1min']:.1f}/{n['load_1min']:.1f}", flush=True)
    for w in workers.values():
        w.close()
    out = {"commits": {k: _commit(w.checkout) for k, w in workers.items()}, "machine": machine_info(),
           "settings": {"methods": args.methods, "stability": args.stability, "repeat": args.repeat,
                        "problems": args.problems}, "summary": summarise(rows), "runs": rows}
    s = out["summary"]
    print(f"all plans the same: {s['all_same']}; plan time {s['time_old_s']:.1f} -> {s['time_new_s']:.1f} s "
          f"({s['time_old_s'] / s['time_new_s']:.2f}x); outside the solvers {100 * s['outside_share_old']:.1f} % "
          f"-> {100 * s['outside_share_new']:.1f} %")
    if args.out:
        args.out.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
