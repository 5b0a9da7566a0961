"""Benchmark: what the trajectories (issue 15) cost and how many pass, on every shipped problem.

For each problem and method: the warm planning time (NLPs cached) with `trajectories=False` and with
`trajectories=True` (median of `--repeats` alternating runs, wall and CPU time), the time of
`attach_trajectories` alone, and the paths: how many, how many the trajectory code flags (by kind and
reason), and an independent sampled check of every path with the exact mesh distance (exact within 1 mm
of each threshold, `near_signed_distance`), every 2 ms of the motion (at 1 rad/s no point of the hand
moves more than ≈ 0.3 mm between samples):

* gaits: during the transit every sphere of the moving finger ≥ β − 0.05 mm from the object; during
  lift-off and touch-down its non-tip spheres ≥ −0.05 mm and its tip ≥ −0.5 mm (no penetration);
* reposings and final moves: every tip within 0.5 mm of the surface, every contact within 1 mm of where
  it was on the object at the step before, every non-tip sphere ≥ −0.05 mm.

Prints a markdown table; writes benchmarks/results/trajectories.json with the machine description.
Measures; asserts nothing (target of issue 15: trajectories add at most 50 % to the median plan time).

    python benchmarks/trajectories.py [--repeats 3] [--methods svd sd] [--problems box_rotate ...] [--ycb]

Run of commit 44bb686 (2026-12-01, after the self-collision constraint regenerated the problems; AMD
EPYC, 2 cores shared with other jobs: 1-minute load 5-6; Python 3.11.7, CasADi 3.8.2, numpy 2.4.6,
trimesh 5.2.0), `--repeats 3`:

| problem | method | plan s without → with (wall) | CPU s without → with | attach s | paths (g/r/f) | flagged | sampled check fails | knots | motion s |
|---|---|---|---|---|---|---|---|---|---|
| bottle_regrasp | svd | 3.76 → 4.70 | 2.46 → 3.11 | 0.98 | 23/7/6 | 1 (gait transit) | 0 | 1715 | 19.3 |
| bottle_regrasp | sd | 4.54 → 5.06 | 2.94 → 3.35 | 0.73 | 26/7/1 | 8 (6 gait transit, 2 gait lift-off) | 0 | 1448 | 15.3 |
| box_rotate | svd | 1.75 → 2.47 | 0.88 → 1.20 | 0.42 | 16/3/3 | 0 | 0 | 885 | 8.8 |
| box_rotate | sd | 1.96 → 2.51 | 0.98 → 1.24 | 0.42 | 16/3/3 | 0 | 0 | 977 | 11.1 |
| box_shift | svd | 1.34 → 1.65 | 0.66 → 0.84 | 0.35 | 16/3/1 | 0 | 0 | 704 | 6.4 |
| box_shift | sd | 2.16 → 2.06 | 1.08 → 1.29 | 0.43 | 16/3/2 | 0 | 0 | 830 | 7.9 |
| cylinder_slide | svd | 1.34 → 1.81 | 0.89 → 1.19 | 0.53 | 19/4/2 | 4 (2 gait transit, 2 gait lift-off) | 0 | 1037 | 10.7 |
| cylinder_slide | sd | 2.92 → 3.59 | 1.93 → 2.37 | 0.69 | 21/5/2 | 4 (gait transit) | 0 | 1239 | 12.7 |

Median time per plan: 2.06 s without, 2.49 s with trajectories (+21 %, wall); 1.03 → 1.27 s (+23 %,
CPU). Paths: 208; flagged by the trajectory code: 17 — 13 transits or touch-downs that bring the moving
finger within 1 mm of (5 of them into, by ≤ 0.53 mm) a neighbouring finger, 4 lift-offs the joint
limits lean more than 45° off the normal; failing the sampled check (object only): 0. Before the
self-collision constraint (commit 34b3b7a, same machine): +22 % (1.50 → 1.83 s), 226 paths, 7 flagged
(joint limits), 0 failing. ("attach s" is wall time inside the loaded run.)

verify's motion rows (`regrasp_casadi.verify_motion`) on the plans with trajectories, run of e967073 with
`--repeats 0` (one plan each; times from `plan.timing`, NLP builds left out; 2 cores, 1-minute load
17-21 from other jobs, so wall times are 3-5x the unloaded ones), results/trajectories.json:

* shipped problems (8 plans): 8 converged, 7 verified, 7 pass the motion rows; the one failure is
  bottle_regrasp sd, step 24 (gait of the thumb, touch-down, t = 0.201 s): palm_link and link_15.0
  (thumb) spheres overlap by 0.01 mm (the trajectory code flags the same transit). Before the leaning
  lift-offs (b2bee3b, `--repeats 1`) 5 of 8 passed: 8 self-collision violations of ≤ 0.53 mm in
  bottle_regrasp sd and cylinder_slide svd/sd. Median plan time 12.88 → 17.91 s with trajectories
  (+39 % wall, under load; the earlier `--repeats 1` run: +24 % wall, +25 % CPU). verify per plan:
  median 6.5 s, of which the motion rows 4.2 s (4,327 samples).
* paper benchmark (25 YCB pairs × 2 methods, problems regenerated with the self-collision rule): not
  completed — stopped after 7 plans at the deadline (banana_0-3 svd, banana_0-2 sd): 6 converged
  (banana_2 sd: solver_failure), 5 verified; banana_0 fails with both methods: during the final move
  (step 36 for svd, t = 0.413 s) a palm sphere (palm_link#11) goes 0.97 mm into the banana (the
  trajectory code flags that path too: 0.965 mm). verify per YCB plan 30-146 s under load (motion rows
  9-79 s, 3,700-7,800 samples; the exact mesh distance of the holding tips dominates).
"""

from __future__ import annotations

import argparse
import collections
import json
import pathlib
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from machine import REPO, machine_info  # noqa: E402

from regrasp_casadi.motion import sample_knots  # noqa: E402
from regrasp_casadi.planner import plan_regrasp  # noqa: E402
from regrasp_casadi.problem import RegraspProblem  # noqa: E402
from regrasp_casadi.verify import verify  # noqa: E402

RESULTS = REPO / "benchmarks" / "results" / "trajectories.json"
DT = 0.002
SLACK = 5e-5


def _to_object(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.einsum("kij,ksi->ksj", T[:, :3, :3], p - T[:, None, :3, 3])


def sampled_check(plan, hand, obj, beta: float) -> list[str]:
    """Independent check of every path sampled every `DT` s; one line per failing step."""
    failures = []
    radii = hand.sphere_radii(None, include_tip=True)
    by_label = {s.label: s for s in hand.spheres}
    spheres = [by_label[label] for label in hand.sphere_labels(None, include_tip=True)]
    fingers = [s.finger for s in spheres]
    is_tip = np.array([s.is_tip for s in spheres])
    for i, (prev, step) in enumerate(zip(plan.steps[:-1], plan.steps[1:], strict=True), start=1):
        path = step.path
        t, q, T = sample_knots(path.t, path.q, path.T_palm_object, DT)
        centres = _to_object(T, np.stack([hand.sphere_centers(x, None, include_tip=True) for x in q]))
        if step.kind == "gait":
            mine = np.array([f == step.finger for f in fingers])
            r = np.tile(radii[mine], len(t))
            d = (obj.near_signed_distance(centres[:, mine].reshape(-1, 3), r + beta + 1e-3) - r).reshape(len(t), -1)
            phase = np.array(path.phases)[np.clip(np.searchsorted(path.t, t, side="right") - 1, 0,
                                                  len(path.phases) - 1)]
            transit = phase == "transit"
            tip = is_tip[mine]
            bad = []
            if transit.any() and np.min(d[transit]) < beta - SLACK:
                bad.append(f"transit clearance {np.min(d[transit]) * 1e3:.3f} mm")
            if (~transit).any() and np.min(d[~transit][:, ~tip], initial=np.inf) < -SLACK:
                bad.append(f"non-tip sphere {np.min(d[~transit][:, ~tip]) * 1e3:.3f} mm")
            if (~transit).any() and np.min(d[~transit][:, tip]) < -5e-4:
                bad.append(f"tip {np.min(d[~transit][:, tip]) * 1e3:.3f} mm")
        else:
            tips = centres[:, is_tip]
            closest, sd = obj.closest_points(tips.reshape(-1, 3))
            surface = np.max(np.abs(sd - np.tile(radii[is_tip], len(t))))
            slip = np.max(np.linalg.norm(closest.reshape(tips.shape) - prev.contacts_object[None], axis=2))
            r = np.tile(radii[~is_tip], len(t))
            others = obj.near_signed_distance(centres[:, ~is_tip].reshape(-1, 3), r + 1e-3) - r
            bad = [text for text, failed in ((f"surface {surface * 1e3:.3f} mm", surface > 5e-4),
                                             (f"slip {slip * 1e3:.3f} mm", slip > 1e-3),
                                             (f"non-tip sphere {np.min(others) * 1e3:.3f} mm",
                                              np.min(others) < -SLACK)) if failed]
        if bad:
            failures.append(f"step {i} {step.kind}: " + ", ".join(bad))
    return failures


def _timed_plan(problem, method: str, trajectories: bool):
    c0, w0 = time.process_time(), time.perf_counter()
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method=method, trajectories=trajectories)
    return plan, time.perf_counter() - w0, time.process_time() - c0


def run(path: pathlib.Path, method: str, repeats: int) -> dict:
    """One record; `repeats` 0: a single plan with trajectories, its time without them = its
    `timing["total"]` − `timing["trajectories"]` (they are attached after planning), NLP builds
    (`timing["build"]`) left out of both (CPU columns: the process CPU time of that plan)."""
    problem = RegraspProblem.load(path)
    runs = {False: [], True: []}
    plan = None
    if repeats == 0:
        plan, wall, cpu = _timed_plan(problem, method, True)
        tm = plan.timing
        build, attach = tm.get("build", 0.0), tm.get("trajectories", 0.0)
        runs[True].append((tm["total"] - build, cpu, attach))
        runs[False].append((tm["total"] - build - attach, cpu * (1 - attach / max(wall, 1e-9)), 0.0))
    else:
        _timed_plan(problem, method, False)  # builds the NLPs
    for _ in range(repeats):
        for flag in (False, True):
            p, wall, cpu = _timed_plan(problem, method, flag)
            runs[flag].append((wall, cpu, p.timing.get("trajectories", 0.0)))
            plan = p if flag else plan
    flagged = collections.Counter()
    for step in plan.steps[1:]:
        if not step.path.ok:
            flagged[(step.kind, step.path.detail.split(":")[0].split(" ")[0])] += 1
    kinds = collections.Counter(s.kind for s in plan.steps[1:])
    failures = sampled_check(plan, problem.hand, problem.obj, plan.options["trajectory"]["beta"])
    v0 = time.perf_counter()
    report = verify(plan, problem.hand, problem.obj)
    verify_s = time.perf_counter() - v0
    by_check = collections.Counter(v.check for v in report.violations)
    med = {flag: [statistics.median(r[k] for r in runs[flag]) for k in range(3)] for flag in runs}
    return {"problem": path.stem, "method": method, "status": plan.status,
            "wall_without": med[False][0], "wall_with": med[True][0], "cpu_without": med[False][1],
            "cpu_with": med[True][1], "attach": med[True][2], "paths": dict(kinds),
            "flagged": {f"{k[0]} {k[1]}": v for k, v in flagged.items()},
            "n_flagged": sum(flagged.values()), "n_paths": len(plan.steps) - 1,
            "knots": sum(len(s.path.t) for s in plan.steps[1:]),
            "duration_s": sum(s.path.duration for s in plan.steps[1:]),
            "sampled_failures": failures, "verified": report.ok,
            "violations": dict(by_check), "motion_ok": not any(c.startswith("motion_") for c in by_check),
            "motion_samples": report.metrics.get("motion_samples", 0),
            "motion_seconds": report.metrics.get("motion_seconds", 0.0), "verify_s": verify_s,
            "first_violations": [f"step {v.step} {v.check} [{v.who}]: {v.message}" for v in report.violations[:3]]}


def _print_verify(records: list[dict]) -> None:
    """verify's verdict on the plans with trajectories: converged, verified, passing the motion rows,
    violations by check, time of verify and of its motion rows."""
    conv = [r for r in records if r["status"] == "converged"]
    kinds = collections.Counter()
    for r in records:
        kinds.update(r["violations"])
    print(f"plans: {len(records)}, converged {len(conv)} ({100 * len(conv) / max(1, len(records)):.0f} %); "
          f"verified {sum(r['verified'] for r in records)} (converged and verified "
          f"{sum(r['verified'] for r in conv)}); motion rows pass on {sum(r['motion_ok'] for r in records)} "
          f"(converged: {sum(r['motion_ok'] for r in conv)})")
    print(f"violations by check: {dict(kinds) or 'none'}")
    print(f"verify per plan: median {statistics.median(r['verify_s'] for r in records):.2f} s, of which the "
          f"motion rows {statistics.median(r['motion_seconds'] for r in records):.2f} s "
          f"({statistics.median(r['motion_samples'] for r in records):.0f} samples)")
    for r in records:
        for line in r["first_violations"]:
            print(f"  {r['problem']} {r['method']} ({r['status']}): {line[:240]}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3,
                    help="alternating runs without/with trajectories; 0: one plan, times from plan.timing")
    ap.add_argument("--methods", nargs="+", default=["svd", "sd"])
    ap.add_argument("--problems", nargs="+", help="problem names (default: every problems/*.yaml)")
    ap.add_argument("--ycb", action="store_true",
                    help="also the paper's YCB pairs (benchmarks/problems/*.yaml; needs ../shared/reference)")
    ap.add_argument("--only-ycb", action="store_true", help="only the YCB pairs (with --ycb)")
    ap.add_argument("--out", type=pathlib.Path, default=RESULTS, help="results JSON")
    args = ap.parse_args(argv)
    files = [] if args.only_ycb else sorted((REPO / "problems").glob("*.yaml"))
    if args.ycb:
        files += sorted((REPO / "benchmarks" / "problems").glob("*.yaml"))
    if args.problems:
        files = [f for f in files if f.stem in args.problems]
    records = []
    for f in files:
        for m in args.methods:
            records.append(run(f, m, args.repeats))
            r = records[-1]
            print(f"# {r['problem']} {r['method']}: {r['status']}, verified {r['verified']}, motion rows "
                  f"{'pass' if r['motion_ok'] else 'FAIL'}, {r['wall_without']:.2f} -> {r['wall_with']:.2f} s, "
                  f"verify {r['verify_s']:.2f} s (motion {r['motion_seconds']:.2f} s, {r['motion_samples']} "
                  f"samples), violations {r['violations']}", flush=True)
    print("| problem | method | plan s without → with (wall) | CPU s without → with | attach s | paths "
          "(g/r/f) | flagged | sampled check fails | knots | motion s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in records:
        p = r["paths"]
        print(f"| {r['problem']} | {r['method']} | {r['wall_without']:.2f} → {r['wall_with']:.2f} | "
              f"{r['cpu_without']:.2f} → {r['cpu_with']:.2f} | {r['attach']:.2f} | "
              f"{p.get('gait', 0)}/{p.get('repose', 0)}/{p.get('final', 0)} | "
              f"{r['n_flagged']} {r['flagged'] or ''} | {len(r['sampled_failures'])} | {r['knots']} | "
              f"{r['duration_s']:.1f} |")
    for key in ("wall", "cpu"):
        without = statistics.median(r[f"{key}_without"] for r in records)
        with_ = statistics.median(r[f"{key}_with"] for r in records)
        print(f"median {key} time per plan: {without:.2f} s without, {with_:.2f} s with trajectories "
              f"(+{100 * (with_ / without - 1):.0f} %)")
    n_paths = sum(r["n_paths"] for r in records)
    print(f"paths: {n_paths}, flagged by the trajectory code: {sum(r['n_flagged'] for r in records)}, "
          f"failing the sampled check: {sum(len(r['sampled_failures']) for r in records)}")
    for r in records:
        for line in r["sampled_failures"]:
            print(f"  {r['problem']} {r['method']}: {line}")
    _print_verify(records)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": machine_info(), "records": records}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
