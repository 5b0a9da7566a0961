"""Execute plans in MuJoCo (`regrasp_casadi.simulate`): held / deviating / dropped, deviations, wall time.

    python benchmarks/simulate.py                                  # shipped problems, stability "none"
    python benchmarks/simulate.py --problems paper --pairs 1 --stability none force_closure \\
        --problem-dir ../main/benchmarks/problems --out benchmarks/results/simulate.json --plot
    python benchmarks/simulate.py --per-step                       # every step alone, by step kind

Plans: `plan_regrasp` with each method (svd, sd) and each `PlannerOptions.stability` asked for ("none":
the paper's planner; "force_closure": the certified planner of issue 14, whose every step keeps a holding
set in force closure; "gravity": one plan per condition, certified to hold the object's weight in that
condition's gravity, "force_closure" for "off"); each is judged by `verify` (its own tolerances).
Executed closed loop on the object's pose (`SimOptions.feedback`, default; ``--feedback none``: open
loop). ``--workers N`` plans and executes N (problem, stability, method) jobs in parallel. ``--mu`` and
``--min-margin`` set the certified planner's friction and least force-closure margin, ``--max-normal-force``
and ``--min-normal-force`` the gravity certificate's bounds per finger (a force reserve: `HoldingOptions.mu`,
`min_margin`, `max_normal_force`, `min_normal_force`). Each plan is executed in four
conditions (gravity in the palm frame, m/s²; the Allegro palm faces +x, its fingers point along +z):
off (0, 0, 0), fingers up (0, 0, −9.81), palm up (−9.81, 0, 0), palm down (+9.81, 0, 0), and on request
"support": per problem, gravity pressing the object onto the fingers opposite the thumb in the initial
grasp (`hand_orientation.supporting_gravity`; with ``--stability gravity`` the plan is certified for it).
Object mass:
the problem's `object.mass`, else the published mass of a YCB object (`certificates.YCB_MASSES`), else
the mesh volume × 500 kg/m³.
A case is *held* when `simulate` says "held": never more than 2 cm from the plan, at least two fingers
touching at every step end, and every step-end deviation within 5 mm / 5°.

For each plan it also counts the gaits whose three holding fingers are not in force closure ("open":
`stability.holding_quality` ≤ 1e-3 with μ = 0.5) and, for a drop, the step being executed.

``--per-step`` executes every step of every plan alone, from the plan's previous step (a fresh settle
there, then the step, then a 0.3 s hold), and reports held % per step kind: "gait_closed" (certified
holding set), "gait_open", "repose", "final", "slide". A step's deviation is then its own, not the
drift of the steps before it.

Writes the records (per case: verdict, deviations, the deviation time series every 0.05 s) and the
machine (benchmarks/machine.py) to ``--out``; ``--plot`` draws the deviation over time
(``--out`` with .png). Measures; asserts nothing. Results: benchmarks/README.md ("Simulation").
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys
import time
from collections import defaultdict

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))
GRAVITY = {"off": (0.0, 0.0, 0.0), "fingers_up": (0.0, 0.0, -9.81), "palm_up": (-9.81, 0.0, 0.0),
           "palm_down": (9.81, 0.0, 0.0), "support": None}
"""Gravity of each condition, palm frame, m/s²; "support" depends on the problem (`condition_gravity`)."""


def condition_gravity(cond: str, problem) -> tuple[float, float, float]:
    """The gravity of condition `cond` for `problem`, palm frame, m/s²: the fixed ones, or for "support"
    the direction that presses the object onto the fingers opposite the thumb in the initial grasp
    (`hand_orientation.supporting_gravity`)."""
    if GRAVITY[cond] is not None:
        return GRAVITY[cond]
    from regrasp_casadi.hand_orientation import supporting_gravity

    return tuple(float(g) for g in supporting_gravity(problem.grasp0))
SERIES_DT = 0.05  # s, the recorded deviation series


def gait_margins(plan, hand, obj) -> dict[int, float]:
    """step index -> force-closure margin ε (μ = 0.5, `stability.holding_quality`) of the fingers that
    hold the object while a gait lifts its finger."""
    from regrasp_casadi.stability import holding_quality, torque_reference

    com, length = torque_reference(obj.mesh)
    out = {}
    for i, (before, step) in enumerate(zip(plan.steps[:-1], plan.steps[1:], strict=True), start=1):
        if step.kind != "gait":
            continue
        T = before.T_palm_object
        tips = (hand.tip_positions(before.q) - T[:3, 3]) @ T[:3, :3]
        out[i] = holding_quality(before.contacts_object, tips, list(plan.fingers).index(step.finger), com,
                                 length)
    return out


def open_gaits(plan, hand, obj) -> set[int]:
    """Steps (indices) of the gaits whose three holding fingers are not in force closure (ε ≤ 1e-3,
    μ = 0.5)."""
    return {i for i, eps in gait_margins(plan, hand, obj).items() if eps <= 1e-3}


def step_class(plan, i: int, open_steps: set[int]) -> str:
    """"gait_closed" | "gait_open" | the step's kind (repose, final, slide, ...)."""
    kind = plan.steps[i].kind
    if kind == "gait":
        return "gait_open" if i in open_steps else "gait_closed"
    return kind


def drop_step(report, plan, open_steps: set[int]) -> str:
    """"k kind finger, open|closed" for the step being executed when the object was dropped ("" if not)."""
    if not report.dropped:
        return ""
    k = next((r.step for r in report.steps if r.time >= report.drop_time - 1e-9), len(plan.steps) - 1)
    k = min(k, len(plan.steps) - 1)
    step = plan.steps[k]
    what = f"{k} {step.kind}" + (f" {step.finger}" if step.finger else "")
    return what + (", open" if k in open_steps else ", closed" if step.kind == "gait" else "")


def object_mass(path: pathlib.Path) -> float | None:
    """The published mass of a YCB problem's object, kg (None: not a YCB object)."""
    from regrasp_casadi.certificates import YCB_MASSES

    text = path.read_text()
    return next((m for name, m in YCB_MASSES.items() if name in text), None)


def problem_files(which: str, pairs: int, problem_dir: pathlib.Path) -> list[pathlib.Path]:
    """The shipped problems, or the paper pairs <object>_<k> with k < `pairs`."""
    if which == "shipped":
        return sorted((REPO / "problems").glob("*.yaml"))
    return sorted(p for p in problem_dir.glob("*.yaml") if int(p.stem.rsplit("_", 1)[1]) < pairs)


def make_plan(problem, method: str, stability: str, gait_order: str | None, gravity_palm=None,
              mass: float | None = None, holding: dict | None = None):
    """(plan, verified, plan wall s) of `plan_regrasp`, with `stability` when not "none" (for "gravity":
    `gravity_palm` m/s² and the object's `mass` kg; `holding`: HoldingOptions overrides, e.g. mu)."""
    from regrasp_casadi.planner import PlannerOptions, plan_regrasp
    from regrasp_casadi.verify import verify

    kw = {"method": method, **(holding if stability != "none" and holding else {})}
    if stability == "gravity":
        kw |= {"gravity_palm": gravity_palm, **({"object_mass": mass} if mass else {})}
    if gait_order:
        kw["gait_order"] = gait_order
    if "stability" in {f.name for f in dataclasses.fields(PlannerOptions)}:
        kw["stability"] = stability
    elif stability != "none":
        raise SystemExit(f"--stability {stability}: this PlannerOptions has no 'stability' field "
                         "(the certified planner of issue 14 is not in this checkout)")
    t0 = time.perf_counter()
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, **kw)
    wall = time.perf_counter() - t0
    return plan, bool(verify(plan, problem.hand, problem.obj).ok), wall


def run_plan(plan, problem, conditions, opts_kw: dict) -> list[dict]:
    """One record per gravity condition: the whole plan executed."""
    from regrasp_casadi.simulate import SimOptions, simulate

    open_steps = open_gaits(plan, problem.hand, problem.obj)
    out = []
    for cond in conditions:
        t0 = time.perf_counter()
        rep = simulate(plan, problem.hand, problem.obj,
                       SimOptions(gravity_palm=condition_gravity(cond, problem), **opts_kw))
        last, s = rep.steps[-1], rep.series
        every = max(1, int(round(SERIES_DT / float(np.median(np.diff(s["t"]))))))
        out.append(dict(
            condition=cond, status=rep.status, max_mm=rep.max_deviation_mm, max_deg=rep.max_deviation_deg,
            max_tip_drift_mm=rep.max_tip_drift_mm,
            final_mm=last.deviation_mm, final_deg=last.deviation_deg, wall_s=time.perf_counter() - t0,
            sim_s=rep.sim_time, drop_time=rep.drop_time, drop_step=drop_step(rep, plan, open_steps),
            detail=rep.detail, object_mass=rep.object_mass,
            open_gaits=sorted(open_steps), gaits=sum(st.kind == "gait" for st in plan.steps),
            steps=len(plan.steps), series_t=np.round(s["t"][::every], 3).tolist(),
            series_mm=np.round(s["deviation_mm"][::every], 3).tolist()))
    return out


def run_steps(plan, problem, conditions, opts_kw: dict) -> list[dict]:
    """One record per (step ≥ 1, condition): the step executed alone from its planned predecessor."""
    from regrasp_casadi.simulate import SimOptions, simulate

    margins = gait_margins(plan, problem.hand, problem.obj)
    open_steps = {i for i, eps in margins.items() if eps <= 1e-3}
    out = []
    for i in range(1, len(plan.steps)):
        first = dataclasses.replace(plan.steps[i - 1], kind="initial", finger=None, path=None)
        sub = dataclasses.replace(plan, steps=(first, plan.steps[i]))
        for cond in conditions:
            kw = {**opts_kw, "hold_time": 0.3}
            rep = simulate(sub, problem.hand, problem.obj,
                           SimOptions(gravity_palm=condition_gravity(cond, problem), **kw))
            out.append(dict(step=i, kind=step_class(plan, i, open_steps), finger=plan.steps[i].finger,
                            condition=cond, status=rep.status, settle_mm=rep.steps[0].deviation_mm,
                            mm=rep.steps[1].deviation_mm, deg=rep.steps[1].deviation_deg,
                            tip_drift_mm=max(rep.steps[1].tip_drift_mm.values()),
                            grip_residual=rep.steps[1].grip_residual, margin=margins.get(i)))
    return out


def _pct(n: int, d: int) -> str:
    return f"{n} / {d} ({100.0 * n / d:.0f} %)" if d else "0 / 0"


def _median(rs: list[dict], key: str) -> str:
    return f"{np.median([r[key] for r in rs]):.1f}" if rs else "–"


def summary_table(records: list[dict]) -> str:
    """Per (stability, condition): held, within 5 mm / 5° at the end, dropped, deviations, wall time; the
    plans refused as `invalid_input` (their initial grasp alone, which may well hold) are not cases, and
    are counted on a line of their own."""
    groups = defaultdict(list)
    refused = [r for r in records if r.get("plan_status") == "invalid_input"]
    for r in records:
        if r.get("plan_status") == "invalid_input":
            continue
        groups[(r["stability"], r["condition"])].append(r)
        if r["condition"] != "off":
            groups[(r["stability"], "gravity (3 orientations)")].append(r)
    lines = ["| stability | condition | cases | held | final within 5 mm / 5° | dropped | final mm median "
             "(not dropped) | max mm median (not dropped) | max tip drift mm median (not dropped) | wall s "
             "median / max |", "|---|---|---|---|---|---|---|---|---|---|"]
    for (stab, cond), rs in sorted(groups.items()):
        kept = [r for r in rs if r["status"] != "dropped"]
        close = sum(r["status"] != "dropped" and r["final_mm"] <= 5 and r["final_deg"] <= 5 for r in rs)
        lines.append(f"| {stab} | {cond} | {len(rs)} | {_pct(sum(r['status'] == 'held' for r in rs), len(rs))} "
                     f"| {_pct(close, len(rs))} | {_pct(sum(r['status'] == 'dropped' for r in rs), len(rs))} "
                     f"| {_median(kept, 'final_mm')} | {_median(kept, 'max_mm')} | "
                     f"{_median([r for r in kept if 'max_tip_drift_mm' in r], 'max_tip_drift_mm')} | "
                     f"{np.median([r['wall_s'] for r in rs]):.1f} / "
                     f"{max(r['wall_s'] for r in rs):.1f} |")
    if refused:
        lines.append(f"\n{len(refused)} plans refused as invalid_input (initial grasp not certified), not counted.")
    return "\n".join(lines)


def step_table(records: list[dict]) -> str:
    """Per (stability, step kind, condition): held % of the steps executed alone."""
    groups = defaultdict(list)
    for r in records:
        groups[(r["stability"], r["kind"], r["condition"])].append(r)
    lines = ["| stability | step kind | condition | steps | held | dropped | step-end mm median | settle mm "
             "median | step-end tip drift mm median / p90 |", "|---|---|---|---|---|---|---|---|---|"]
    for (stab, kind, cond), rs in sorted(groups.items()):
        drift = [r["tip_drift_mm"] for r in rs if "tip_drift_mm" in r]
        drift_text = f"{np.median(drift):.2f} / {np.percentile(drift, 90):.2f}" if drift else "–"
        lines.append(f"| {stab} | {kind} | {cond} | {len(rs)} | {_pct(sum(r['status'] == 'held' for r in rs), len(rs))}"
                     f" | {_pct(sum(r['status'] == 'dropped' for r in rs), len(rs))} | "
                     f"{np.median([r['mm'] for r in rs]):.2f} | {np.median([r['settle_mm'] for r in rs]):.2f} | "
                     f"{drift_text} |")
    return "\n".join(lines)


def plot(records: list[dict], path: pathlib.Path) -> None:
    """Deviation (mm, log scale) over simulated time of every case, one panel per condition, one colour
    per stability setting; the 5 mm tolerance and the 20 mm drop distance dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    conds = [c for c in GRAVITY if any(r["condition"] == c for r in records)]
    stabs = sorted({r["stability"] for r in records})
    colors = dict(zip(stabs, ("#D55E00", "#0072B2", "#009E73"), strict=False))
    fig, axes = plt.subplots(1, len(conds), figsize=(4.2 * len(conds), 3.6), sharey=True, squeeze=False)
    for ax, cond in zip(axes[0], conds, strict=True):
        for r in (r for r in records if r["condition"] == cond):
            ax.plot(r["series_t"], np.maximum(r["series_mm"], 1e-2), color=colors[r["stability"]], lw=0.7,
                    alpha=0.6)
        for y, text in ((5.0, "5 mm"), (20.0, "drop")):
            ax.axhline(y, color="k", ls="--", lw=0.8)
            ax.text(0.02, y * 1.1, text, transform=ax.get_yaxis_transform(), fontsize=8)
        ax.set_yscale("log")
        ax.set_ylim(1e-2, 1e3)
        ax.set_title(cond.replace("_", " "))
        ax.set_xlabel("simulated time (s)")
    axes[0][0].set_ylabel("object deviation from the plan (mm)")
    for stab in stabs:
        axes[0][-1].plot([], [], color=colors[stab], label=f'stability="{stab}"')
    axes[0][-1].legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def _args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", choices=("shipped", "paper"), default="shipped")
    ap.add_argument("--problem-dir", type=pathlib.Path, default=REPO / "benchmarks" / "problems",
                    help="folder of the paper problems (their YCB meshes must resolve from there)")
    ap.add_argument("--pairs", type=int, default=5, help="paper pairs per object (the first N)")
    ap.add_argument("--methods", nargs="+", choices=("svd", "sd"), default=["svd", "sd"])
    ap.add_argument("--stability", nargs="+", default=["none"],
                    help="PlannerOptions.stability settings to compare (e.g. none force_closure gravity; "
                         "gravity: one plan per condition, certified for that condition's gravity)")
    ap.add_argument("--conditions", nargs="+", choices=tuple(GRAVITY),
                    default=[c for c in GRAVITY if c != "support"])
    ap.add_argument("--grip", choices=("balanced", "squeeze"), default="balanced")
    ap.add_argument("--gait-order", default=None, help="planner gait_order (default: the planner's)")
    ap.add_argument("--per-step", action="store_true", help="every step alone, held %% per step kind")
    ap.add_argument("--feedback", choices=("object_pose", "none"), default="object_pose",
                    help="SimOptions.feedback: closed loop on the object pose (default) or open loop")
    ap.add_argument("--workers", type=int, default=1, help="plans planned and executed in parallel")
    ap.add_argument("--mu", type=float, default=None, help="the certified planner's friction (HoldingOptions.mu)")
    ap.add_argument("--min-margin", type=float, default=None, help="its least force-closure margin ε")
    ap.add_argument("--min-normal-force", type=float, default=None,
                    help="the gravity certificate's least normal force of every holding finger, N (HoldingOptions)")
    ap.add_argument("--min-load-share", type=float, default=None,
                    help="the gravity certificate's least normal force as a share of m g / k, k holding fingers")
    ap.add_argument("--drag-only", action="store_true",
                    help="certify slides with their full kinetic drag only, not also without it (before "
                         "2026-12-02; HoldingOptions.slide_drag_range=False)")
    ap.add_argument("--no-slides", action="store_true",
                    help="the certified planner without slide steps (HoldingOptions.slide=False): a finger "
                         "whose lift is not certified waits")
    ap.add_argument("--max-normal-force", type=float, default=None,
                    help="the gravity certificate's bound on each normal force, N (HoldingOptions)")
    ap.add_argument("--out", type=pathlib.Path, default=None, help="JSON file for the records")
    ap.add_argument("--plot", action="store_true", help="deviation over time, next to --out (.png)")
    return ap.parse_args(argv)


def _job(job: tuple) -> tuple[list[dict], list[dict], list[dict]]:
    """One (problem file, stability, method): plan, verify, execute. Returns (plan heads, whole-plan
    records, per-step records). Stability "gravity": one plan per condition, certified for its gravity
    (`stability="gravity"`, `gravity_palm` of the condition; "force_closure" for "off"), executed in it."""
    from regrasp_casadi.problem import RegraspProblem

    path, stability, method, args = job
    problem = RegraspProblem.load(path)
    mass = getattr(problem, "object_mass", None) or object_mass(path)
    opts_kw = {"grip": args.grip, "feedback": args.feedback, **({"object_mass": mass} if mass else {})}
    runs = [(stability, args.conditions)]
    if stability == "gravity":
        runs = [("force_closure" if c == "off" else "gravity", [c]) for c in args.conditions]
    heads, records, step_records = [], [], []
    for kind, conditions in runs:
        holding = {k: v for k, v in (("mu", args.mu), ("min_margin", args.min_margin),
                                     ("max_normal_force", args.max_normal_force),
                                     ("min_normal_force", args.min_normal_force),
                                     ("min_load_share", args.min_load_share),
                                     ("slide_drag_range", False if args.drag_only else None),
                                     ("slide", False if args.no_slides else None)) if v is not None}
        plan, verified, plan_s = make_plan(problem, method, kind, args.gait_order,
                                           condition_gravity(conditions[0], problem), mass, holding)
        head = dict(problem=path.stem, method=method, stability=stability, plan_status=plan.status,
                    verified=verified, plan_wall_s=plan_s, feedback=args.feedback, certificate=kind)
        heads.append(head | {"steps": len(plan.steps)})
        if args.per_step:
            step_records += [head | r for r in run_steps(plan, problem, conditions, opts_kw)]
        else:
            records += [head | r for r in run_plan(plan, problem, conditions, opts_kw)]
    return heads, records, step_records


def _print_records(rs: list[dict]) -> None:
    for r in rs:
        figures = (f"{r['max_mm']:.1f} | {r['final_mm']:.1f} | {r['final_deg']:.1f}"
                   if r["status"] != "dropped" else f"drop at {r['drop_time']:.2f} s | {r['drop_step']} |")
        print(f"| {r['problem']} | {r['method']} | {r['stability']} | {r['plan_status']}"
              f"{'' if r['verified'] else ' (!v)'} | {len(r['open_gaits'])} / {r['gaits']} | {r['condition']} | "
              f"{r['status']} | {figures} | {r['wall_s']:.1f} |", flush=True)


def main(argv: list[str] | None = None) -> int:
    args = _args(argv)
    from concurrent.futures import ProcessPoolExecutor

    from machine import machine_info

    info = machine_info(("mujoco", "numpy", "scipy", "casadi"))  # at the start: the commit that runs
    jobs = [(path, stability, method, args) for path in problem_files(args.problems, args.pairs, args.problem_dir)
            for stability in args.stability for method in args.methods]
    records, step_records, plans = [], [], []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for heads, rs, step_rs in pool.map(_job, jobs):
            plans += heads
            records += rs
            step_records += step_rs
            _print_records(rs)
            if args.per_step:
                print(f"{heads[0]['problem']} {heads[0]['method']} {heads[0]['stability']}: "
                      f"{[h['steps'] for h in heads]} steps", flush=True)
            _save(args, info, plans, records, step_records, complete=False)
    print()
    print(step_table(step_records) if args.per_step else summary_table(records))
    _save(args, info, plans, records, step_records, complete=True)
    if args.out and args.plot and records:
        plot(records, args.out.with_suffix(".png"))
    return 0


def _save(args, info: dict, plans: list, records: list, step_records: list, complete: bool) -> None:
    """Write the records so far to ``--out`` (``complete``: the run has ended)."""
    if not args.out:
        return
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": info, "args": {k: str(v) for k, v in vars(args).items()},
                                    "complete": complete, "plans": plans, "records": records,
                                    "step_records": step_records}, indent=1))


if __name__ == "__main__":
    sys.exit(main())
