"""Wall time of `regrasp_casadi.simulate` per plan, two code versions interleaved on the same plans.

    python benchmarks/simulate_time.py /tmp/sim/*.json --code /tmp/sim/base . --out /tmp/sim/time.json

Each (plan, code) pair runs in its own process (``PYTHONPATH=<code>``, `nice` is the caller's) with the
CLI's options (`SimOptions()`, gravity off unless ``--gravity``; ``--feedback none``: open loop); the code
versions alternate plan by plan, so that both see the same machine load. Per run it records the wall time
of the `simulate` call (hand and object models and the MuJoCo model built, imports and plan reading
excluded), that of the whole process (as `regrasp simulate` without its printing), the 1-minute load
average before it, the
verdict, the largest step-end deviations and every step-end deviation (mm, degrees) and touching-finger
count, so that two versions can be compared step by step (``--compare`` prints the largest
difference). Measures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent


def run_one(plan_path: str, feedback: str, gravity: tuple[float, float, float]) -> dict:
    """Simulate one plan with the code on ``sys.path``; the record (see the module docstring)."""
    from regrasp_casadi.plan import Plan
    from regrasp_casadi.simulate import SimOptions, simulate

    plan = Plan.load(pathlib.Path(plan_path))
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    report = simulate(plan, options=SimOptions(feedback=feedback, gravity_palm=gravity))
    wall = time.perf_counter() - t0
    return {
        "plan": plan_path, "steps": len(plan.steps), "wall_time": wall, "load_before": load,
        "load_after": os.getloadavg()[0], "sim_time": report.sim_time, "status": report.status,
        "drop_time": report.drop_time, "max_deviation_mm": report.max_deviation_mm,
        "max_deviation_deg": report.max_deviation_deg,
        "step_deviation_mm": [r.deviation_mm for r in report.steps],
        "step_deviation_deg": [r.deviation_deg for r in report.steps],
        "step_touching": [len(r.fingers_touching) for r in report.steps],
        "step_time": [r.time for r in report.steps],
    }


def _spawn(code: str, plan_path: str, feedback: str, gravity) -> dict:
    env = dict(os.environ, PYTHONPATH=str(pathlib.Path(code).resolve()))
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, __file__, "--worker", plan_path, "--feedback", feedback,
                          "--gravity", *map(str, gravity)], env=env, capture_output=True, text=True, check=True)
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    rec["code"], rec["process_time"] = code, time.perf_counter() - t0
    return rec


def _differences(a: dict, b: dict) -> tuple[float, float, float, float]:
    """Largest step-end deviation difference (mm, degrees) of two runs of one plan, at the step ends before
    the first drop of either run, then at those after it (0 when there are none)."""
    drop = min((r["drop_time"] for r in (a, b) if r["drop_time"] is not None), default=float("inf"))
    before, after = [0.0, 0.0], [0.0, 0.0]
    for t, x_mm, y_mm, x_deg, y_deg in zip(a["step_time"], a["step_deviation_mm"], b["step_deviation_mm"],
                                           a["step_deviation_deg"], b["step_deviation_deg"], strict=True):
        out = before if t < drop else after
        out[0], out[1] = max(out[0], abs(x_mm - y_mm)), max(out[1], abs(x_deg - y_deg))
    return before[0], before[1], after[0], after[1]


def compare(records: list[dict], before: str, after: str) -> None:
    """Print per plan: wall times and their ratio, verdicts, drop times, largest step-end deviation
    differences before and after the (earlier) drop, and whether the touching-finger counts agree."""
    by: dict[tuple[str, str], dict] = {}
    for r in records:  # the fastest of the repeats (the least disturbed by the other jobs)
        key = (r["code"], r["plan"])
        if key not in by or r["wall_time"] < by[key]["wall_time"]:
            by[key] = dict(r, process_time=min(r["process_time"], by.get(key, r)["process_time"]))
    for plan in dict.fromkeys(r["plan"] for r in records):
        a, b = by.get((before, plan)), by.get((after, plan))
        if a is None or b is None:
            continue
        mm, deg, mm_after, deg_after = _differences(a, b)
        drops = "" if a["drop_time"] is None and b["drop_time"] is None else \
            f" drop {a['drop_time'] or 0:.2f}/{b['drop_time'] or 0:.2f} s"
        print(f"{pathlib.Path(plan).stem:22s} {a['steps']:4d} steps {a['sim_time']:6.2f} s sim  {a['wall_time']:6.2f} ->"
              f"{b['wall_time']:6.2f} s (x{a['wall_time'] / b['wall_time']:.2f}; process {a['process_time']:.1f} -> "
              f"{b['process_time']:.1f} s; load {a['load_before']:.1f}/{b['load_before']:.1f})  "
              f"{a['status']}/{b['status']}{drops}  step-end diff {mm:.1e} mm "
              f"{deg:.1e} deg, after the drop {mm_after:.1e} mm {deg_after:.1e} deg"
              f"{'' if a['step_touching'] == b['step_touching'] else '  TOUCHING DIFFERS'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("plans", nargs="*", help="plan files (JSON)")
    ap.add_argument("--code", nargs="+", default=[str(HERE.parent)],
                    help="folders holding a regrasp_casadi package, run in turn on each plan")
    ap.add_argument("--feedback", default="object_pose", choices=("object_pose", "none"))
    ap.add_argument("--gravity", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "Z"),
                    help="gravity in the palm frame, m/s^2 (default: off, as `regrasp simulate`)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each (plan, code); the comparison "
                    "takes the fastest")
    ap.add_argument("--out", help="write the records (JSON)")
    ap.add_argument("--compare", nargs=2, metavar=("BEFORE", "AFTER"), help="records file: print the "
                    "comparison of these two --code folders instead of running")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(run_one(args.worker, args.feedback, tuple(args.gravity))))
        return
    if args.compare:
        compare(json.loads(pathlib.Path(args.out).read_text())["records"], *args.compare)
        return
    sys.path.insert(0, str(HERE))
    from machine import machine_info

    records = []
    for plan, code in [(p, c) for _ in range(args.repeat) for p in args.plans for c in args.code]:
        rec = _spawn(code, plan, args.feedback, args.gravity)
        records.append(rec)
        print(f"{pathlib.Path(plan).stem:26s} {code:20s} {rec['wall_time']:6.2f} s (load "
              f"{rec['load_before']:.1f}) {rec['status']:9s} max {rec['max_deviation_mm']:.3f} mm / "
              f"{rec['max_deviation_deg']:.3f} deg", flush=True)
        if args.out:
            pathlib.Path(args.out).write_text(json.dumps(
                {"machine": machine_info(("mujoco", "numpy", "scipy", "casadi")), "feedback": args.feedback,
                 "gravity_palm": args.gravity, "repeat": args.repeat, "code": args.code, "records": records},
                indent=1))
    if len(args.code) == 2:
        compare(records, *args.code)


if __name__ == "__main__":
    main()
