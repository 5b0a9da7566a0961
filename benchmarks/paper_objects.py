"""The paper's experiment: 5 YCB objects × 5 regrasp pairs × 2 methods (SVD, SD), judged by `verify`.

Sundaralingam & Hermans (ICRA 2018) plan 5 regrasps on each of banana, soft-scrub (bleach cleanser),
mustard, sugar-box and Pringles (chips can) with both forms of OPT2 and report planning time, iterations
and the average point error (mean distance between planned final and desired contacts). This script
does the same with the meshes of `../shared/reference/ycb/`:

1. regrasp pairs per object from a fixed seed (`grasp_gen.generate_regrasp_pairs`), cached as problem
   files in `benchmarks/problems/<object>_<k>.yaml` so repeated runs reuse them;
2. `plan_regrasp` for every pair and method with `regrasp_casadi.batch.plan_many` (`--backend process`:
   `--workers` local processes, the default; `--backend ray`: Ray actors, locally with `--workers` CPUs or
   on the cluster at `--address`; `--backend serial`), each plan judged by `verify`; success = verified
   and final average point error ≤ 6 mm; throughput = plans per minute per core over the planning stage;
3. writes `<out-dir>/paper_objects.json` (every run + environment), `paper_objects.md` (tables beside the
   paper's figures) and two plots: `paper_objects_convergence.png` (normalised average point error per
   iteration, mean ± std over runs) and `paper_objects_error.png` (final error per object and method).

    python benchmarks/paper_objects.py --workers 2
    python benchmarks/paper_objects.py --objects banana sugar-box --pairs 2 --methods svd
    regrasp bench --workers 2          # the same through the CLI
    regrasp bench --backend ray --workers 2              # a local 2-CPU Ray instance
    regrasp bench --backend ray --address auto           # a running Ray cluster, all its CPUs

Planning time is `plan.timing["total"]` (NLP builds included; NLPs are cached per worker process and
object, so the first plan on an object pays the builds). Measures and records; asserts nothing.
The latest per-object table, with its machine and versions, is in `benchmarks/README.md`. A
representative summary (commit 95f585c; Intel Xeon VM, 2 cores, `--workers 2`; Python 3.11.7, CasADi
3.8.2, IPOPT 3.14.19 + MUMPS):

    method  runs  verified  success  median time (paper)  max time  median it. (paper)  error median/max
    SVD     25    25        25       3.61 s (75 s)        22.5 s    7 (44)              0.89 / 3.79 mm
    SD      25    25        23       4.50 s (729 s)       39.2 s    7 (29)              1.13 / 20.97 mm
"""

from __future__ import annotations

import argparse
import datetime
import json
import multiprocessing
import os
import pathlib
import platform
import re
import socket
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
YCB_DIR = REPO.parent / "shared" / "reference" / "ycb"

OBJECTS = {  # paper label -> YCB folder
    "banana": "011_banana",
    "soft-scrub": "021_bleach_cleanser",
    "mustard": "006_mustard_bottle",
    "sugar-box": "004_sugar_box",
    "pringles": "001_chips_can",
}
YCB_NAMES = {ycb: label for label, ycb in OBJECTS.items()}


def object_label(name: str) -> str:
    """The paper label of an object given by its label or its YCB name (`004_sugar_box` -> `sugar-box`)."""
    return YCB_NAMES.get(name, name)


SEED = 2018
ZETA = 0.006  # 6 mm: success threshold on the average point error, as the paper's ζ

# Paper, Table I: planning time per object, seconds (max, median)
PAPER_TIMES = {
    "banana": {"sd": (1025.35, 902.65), "svd": (84.0, 45.0)},
    "sugar-box": {"sd": (2283.37, 1917.41), "svd": (112.59, 99.38)},
    "mustard": {"sd": (1133.504, 649.69), "svd": (135.0, 92.83)},
    "soft-scrub": {"sd": (884.927, 388.317), "svd": (95.0, 74.97)},
    "pringles": {"sd": (3513.96, 796.93), "svd": (134.275, 16.0052)},
}
PAPER_OVERALL = {"svd": {"median_time": 75.0, "median_iterations": 44},
                 "sd": {"median_time": 729.05, "median_iterations": 29}}


# ------------------------------------------------------------------------------------ environment
def _compiled_mode() -> str:
    """How the NLPs are evaluated (`regrasp_casadi.compiled.mode`: "compile", "cached" — the libraries
    `regrasp compile` made, where the cache has them — or "off"), with the C compiler found; "off" for a
    checkout without compiled NLPs."""
    try:
        from regrasp_casadi import compiled
    except ImportError:
        return "off"
    mode = compiled.mode(None)
    return mode if mode == "off" else f"{mode} ({compiled.find_compiler() or 'no C compiler'})"


def environment(workers: int) -> dict:
    """Machine and versions: CPU, cores, Python, CasADi, IPOPT, numpy/scipy/trimesh, git commit."""
    import casadi as ca
    import scipy
    import trimesh

    cpu = platform.processor() or ""
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass

    def git(*args: str) -> str:
        try:
            return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                                  timeout=10, check=False).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    return {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "host": socket.gethostname(),
        "cpu": cpu,
        "cores": os.cpu_count(),
        "load_1min": os.getloadavg()[0],
        "workers": workers,
        "python": platform.python_version(),
        "casadi": ca.__version__,
        "ipopt": _ipopt_version(),
        "linear_solver": "mumps",
        "compiled_mode": _compiled_mode(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "trimesh": trimesh.__version__,
        "git_commit": git("rev-parse", "HEAD"),
        # uncommitted changes to the tracked code and data the results depend on
        "git_dirty": bool(git("status", "--porcelain", "--untracked-files=no", "--", *_RESULT_INPUTS)),
    }


_RESULT_INPUTS = ("regrasp_casadi", "models", "benchmarks/paper_objects.py", "benchmarks/problems",
                  "pyproject.toml")


def _ipopt_version() -> str:
    """IPOPT's version as it prints it in its banner (run in a subprocess to capture its stdout)."""
    code = ("import casadi as ca; x = ca.SX.sym('x'); "
            "s = ca.nlpsol('s', 'ipopt', {'x': x, 'f': x**2}, {'ipopt.print_level': 5}); s(x0=1)")
    try:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                             check=False).stdout
    except (OSError, subprocess.SubprocessError):
        return ""
    m = re.search(r"Ipopt version ([0-9.]+)", out)
    return m.group(1) if m else ""


# ------------------------------------------------------------------------------- pairs (cached)
def problem_paths(problems_dir: pathlib.Path, name: str, n_pairs: int) -> list[pathlib.Path]:
    return [problems_dir / f"{name}_{k}.yaml" for k in range(n_pairs)]


def generate_pairs(name: str, n_pairs: int, problems_dir: str) -> tuple[str, float, list[str]]:
    """Write the missing problem files of `name` (same seed → same pairs). Returns (name, seconds, paths)."""
    from regrasp_casadi.certificates import YCB_MASSES
    from regrasp_casadi.grasp_gen import generate_regrasp_pairs
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.problem import RegraspProblem

    paths = problem_paths(pathlib.Path(problems_dir), name, n_pairs)
    t0 = time.perf_counter()
    if not all(p.is_file() for p in paths):
        hand = Hand.allegro_right()
        obj = ObjectModel.from_mesh(YCB_DIR / OBJECTS[name] / "mesh.obj")
        seed = SEED + list(OBJECTS).index(name)
        pairs = generate_regrasp_pairs(hand, obj, n_pairs, seed=seed)
        for k, ((g0, gg), path) in enumerate(zip(pairs, paths, strict=True)):
            d = float(np.mean(np.linalg.norm(g0.contacts_object - gg.contacts_object, axis=1)))
            desc = (f"{name} ({OBJECTS[name]}) regrasp pair {k} of {n_pairs}, grasp_gen seed {seed}; mean "
                    f"goal contact distance {d * 100:.2f} cm")
            RegraspProblem(f"{name}_{k}", desc, None, hand, obj, g0, gg, {},
                           object_mass=YCB_MASSES[OBJECTS[name]]).save(path)
    return name, time.perf_counter() - t0, [str(p) for p in paths]


# -------------------------------------------------------------------------------------- one run
def record(result, name: str, k: int) -> dict:
    """The benchmark record of one `plan_many` result (a `regrasp_casadi.batch.BatchResult`)."""
    rec: dict = {"object": name, "pair": k, "method": result.method,
                 "problem": os.path.relpath(result.path, REPO), "worker": result.worker}
    plan = result.plan
    if plan is None:  # a benchmark records failures, it does not stop on them
        rec.update(status="exception", status_detail=result.error, verified=False, success=False)
        return rec
    final = plan.steps[-1] if plan.steps else None
    error = float(np.mean(final.contact_error)) if final is not None else float("nan")
    rec.update(
        status=plan.status,
        status_detail=plan.status_detail,
        iterations=int(plan.iterations),
        planning_time=float(plan.timing.get("total", result.wall_time)),
        wall_time=result.wall_time,
        timing={key: float(v) for key, v in plan.timing.items()},
        solves={str(key): int(v) for key, v in (plan.options.get("solves") or {}).items()},
        average_point_error=error,
        max_point_error=float(np.max(final.contact_error)) if final is not None else float("nan"),
        initial_error=float(plan.iteration_errors[0]) if len(plan.iteration_errors) else float("nan"),
        iteration_errors=[float(e) for e in plan.iteration_errors],
        steps=len(plan.steps),
        verified=bool(result.verified),
        violations=list(result.violations[:5]),
        n_violations=len(result.violations),
        min_clearance=float(result.verify_metrics.get("min_clearance", float("nan"))),
        success=bool(result.verified and error <= ZETA),
    )
    log = getattr(result, "solve_log", None)
    if log is not None:  # every backend call (kind, s, iterations) and OPT2 move (s, iterations, accepted)
        rec["solve_calls"] = [[c.kind, c.time, c.iterations] for c in log.calls]
        rec["solve_moves"] = [[m.kind, m.time, m.iterations, bool(m.accepted)] for m in log.moves]
        rec["outside_solvers_time"] = rec["planning_time"] - sum(c.time for c in log.calls)
    return rec


def solve_statistics(runs: list[dict]) -> dict:
    """Over `runs` (one method's): per kind ("opt1", "opt2") the per-call median / p95 time (ms) and
    iteration median / p95 / max, the moves and the share of their time spent on rejected ones
    (`solve_log.summarise`); and the time outside the solvers, total and as a share of planning time."""
    from regrasp_casadi.solve_log import SolveRecord, summarise

    logged = [r for r in runs if "solve_calls" in r]
    calls = [SolveRecord(k, t, i, "") for r in logged for k, t, i in r["solve_calls"]]
    moves = [SolveRecord(k, t, i, "", a) for r in logged for k, t, i, a in r["solve_moves"]]
    out: dict = summarise(calls, moves)
    plan_time = sum(r["planning_time"] for r in logged)
    outside = sum(r["outside_solvers_time"] for r in logged)
    out["outside_solvers"] = {"time_s": outside, "share": outside / plan_time if plan_time > 0 else float("nan")}
    t = np.array([r["planning_time"] for r in logged], float)
    out["plan_time"] = {"median_s": float(np.median(t)) if t.size else float("nan"),
                        "p95_s": float(np.percentile(t, 95)) if t.size else float("nan"),
                        "max_s": float(np.max(t)) if t.size else float("nan"), "plans": int(t.size)}
    return out


def throughput(n_plans: int, wall_time: float, cores: int) -> dict:
    """Plans per minute, and per minute per core, of `n_plans` plans that took `wall_time` s on `cores`."""
    per_minute = 60.0 * n_plans / wall_time if wall_time > 0 else float("nan")
    return {"plans": n_plans, "wall_time": wall_time, "cores": cores, "plans_per_minute": per_minute,
            "plans_per_minute_per_core": per_minute / max(1, cores)}


# ------------------------------------------------------------------------------------- summaries
def _fmt(x: float, unit: str = "") -> str:
    if x is None or not np.isfinite(x):
        return "–"
    if unit == "mm":
        return f"{x * 1e3:.2f}"
    return f"{x:.3g}" if x < 100 else f"{x:.0f}"


def summarise(runs: list[dict]) -> dict:
    """Per (object, method) and per method: median/max time, median iterations, median/max error, success."""
    out: dict = {"per_object": {}, "per_method": {}}

    def stats(rs: list[dict]) -> dict:
        t = np.array([r.get("planning_time", np.nan) for r in rs], float)
        it = np.array([r.get("iterations", np.nan) for r in rs], float)
        e = np.array([r.get("average_point_error", np.nan) for r in rs], float)
        ok = lambda a: a[np.isfinite(a)]  # noqa: E731
        return {
            "runs": len(rs),
            "median_time": float(np.median(ok(t))) if ok(t).size else float("nan"),
            "max_time": float(np.max(ok(t))) if ok(t).size else float("nan"),
            "median_iterations": float(np.median(ok(it))) if ok(it).size else float("nan"),
            "median_error": float(np.median(ok(e))) if ok(e).size else float("nan"),
            "max_error": float(np.max(ok(e))) if ok(e).size else float("nan"),
            "verified": int(sum(bool(r.get("verified")) for r in rs)),
            "success": int(sum(bool(r.get("success")) for r in rs)),
            "converged": int(sum(r.get("status") == "converged" for r in rs)),
        }

    for name in OBJECTS:
        for method in ("svd", "sd"):
            rs = [r for r in runs if r["object"] == name and r["method"] == method]
            if rs:
                out["per_object"][f"{name}/{method}"] = stats(rs)
    for method in ("svd", "sd"):
        rs = [r for r in runs if r["method"] == method]
        if rs:
            out["per_method"][method] = stats(rs)
            out.setdefault("solves", {})[method] = solve_statistics(rs)
    return out


def solves_markdown(solves: dict) -> list[str]:
    """The per-solve table (issue 10 targets: OPT2 ≤ 20 ms, OPT1 ≤ 3 ms median per call, iterations p95
    ≤ 60, rejected < 5 % of OPT2 time, outside the solvers < 10 %)."""
    lines = ["", "| method | NLP | calls | median / p95 per call (ms) | iterations median / p95 / max "
             "| moves | rejected (share of time) |", "|---|---|---|---|---|---|---|"]
    for method, s in solves.items():
        for kind in ("opt1", "opt2"):
            k = s.get(kind)
            if not k:
                continue
            share = k["rejected_share"]
            rejected = f"{k['rejected']} ({share * 100:.1f} %)" if np.isfinite(share) else "–"
            lines.append(f"| {method.upper()} | {kind.upper()} | {k['calls']} | {k['call_median_ms']:.1f} / "
                         f"{k['call_p95_ms']:.1f} | {k['iterations_median']:.0f} / {k['iterations_p95']:.0f} / "
                         f"{k['iterations_max']:.0f} | {k['moves']} | {rejected} |")
    for method, s in solves.items():
        pt, out = s["plan_time"], s["outside_solvers"]
        lines.append(f"\n{method.upper()}: plan time median {pt['median_s']:.2f} s, p95 {pt['p95_s']:.2f} s, max "
                     f"{pt['max_s']:.2f} s; outside the solvers {out['share'] * 100:.1f} % of planning time.")
    return lines


def markdown(summary: dict, env: dict) -> str:
    lines = [
        f"Machine: {env['cpu']} ({env['cores']} cores, {env['workers'] or 'all'} worker(s), "
        f"{env.get('backend', 'process')} backend); Python "
        f"{env['python']}, CasADi {env['casadi']}, IPOPT {env['ipopt']} ({env['linear_solver']}); compiled NLPs: "
        f"{env.get('compiled_mode', 'off')}; commit "
        f"`{env['git_commit'][:10]}`{' (dirty tree)' if env['git_dirty'] else ''}; {env['date']}.",
        "",
        "| object | method | runs | verified | success (≤ 6 mm) | median time (s) | max time (s) "
        "| paper median / max (s) | median iterations | median error (mm) | max error (mm) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key, s in summary["per_object"].items():
        name, method = key.split("/")
        pmax, pmed = PAPER_TIMES[name][method]
        lines.append(
            f"| {name} | {method.upper()} | {s['runs']} | {s['verified']} | {s['success']} | "
            f"{_fmt(s['median_time'])} | {_fmt(s['max_time'])} | {pmed:g} / {pmax:g} | "
            f"{_fmt(s['median_iterations'])} | {_fmt(s['median_error'], 'mm')} | "
            f"{_fmt(s['max_error'], 'mm')} |")
    lines += ["", "| method | runs | verified | success | converged | median time (s) | paper median (s) "
              "| max time (s) | median iterations | paper median iterations | median error (mm) "
              "| max error (mm) |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for method, s in summary["per_method"].items():
        p = PAPER_OVERALL[method]
        lines.append(
            f"| {method.upper()} | {s['runs']} | {s['verified']} | {s['success']} | {s['converged']} | "
            f"{_fmt(s['median_time'])} | {p['median_time']:g} | {_fmt(s['max_time'])} | "
            f"{_fmt(s['median_iterations'])} | {p['median_iterations']} | {_fmt(s['median_error'], 'mm')} | "
            f"{_fmt(s['max_error'], 'mm')} |")
    if summary.get("solves"):
        lines += solves_markdown(summary["solves"])
    tp = summary.get("throughput")
    if tp:
        lines += ["", f"Throughput: {tp['plans']} plans in {tp['wall_time']:.1f} s on {tp['cores']} core(s) "
                  f"({env.get('backend', 'process')} backend): {_fmt(tp['plans_per_minute'])} plans/min, "
                  f"{_fmt(tp['plans_per_minute_per_core'])} plans/min per core (load "
                  f"{env['load_1min']:.1f} before, {env.get('load_1min_after', float('nan')):.1f} after)."]
    lines += ["", "Paper (Table I and §VI): SVD median 75 s, SD median 729 s over all objects; median "
              "iterations 44 (SVD), 29 (SD); sugar-box SVD median error 0.36 cm. Paper times are SNOPT on "
              "the authors' machine; ours include NLP builds."]
    return "\n".join(lines)


def plots(runs: list[dict], out_dir: pathlib.Path) -> list[pathlib.Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    colors = {"svd": "tab:blue", "sd": "tab:orange"}
    # convergence: normalised average point error per iteration
    fig, ax = plt.subplots(figsize=(6, 4))
    for method in ("svd", "sd"):
        curves = [np.asarray(r["iteration_errors"]) for r in runs
                  if r["method"] == method and len(r.get("iteration_errors", [])) > 0]
        curves = [c / c[0] for c in curves if c[0] > 0]
        if not curves:
            continue
        n = max(len(c) for c in curves)
        M = np.array([np.concatenate([c, np.full(n - len(c), c[-1])]) for c in curves])
        mean, std = M.mean(axis=0), M.std(axis=0)
        x = np.arange(n)
        ax.plot(x, mean, color=colors[method], label=f"{method.upper()} ({len(curves)} runs)")
        ax.fill_between(x, np.maximum(mean - std, 0), mean + std, color=colors[method], alpha=0.2)
    ax.set_xlabel("iteration")
    ax.set_ylabel("normalised average point error")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    p = out_dir / "paper_objects_convergence.png"
    fig.savefig(p, dpi=120)
    plt.close(fig)
    paths.append(p)
    # final average point error per object and method (box + strip)
    fig, ax = plt.subplots(figsize=(7, 4))
    names = [n for n in OBJECTS if any(r["object"] == n for r in runs)]
    rng = np.random.default_rng(0)
    for i, name in enumerate(names):
        for j, method in enumerate(("svd", "sd")):
            e = np.array([r.get("average_point_error", np.nan) for r in runs
                          if r["object"] == name and r["method"] == method], float) * 1e3
            e = e[np.isfinite(e)]
            if e.size == 0:
                continue
            pos = i + (j - 0.5) * 0.35
            ax.boxplot([e], positions=[pos], widths=0.28, showfliers=False,
                       medianprops={"color": colors[method]})
            ax.scatter(pos + rng.uniform(-0.06, 0.06, e.size), e, s=14, color=colors[method], zorder=3,
                       label=method.upper() if i == 0 else None)
    ax.axhline(ZETA * 1e3, color="gray", ls="--", lw=1, label="6 mm")
    ax.set_xticks(range(len(names)), names)
    ax.set_ylabel("average point error (mm)")
    ax.set_ylim(bottom=0)
    ax.grid(axis="y", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    p = out_dir / "paper_objects_error.png"
    fig.savefig(p, dpi=120)
    plt.close(fig)
    paths.append(p)
    return paths


def _finite(x):
    """NaN/inf -> None, recursively (strict JSON)."""
    if isinstance(x, float):
        return x if np.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    return x


# ------------------------------------------------------------------------------------------- main
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--objects", nargs="+", default=list(OBJECTS), choices=list(OBJECTS), type=object_label,
                        metavar="OBJECT", help=f"paper labels ({', '.join(OBJECTS)}) or YCB names "
                        f"({', '.join(OBJECTS.values())})")
    parser.add_argument("--pairs", type=int, default=5, help="regrasp pairs per object")
    parser.add_argument("--methods", nargs="+", default=["svd", "sd"], choices=["svd", "sd"], help="OPT2 objectives")
    parser.add_argument("--backend", default="process", choices=["process", "ray", "serial"],
                        help="how the plans run (regrasp_casadi.batch.plan_many)")
    parser.add_argument("--workers", type=int, default=None,
                        help="worker processes / Ray CPUs (None: 1, or with --address the cluster's CPUs)")
    parser.add_argument("--address", default=None,
                        help="--backend ray: address of a running Ray cluster (None: start a local one)")
    parser.add_argument("--max-iters", type=int, default=50, help="planner iteration limit")
    parser.add_argument("--stability", choices=("force_closure", "gravity", "none"), default=None,
                        help="PlannerOptions.stability (default: the planner's, force_closure; none: the "
                             "paper's planner)")
    parser.add_argument("--out-dir", type=pathlib.Path, default=HERE / "results", help="folder of the results")
    parser.add_argument("--problems-dir", type=pathlib.Path, default=HERE / "problems",
                        help="cache of generated pairs (problem files)")
    parser.add_argument("--no-plots", action="store_true", help="no convergence and error plots")
    args = parser.parse_args(argv)
    if args.address is not None and args.backend != "ray":
        parser.error("--address needs --backend ray")
    if args.workers is None and args.address is None:
        args.workers = 1
    return args


def _generate_all(args: argparse.Namespace) -> tuple[dict[str, list[str]], dict[str, float]]:
    """The problem files of every object (generated when missing), and the generation time per object."""
    from tqdm import tqdm

    ctx = multiprocessing.get_context("fork") if sys.platform.startswith("linux") else None
    paths: dict[str, list[str]] = {}
    gen_times: dict[str, float] = {}
    with ProcessPoolExecutor(max_workers=max(1, args.workers or 1), mp_context=ctx) as pool:
        futs = [pool.submit(generate_pairs, n, args.pairs, str(args.problems_dir)) for n in args.objects]
        for f in tqdm(as_completed(futs), total=len(futs), desc="pairs", unit="object"):
            name, secs, ps = f.result()
            paths[name], gen_times[name] = ps, secs
    return paths, gen_times


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if not YCB_DIR.is_dir():
        print(f"YCB meshes not found: {YCB_DIR}", file=sys.stderr)
        return 2
    from regrasp_casadi.batch import plan_many

    args.out_dir.mkdir(parents=True, exist_ok=True)
    args.problems_dir.mkdir(parents=True, exist_ok=True)
    env = environment(args.workers)
    env.update(backend=args.backend, ray_address=args.address)
    t_start = time.perf_counter()
    paths, gen_times = _generate_all(args)
    labels = [(n, k) for n in args.objects for k in range(args.pairs)]
    runs: list[dict] = []
    t_plans = time.perf_counter()
    results = plan_many([paths[n][k] for n, k in labels], backend=args.backend, workers=args.workers,
                        address=args.address, methods=args.methods, max_iters=args.max_iters,
                        **({"stability": args.stability} if args.stability else {}))
    plans_time = time.perf_counter() - t_plans
    env["load_1min_after"] = os.getloadavg()[0]
    for r in results:
        runs.append(record(r, *labels[r.index // len(args.methods)]))
    cores = args.workers or len({r.worker for r in results})
    summary = summarise(runs)
    summary["throughput"] = throughput(len(results), plans_time, cores)
    result = {"environment": env, "settings": {"seed": SEED, "pairs": args.pairs, "methods": args.methods,
                                               "objects": args.objects, "max_iters": args.max_iters,
                                               "stability": args.stability,
                                               "success_error": ZETA, "backend": args.backend,
                                               "workers": args.workers, "address": args.address},
              "pair_generation_time": gen_times, "total_time": time.perf_counter() - t_start,
              "summary": summary, "paper": {"times": PAPER_TIMES, "overall": PAPER_OVERALL}, "runs": runs}
    json_path = args.out_dir / "paper_objects.json"
    json_path.write_text(json.dumps(_finite(result), indent=1, allow_nan=False))
    table = markdown(summary, env)
    (args.out_dir / "paper_objects.md").write_text(table + "\n")
    print(table)
    print(f"\nruns: {json_path}")
    if not args.no_plots:
        for p in plots(runs, args.out_dir):
            print(f"plot: {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
