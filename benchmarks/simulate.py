"""Execute the shipped problems' plans in MuJoCo: held / deviating / dropped, deviations, wall time.

    python benchmarks/simulate.py                       # 4 problems × 2 methods × 4 gravity conditions
    python benchmarks/simulate.py --grip squeeze --out benchmarks/results/simulate_squeeze.json
    python benchmarks/simulate.py --gait-order stability

Gravity conditions (palm frame, m/s²; the Allegro palm faces +x, its fingers point along +z):
off (0, 0, 0), fingers up (0, 0, −9.81), palm up (−9.81, 0, 0), palm down (+9.81, 0, 0).
For each plan it also prints the number of gaits whose holding fingers lack force closure
(`stability.holding_quality` ≤ 0), which is what decides most drops. Measures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))
GRAVITY = {"off": (0.0, 0.0, 0.0), "fingers_up": (0.0, 0.0, -9.81), "palm_up": (-9.81, 0.0, 0.0),
           "palm_down": (9.81, 0.0, 0.0)}


def open_gaits(plan, hand, obj) -> set[int]:
    """Steps (indices) of the gaits whose three holding fingers are not in force closure (ε ≤ 1e-3,
    μ = 0.5)."""
    from regrasp_casadi.stability import holding_quality, torque_reference

    com, length = torque_reference(obj.mesh)
    out = set()
    for i, (before, step) in enumerate(zip(plan.steps[:-1], plan.steps[1:], strict=True), start=1):
        if step.kind != "gait":
            continue
        T = before.T_palm_object
        tips = (hand.tip_positions(before.q) - T[:3, 3]) @ T[:3, :3]
        eps = holding_quality(before.contacts_object, tips, list(plan.fingers).index(step.finger), com, length)
        if eps <= 1e-3:
            out.add(i)
    return out


def drop_step(report, plan, open_steps: set[int]) -> str:
    """"k kind finger, open|closed" for the step being executed when the object was dropped ("" if not)."""
    if not report.dropped:
        return ""
    k = next((r.step for r in report.steps if r.time >= report.drop_time - 1e-9), len(plan.steps) - 1)
    k = min(k, len(plan.steps) - 1)
    step = plan.steps[k]
    what = f"{k} {step.kind}" + (f" {step.finger}" if step.finger else "")
    return what + (", open" if k in open_steps else ", closed" if step.kind == "gait" else "")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grip", choices=("balanced", "squeeze"), default="balanced")
    ap.add_argument("--gait-order", default=None, help="planner gait_order (default: the planner's)")
    ap.add_argument("--conditions", nargs="+", choices=tuple(GRAVITY), default=list(GRAVITY))
    ap.add_argument("--out", type=pathlib.Path, default=None, help="JSON file for the records")
    args = ap.parse_args(argv)
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem
    from regrasp_casadi.simulate import SimOptions, simulate

    records = []
    print("| problem | method | open gaits | condition | status | max mm | max deg | final mm | final deg | "
          "drop step | wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for path in sorted((REPO / "problems").glob("*.yaml")):
        problem = RegraspProblem.load(path)
        for method in ("svd", "sd"):
            kw = {"method": method}
            if args.gait_order:
                kw["gait_order"] = args.gait_order
            plan = plan_regrasp(problem.grasp0, problem.grasp_goal, **kw)
            open_steps = open_gaits(plan, problem.hand, problem.obj)
            n_open = f"{len(open_steps)} / {sum(st.kind == 'gait' for st in plan.steps)}"
            for cond in args.conditions:
                t0 = time.perf_counter()
                rep = simulate(plan, problem.hand, problem.obj,
                               SimOptions(gravity_palm=GRAVITY[cond], grip=args.grip))
                last = rep.steps[-1]
                rec = dict(problem=path.stem, method=method, plan_status=plan.status, open_gaits=sorted(open_steps),
                           condition=cond, status=rep.status, max_mm=rep.max_deviation_mm,
                           max_deg=rep.max_deviation_deg, final_mm=last.deviation_mm,
                           final_deg=last.deviation_deg, wall_s=time.perf_counter() - t0,
                           sim_s=rep.sim_time, drop_time=rep.drop_time,
                           drop_step=drop_step(rep, plan, open_steps), detail=rep.detail)
                records.append(rec)
                figures = (f"{rec['max_mm']:.1f} | {rec['max_deg']:.1f} | {rec['final_mm']:.1f} | "
                           f"{rec['final_deg']:.1f} | " if not rep.dropped else
                           f"at {rep.drop_time:.2f} s | | | | {rec['drop_step']}")
                print(f"| {path.stem} | {method} | {n_open} | {cond} | {rep.status} | {figures} | "
                      f"{rec['wall_s']:.1f} |", flush=True)
    held = sum(r["status"] == "held" for r in records)
    kept = [r["final_mm"] for r in records if r["status"] != "dropped"]
    print(f"\nheld {held} / {len(records)}, dropped {sum(r['status'] == 'dropped' for r in records)}; "
          f"final deviation of the not dropped: median {np.median(kept) if kept else float('nan'):.1f} mm; "
          f"wall time median {np.median([r['wall_s'] for r in records]):.1f} s, "
          f"max {max(r['wall_s'] for r in records):.1f} s")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        from machine import machine_info

        info = machine_info(("mujoco", "numpy", "scipy", "casadi"))
        args.out.write_text(json.dumps({"machine": info, "grip": args.grip, "gait_order": args.gait_order,
                                        "records": records}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
