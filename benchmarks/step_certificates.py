"""How many steps of the planner's plans hold the object: force-closure and gravity certificates per step.

Plans each problem with each method (`plan_regrasp`, default options) and certifies every step's holding
set (`certificates.step_certificates`): for a gait, the fingers other than the moving one; for any other
step, all fingers. Force closure with μ = 0.5; gravity along −z of the palm with ≤ 10 N per finger and
the object's mass (the YCB objects' published masses, else mesh volume × 500 kg/m³). Also prints verify's
stability metric (`unstable_gaits`, ε ≤ 0 at the exact closest points) as a cross-check. Measures;
asserts nothing.

    python benchmarks/step_certificates.py                    # the shipped problems, svd and sd
    python benchmarks/step_certificates.py --ycb --methods svd --out /tmp/certs.json
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
from concurrent.futures import ProcessPoolExecutor

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent


def _problem_files(ycb: bool) -> list[pathlib.Path]:
    files = sorted((REPO / "problems").glob("*.yaml"))
    if ycb and (REPO.parent / "shared" / "reference" / "ycb").is_dir():
        files += sorted((HERE / "problems").glob("*.yaml"))
    return files


def measure(path: str, method: str) -> dict:
    """Plan one problem with one method and count its certified steps (never raises)."""
    from regrasp_casadi.certificates import YCB_MASSES, object_mass, step_certificates
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem
    from regrasp_casadi.verify import verify

    rec: dict = {"problem": pathlib.Path(path).stem, "method": method}
    try:
        problem = RegraspProblem.load(path)
        spec = json.dumps(problem.obj.spec)
        mass = next((m for name, m in YCB_MASSES.items() if name in spec), None)
        plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method)
        t0 = time.perf_counter()
        fc = step_certificates(plan, problem.obj, "force_closure", 0.5, hand=problem.hand)
        t1 = time.perf_counter()
        grav = step_certificates(plan, problem.obj, "gravity", 0.5, hand=problem.hand, mass=mass)
        t2 = time.perf_counter()
        report = verify(plan, problem.hand, problem.obj)
    except Exception as exc:  # recorded, not raised
        rec["status"] = f"exception: {type(exc).__name__}: {exc}"
        return rec
    gait = [k for k, s in enumerate(plan.steps) if s.kind == "gait"]
    rest = [k for k, s in enumerate(plan.steps) if s.kind != "gait"]
    rec.update(
        status=plan.status, verified=bool(report.ok), mass_kg=round(object_mass(problem.obj.mesh, mass), 4),
        gaits=len(gait), gaits_fc=sum(fc[k].ok for k in gait), gaits_gravity=sum(grav[k].ok for k in gait),
        gaits_both=sum(fc[k].ok and grav[k].ok for k in gait),
        other_steps=len(rest), other_fc=sum(fc[k].ok for k in rest),
        other_gravity=sum(grav[k].ok for k in rest),
        verify_unstable_gaits=int(report.metrics.get("unstable_gaits", -1)),
        fc_ms_per_step=round(1e3 * (t1 - t0) / len(plan.steps), 2),
        gravity_ms_per_step=round(1e3 * (t2 - t1) / len(plan.steps), 2),
        uncertified_gaits=[{"step": k, "finger": plan.steps[k].finger, "eps": round(fc[k].margin, 5),
                            "scale": round(grav[k].margin, 3)} for k in gait if not fc[k].ok],
    )
    return rec


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ycb", action="store_true", help="also the YCB pairs of benchmarks/problems")
    ap.add_argument("--methods", nargs="+", default=["svd", "sd"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=pathlib.Path, help="records as JSON")
    args = ap.parse_args(argv)
    jobs = [(str(p), m) for p in _problem_files(args.ycb) for m in args.methods]
    with ProcessPoolExecutor(args.workers) as pool:
        records = list(pool.map(measure, *zip(*jobs, strict=True)))
    print("| problem | method | status | mass (kg) | gaits | FC | gravity | both | other steps FC / gravity "
          "| verify unstable | ms/step FC, gravity |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in records:
        if "gaits" not in r:
            print(f"| {r['problem']} | {r['method']} | {r['status']} |")
            continue
        print(f"| {r['problem']} | {r['method']} | {r['status']} | {r['mass_kg']} | {r['gaits']} | "
              f"{r['gaits_fc']} | {r['gaits_gravity']} | {r['gaits_both']} | "
              f"{r['other_fc']} / {r['other_gravity']} of {r['other_steps']} | {r['verify_unstable_gaits']} | "
              f"{r['fc_ms_per_step']}, {r['gravity_ms_per_step']} |")
    done = [r for r in records if "gaits" in r]
    total = sum(r["gaits"] for r in done)
    for key in ("gaits_fc", "gaits_gravity", "gaits_both"):
        n = sum(r[key] for r in done)
        print(f"{key}: {n} of {total} gait steps certified ({100 * n / max(total, 1):.0f} %)")
    if args.out:
        args.out.write_text(json.dumps(records, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
