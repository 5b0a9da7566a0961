"""Throughput of `plan_many`: the shipped problems × {svd, sd} planned serially, in a process pool and on Ray.

Each backend plans the same jobs from cold (fresh worker processes, empty NLP caches; worker start-up,
Ray start-up and NLP builds included), and every result is checked against the serial run (same status,
iterations and bit-identical joint angles of every step). Records the wall time, plans per minute and
plans per minute per core, plans per CPU-minute (over the workers' CPU time in the jobs: what a core
gives when it is not shared), the CPU obtained (the workers' CPU time / wall time, in cores: below the
cores asked for when other processes share them), the workers' busy fraction (sum of job times / (wall time × cores)), the
NLP build time and the 1-minute load average before and after each backend, with the machine
(benchmarks/machine.py).

    python benchmarks/throughput.py                         # serial, process (2 workers), ray (2 CPUs)
    python benchmarks/throughput.py --backends serial process --workers 2 --repeat 2

Writes `<out-dir>/throughput.json` and prints a markdown table. The figures are indicative on a shared
machine: the load average shows how many other processes competed for the cores. Measures and records;
exits 1 only when a backend's plans differ from the serial ones.

Latest run (`python benchmarks/throughput.py --repeat 2`, commit 34d012f, 2026-12-01 19:53 UTC; AMD EPYC
VM, 2 cores, Python 3.11.7, CasADi 3.8.2; the 4 shipped problems × {svd, sd} = 8 plans per row; 1-minute
load 6.6–10.4 from about five other sessions):

| backend | cores | plans | wall time (s) | plans/min | plans/min per core | plans per CPU-min | CPU obtained (cores) | busy fraction | load before / after | same as serial |
|---|---|---|---|---|---|---|---|---|---|---|
| serial | 1 | 8 | 42.3 | 11.3 | 11.3 | 37.8 | 0.30 | 0.92 | 10.4 / 9.8 | yes |
| process | 2 | 8 | 30.0 | 16.0 | 8.0 | 36.5 | 0.44 | 0.86 | 9.8 / 8.0 | yes |
| ray | 2 | 8 | 34.3 | 14.0 | 7.0 | 31.4 | 0.45 | 0.62 | 8.0 / 7.2 | yes |
| serial | 1 | 8 | 26.4 | 18.2 | 18.2 | 47.9 | 0.38 | 1.00 | 7.2 / 6.6 | yes |
| process | 2 | 8 | 31.9 | 15.0 | 7.5 | 39.5 | 0.38 | 0.95 | 6.6 / 6.8 | yes |
| ray | 2 | 8 | 39.3 | 12.2 | 6.1 | 34.0 | 0.36 | 0.61 | 6.8 / 8.0 | yes |

Every backend gave the serial plans bit for bit. The two workers did not get more CPU than one process:
the kernel shares the cores between sessions (`sched_autogroup_enabled = 1`), so this session obtained
0.3–0.45 of a core whether it ran one process or two, and the wall times measure the load, not the
parallelism. The load-independent figure is plans per CPU-minute: 38–48 serial, 37–40 with two
processes (some objects' NLPs built in both workers), 31–34 on Ray, whose busy fraction of about 0.6 is
its start-up (`ray.init`, actors, imports: ≈ 7 s of each ≈ 35 s row) — worth it for long batches or a
cluster, not for 8 short plans. On two unshared cores, two processes would give about 2 × 37 ≈ 70 plans
per minute on these problems.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))


def _same(a, b) -> bool:
    """Same status, iterations and bit-identical joint angles and poses in every step."""
    if a.plan is None or b.plan is None:
        return a.error == b.error
    pa, pb = a.plan, b.plan
    return (pa.status == pb.status and pa.iterations == pb.iterations and len(pa.steps) == len(pb.steps)
            and all(np.array_equal(x.q, y.q) and np.array_equal(x.T_palm_object, y.T_palm_object)
                    for x, y in zip(pa.steps, pb.steps, strict=True)))


def run_backend(backend: str, problems: list[str], methods: list[str], workers: int) -> tuple[dict, list]:
    """Plan every job with `backend` from cold; returns (the measurement, the results)."""
    from regrasp_casadi.batch import plan_many

    cores = 1 if backend == "serial" else workers
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    results = plan_many(problems, backend=backend, workers=workers, methods=methods, progress=False)
    wall = time.perf_counter() - t0
    busy = sum(r.wall_time for r in results)
    cpu = sum(r.cpu_time for r in results)
    per_minute = 60.0 * len(results) / wall
    return {
        "backend": backend, "cores": cores, "plans": len(results), "wall_time": wall,
        "plans_per_minute": per_minute, "plans_per_minute_per_core": per_minute / cores,
        "busy_fraction": busy / (wall * cores), "job_time_sum": busy, "job_cpu_time_sum": cpu,
        "plans_per_cpu_minute": 60.0 * len(results) / cpu,
        "build_time_sum": sum(r.plan.timing.get("build", 0.0) for r in results if r.plan is not None),
        "workers_used": len({r.worker for r in results}),
        "load_1min_before": load_before, "load_1min_after": os.getloadavg()[0],
        "statuses": [r.status for r in results], "errors": [r.error for r in results if r.error],
    }, results


def markdown(runs: list[dict], machine: dict) -> str:
    lines = [
        f"Machine: {machine['cpu']}, {machine['cores']} cores; Python {machine['python']}, CasADi "
        f"{machine['versions'].get('casadi')}; commit `{machine['git_commit'][:10]}`"
        f"{' (dirty tree)' if machine['git_dirty'] else ''}; {machine['date']}.",
        "",
        "| backend | cores | plans | wall time (s) | plans/min | plans/min per core | plans per CPU-min "
        "| CPU obtained (cores) | busy fraction | load before / after | same as serial |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        lines.append(
            f"| {r['backend']} | {r['cores']} | {r['plans']} | {r['wall_time']:.1f} | "
            f"{r['plans_per_minute']:.1f} | {r['plans_per_minute_per_core']:.1f} | "
            f"{r['plans_per_cpu_minute']:.1f} | {r['job_cpu_time_sum'] / r['wall_time']:.2f} | "
            f"{r['busy_fraction']:.2f} | "
            f"{r['load_1min_before']:.1f} / {r['load_1min_after']:.1f} | "
            f"{'yes' if r['same_as_serial'] else 'NO'} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backends", nargs="+", default=["serial", "process", "ray"],
                    choices=["serial", "process", "ray"])
    ap.add_argument("--workers", type=int, default=2, help="processes / Ray CPUs (default 2)")
    ap.add_argument("--methods", nargs="+", default=["svd", "sd"], choices=["svd", "sd"])
    ap.add_argument("--repeat", type=int, default=1, help="rounds over the backends (default 1)")
    ap.add_argument("--out-dir", type=pathlib.Path, default=HERE / "results")
    args = ap.parse_args(argv)
    from machine import machine_info

    problems = [str(p) for p in sorted((REPO / "problems").glob("*.yaml"))]
    backends = list(args.backends)
    if "ray" in backends:
        try:
            import ray  # noqa: F401
        except ImportError:
            print("ray is not installed (pip install 'regrasp-casadi[ray]'): skipping the ray backend",
                  file=sys.stderr)
            backends.remove("ray")
    machine = machine_info()
    reference = None
    runs: list[dict] = []
    for _ in range(args.repeat):
        for backend in backends:
            rec, results = run_backend(backend, problems, args.methods, args.workers)
            if reference is None:
                reference = results  # the first run (serial by default) is the reference
            rec["same_as_serial"] = all(_same(a, b) for a, b in zip(results, reference, strict=True))
            runs.append(rec)
            print(f"{backend}: {rec['plans']} plans in {rec['wall_time']:.1f} s "
                  f"({rec['plans_per_minute_per_core']:.1f} plans/min per core)", file=sys.stderr)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    out = args.out_dir / "throughput.json"
    out.write_text(json.dumps({"machine": machine, "problems": [os.path.relpath(p, REPO) for p in problems],
                               "methods": args.methods, "workers": args.workers, "runs": runs}, indent=1))
    print(markdown(runs, machine))
    print(f"\nruns: {out}")
    return 0 if all(r["same_as_serial"] for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
