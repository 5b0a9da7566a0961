"""Self-collision on and off: do the problems' grasps and plans keep the fingers apart, and what it costs.

For every problem (the shipped ones, and with ``--ycb`` the paper pairs of ``benchmarks/problems``) and
method: are the problem's own grasps (initial, desired) in self-collision (sphere model: the smallest
surface distance of `Hand.self_collision_pairs()`; vendor link meshes: intersecting link pairs, when
``../shared/reference/allegro_right`` and python-fcl are there); then the plan without
(``self_clearance=None``) and with the constraints (default 1 mm): status, whether `verify` passes
without and with its self-collision checks (spheres, and the vendor meshes), the steps in self-collision,
plan time without the NLP builds (wall; with ``--warm-up`` the NLPs are built on an untimed plan first
and the process CPU time is that of the plan alone) and the build time (reported apart). Measures; asserts nothing.

    python benchmarks/self_collision.py --out /tmp/selfcol.json            # shipped problems
    python benchmarks/self_collision.py --ycb --out /tmp/selfcol_ycb.json  # + the paper pairs

Measured (results/self_collision.json; 2 cores shared with other jobs, load 5-6, so times are inflated;
"verified" includes both self-collision rows, with the vendor meshes of ../shared/reference):

| problems | self-collision | converged | verified | plans through a self-collision (spheres / meshes, max depth) | median plan s (wall, no builds) | median build s |
|---|---|---|---|---|---|---|
| shipped (regenerated with the constraint), 8 | off | 8 | 4 (8 without the self-collision rows) | 4 / 1, 2.1 mm | 1.23 | 0.96 |
| shipped, 8 | on (1 mm) | 8 | 8 | 0 / 0 | 2.05 | 5.4 |
| YCB pairs (generated before it), 50 | off | 45 | 4 (50 without) | 46 / 44, 13.4 mm | 12.5 | 6.1 |
| YCB pairs, 50 | on | 28 | 13 (8 of them converged) | 36 / 32, 13.3 mm | 24.2 | 15.5 |

The YCB pairs themselves: 22 of 25 have a grasp in sphere self-collision (initial 18, desired 14), 21 of 25
on the vendor meshes (up to 11.2 mm); the three that do not (pringles_0, 1, 4) converge and verify with
both methods and the constraint on. A plan that starts in self-collision may not make an overlap worse
(the constraints' floors) and often resolves it, but its step 0 fails verify whatever the planner does.

Since then the 25 pairs were regenerated with the self-collision rule (`benchmarks/regenerate_pairs.py`,
same seeds, every other key of the files kept; 856 s wall on 2 workers, load 10-17): the smallest sphere
self-clearance of the 50 grasps is 1.00 mm (soft-scrub_0's desired grasp), none below the 1 mm rule
(`Hand.self_collision_distances`). The table above predates the regeneration.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
VENDOR = REPO.parent / "shared" / "reference" / "allegro_right" / "allegro_hand_right.urdf"
sys.path.insert(0, str(HERE))

_MESHES: dict[str, object] = {}


def _meshes(hand):
    """The vendor link meshes (None without reference data or python-fcl), once per worker."""
    if "vendor" not in _MESHES:
        from regrasp_casadi.link_meshes import LinkMeshes

        _MESHES["vendor"] = LinkMeshes.from_urdf(VENDOR, hand)[0] if VENDOR.is_file() else None
    return _MESHES["vendor"]


def _grasp_state(hand, q) -> dict:
    meshes = _meshes(hand)
    out = {"sphere_min_mm": round(float(np.min(hand.self_collision_distances(q))) * 1e3, 2)}
    if meshes is not None:
        hits = meshes.intersections(q)
        out["mesh_pairs"] = len(hits)
        out["mesh_depth_mm"] = round(max((d for *_, d in hits), default=0.0) * 1e3, 2)
    return out


def _plan(problem, method, self_clearance) -> dict:
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.verify import verify

    extra = {} if self_clearance == "default" else {"self_clearance": self_clearance}
    cpu = time.process_time()
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method, **extra)
    cpu = time.process_time() - cpu
    report = verify(plan, problem.hand, problem.obj,
                    link_meshes=VENDOR if VENDOR.is_file() else None)
    other = [v for v in report.violations if not v.check.startswith("self_collision")]
    sphere_steps = {v.step for v in report.violations if v.check == "self_collision"}
    mesh_steps = {v.step for v in report.violations if v.check == "self_collision_mesh"}
    return {"status": plan.status, "iterations": plan.iterations, "steps": len(plan.steps),
            "verified_without_self": not other, "verified": report.ok,
            "sphere_collision_steps": len(sphere_steps), "mesh_collision_steps": len(mesh_steps),
            "max_mesh_depth_mm": round(report.metrics["max_mesh_penetration"] * 1e3, 2),
            "wall_s": round(plan.timing["total"] - plan.timing["build"], 2), "cpu_s": round(cpu, 2),
            "build_s": round(plan.timing["build"], 2), "final_max_error_mm": round(
                float(np.max(plan.steps[-1].contact_error)) * 1e3, 2) if plan.steps else None}


def measure(path: str, method: str, warm: bool) -> dict:
    """One problem, one method: its grasps, then the plan off and on (never raises)."""
    from regrasp_casadi.problem import RegraspProblem

    rec = {"problem": pathlib.Path(path).stem, "method": method}
    try:
        problem = RegraspProblem.load(path)
        if warm:  # build the NLPs of this process (both settings) outside the timed plans
            for sc in (None, "default"):
                _plan(problem, method, sc)
        hand = problem.hand
        rec["grasp0"] = _grasp_state(hand, problem.grasp0.q)
        if problem.grasp_goal.q is not None:
            rec["goal"] = _grasp_state(hand, problem.grasp_goal.q)
        rec["off"] = _plan(problem, method, None)
        rec["on"] = _plan(problem, method, "default")
    except Exception as exc:  # recorded, not raised
        rec["error"] = f"{type(exc).__name__}: {exc}"
    return rec


def _table(records: list[dict]) -> str:
    rows = ["| problem | method | grasp0 / goal sphere min (mm) | grasp0 / goal mesh pairs | off: status, "
            "verified w/o self / with, sphere steps, s | on: status, verified, sphere steps, s |",
            "|---|---|---|---|---|---|"]
    for r in records:
        if "error" in r:
            rows.append(f"| {r['problem']} | {r['method']} | {r['error']} | | | |")
            continue
        g0, gg = r["grasp0"], r.get("goal", {})
        off, on = r["off"], r["on"]
        rows.append(
            f"| {r['problem']} | {r['method']} | {g0['sphere_min_mm']} / {gg.get('sphere_min_mm', '—')} | "
            f"{g0.get('mesh_pairs', '—')} / {gg.get('mesh_pairs', '—')} | {off['status']}, "
            f"{off['verified_without_self']} / {off['verified']}, {off['sphere_collision_steps']}/{off['steps']}, "
            f"{off['wall_s']} | {on['status']}, {on['verified']}, {on['sphere_collision_steps']}/{on['steps']}, "
            f"{on['wall_s']} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--ycb", action="store_true", help="also the paper pairs of benchmarks/problems")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--warm-up", action="store_true", help="build the NLPs on an untimed plan first")
    args = ap.parse_args(argv)
    from machine import machine_info

    files = sorted((REPO / "problems").glob("*.yaml"))
    if args.ycb:
        files += sorted((HERE / "problems").glob("*.yaml"))
    jobs = [(str(p), m, args.warm_up) for p in files for m in ("svd", "sd")]
    with ProcessPoolExecutor(args.workers) as pool:
        records = list(pool.map(measure, *zip(*jobs, strict=True)))
    args.out.write_text(json.dumps({"machine": machine_info(), "records": records}, indent=1))
    print(_table(records))
    return 0


if __name__ == "__main__":
    sys.exit(main())
