"""Smooth signed distance vs the exact mesh distance, on generated objects and the five YCB meshes.

For each object: convex decomposition time (coacd, into a fresh cache unless --use-cache), pieces and
planes, and, at points sampled on the surface and in a 3 cm shell inside and outside (along the surface
normal), the error |smooth − exact| (quantiles 50/95/99/max, mm), the hard plane bound's surface error
(τ → 0), sign errors (all, and those more than 1 mm from the surface), the largest excess of the smooth
value over the exact distance outside (to compare with the stated bias bound τ·log k_max), and the
evaluation time of the CasADi function (value; value + gradient) per point: through a Python call with
one point, and inside CasADi's VM (`map` over 1000 points, per point).

Per object it also reports the decomposition: genus, how far the mesh is from convex (hull volume excess
and the largest distance of 5000 hull-surface samples to the mesh: a shell within 1 mm and 2 % is one
piece, its hull, `convex.is_near_convex`), pieces, planes, build time (coacd under its time cap) and the
*over-cover* error, how far the pieces' union reaches beyond the mesh (`convex.decomposition_error`:
where hulls bridge a concavity or fill a cavity). `--sweep T1 T2 ...` decomposes each non-convex
generated object at those coacd thresholds and picks the first threshold whose successor improves the
over-cover p99 by less than 25 % (results/geometry_sweep.json). `--sweep-pieces N1 N2 ...` does the same
over coacd's piece cap (`piece_count.choose_piece_count`: the cap where the over-cover p99 stops
improving by 25 % or 0.2 mm), reporting pieces, planes, error and time per cap.

Piece-cap sweep of the cup (`piece_count.choose_piece_count(cup_mesh(), (8, 16, 32, 64),
max_seconds=240)`, the call `--sweep-pieces 8 16 32 64` makes; commit 91c3aa1, load ≈ 17 on 2 shared
cores): cap 8 → 8 pieces / 1,242 planes, over-cover p99 / max 7.37 / 8.96 mm, 152 s; cap 16 → 16 / 2,323,
3.78 / 4.01 mm, 144 s; cap 32 → 28 / 3,860, 1.24 / 1.61 mm, 121 s; cap 64 → 28 pieces again (coacd
needs no more), so the chosen cap is 32. Not yet the primitives' default: the grasp NLP is too slow on
3,860 planes (see benchmarks/README.md, `objects.py`).

Thin-walled containers since commit 444f98a: `ObjectModel.bowl/cup/mug` default to convex pieces by
construction (`shapes.bowl_pieces` …: bands of the profile × sectors about the axis, hulls of mesh
vertices, chords within `objects.WALL_TOLERANCE` = 1.5 mm per direction; the fewest face planes within
that tolerance, `piece_count.fewest_planes_piece`), no coacd: bowl 49 pieces / 540 planes, over-cover
p99 / max 2.32 / 2.43 mm; cup 17 / 142, 0.68 / 0.69 mm; mug 24 / 234, 0.69 / 1.17 mm; built in 0.5–2.0 s;
surface p99 2.31 / 0.77 / 0.90 mm (`--objects bowl cup mug --no-ycb`, commit 137ecb5,
results/geometry_walls.json). Without edge planes the smooth value up to 3 cm off the surface is worse:
outside p99 / max 5.93 / 8.79, 5.66 / 9.70, 6.96 / 19.88 mm, sign errors beyond 1 mm 42 / 0 / 6 of 6000
(a lower bound off the rims' corners and across the cavity; the NLPs correct it with exact offsets).
The table below is coacd's (`decomposition="coacd"`).

Targets: surface |smooth − exact| ≤ 0.5 mm for 99 % of samples; no sign error beyond 1 mm; outside,
smooth − exact ≤ τ·log k_max; one distance+gradient evaluation ≤ 20 µs.

    python benchmarks/geometry.py [--n 3000] [--thresholds 0.05 0.02] [--no-ycb] [--use-cache]
                                  [--objects bowl cup ...] [--sweep 0.1 0.05 0.03 0.02 --max-seconds 240]

Writes benchmarks/results/geometry.json (with CPU, python, casadi, coacd, trimesh versions, git commit).

Decomposition (commit d778465, AMD EPYC, 2 cores shared with ~6 other jobs (load 8–12), so times are
~3–5× an idle machine's; coacd 1.0.14, threshold 0.05, ≤ 16 pieces):

| object | genus | hull excess % / dist mm | pieces | planes | build s | over-cover p99/max mm | surface p99/max mm |
|---|---|---|---|---|---|---|---|
| box, cylinder, sphere (7 cm), capsule | 0 | 0 / 0 (hull) | 1 | 62–320 | < 0.1 | 0 | 0.14–1.47 / 0.28–1.72 |
| bottle / banana | 0 | 9.4 / 9.2, 23.8 / 14.9 | 2 / 3 | 320 / 480 | 2.0 / 3.6 | 0.03 / 1.50 | 0.32 / 1.58 |
| bowl (4 mm wall) | 0 | 447 / 54.6 | 16 | 2560 | 66.7 | 7.64 / 8.99 | 3.92 / 3.97 |
| cup / mug (4 mm walls) | 0 / 1 | 349 / 34.2, 382 / 33.0 | 16 / 16 | 2323 / 2526 | 40.0 / 30.0 | 3.78 / 2.94 | 3.69 / 3.02 |
| flat tool (20 × 4.5 × 1.5 cm) | 0 | 16.7 / 9.2 | 2 | 269 | 1.1 | 0.00 | 0.32 / 0.47 |
| holed box (3 tunnels of 4 mm) | 3 | 0.8 / 1.8 | 16 | 1068 | 71.2 | 0.00 / 1.51 | 4.28 / 6.45 |
| YCB chips can / sugar box / mustard / banana / bleach | 0 | 2.0 / 3.0, 3.6 / 2.2, 14 / 8.6, 55 / 33, 9.8 / 8.5 | 1 / 2 / 4 / 4 / 3 | 83–640 | 1.3–15 | 1.6–4.8 | 1.7–4.2 |

Sweep (thresholds 0.1 / 0.05 / 0.03 / 0.02): the chosen threshold is 0.05 or coarser for every generated
object (bottle, cup, bowl 0.1; banana, mug, flat tool 0.05; holed box 0.1): finer thresholds do not
reduce the over-cover error once coacd's 16-piece cap binds (bowl 9.8 → 7.6 → 8.3 → 8.1 mm, cup
3.7 → 3.8 → 2.7 → 3.3 mm), so the primitives keep the default 0.05. The thin-walled shapes are limited
by the piece cap, not the threshold. On the holed box coacd at 0.03 and 0.02 ran out of the 240 s cap
(180 s, then 60 s with `convex.FALLBACK_COACD`) and fell back to the hull. Choosing the threshold this
way at load time is not the default: each threshold tried is another full coacd run (30–120 s for
these objects on this machine, 10–35 s for YCB), so it is a benchmark step whose result sets defaults.

Representative result (n = 3000, τ = 0.2 mm, ≤ 64 face planes + ≤ 96 edge/vertex planes per piece; commit
b591024, Intel Xeon, 2 shared cores, python 3.11.7, casadi 3.8.2, coacd 1.0.14, trimesh 5.2.0; timings
are noisy on the shared machine). The NLPs do not evaluate these whole models: they pass the ≤ 32 planes
near each fingertip as parameters (`ObjectModel.local_planes`) and use ≤ 16 face planes per piece for
the other spheres, so the per-point costs below are those of the full model only.

| object | pieces | planes | surface p99 / max mm | outside p99 / max mm | sign err (>1 mm) | f+grad VM µs (SX) |
|---|---|---|---|---|---|---|
| box / cylinder | 1 | 62 / 130 | 0.22 / 0.41, 0.14 / 0.28 | 0.01 / 0.18, 0.09 / 0.12 | 3 (0), 9 (0) | 4.6 / 14 |
| sphere (64 / 320 planes) | 1 | 64 / 320 | 1.47 / 1.72, 0.29 / 0.35 | 2.67 / 3.34, 0.18 / 0.29 | 61 (8) / 14 (0) | 7.4 / 24 |
| capsule / bottle / banana (generated) | 1 / 2 / 3 | 144 / 320 / 480 | 0.64 / 1.06, 0.32 / 0.52, 1.58 / 1.74 | 1.56 / 2.60, 0.61 / 0.85, 1.68 / 1.97 | 21 (0), 10 (0), 23 (0) | 12 / 28 / 49 |
| YCB, threshold 0.05 | 1–4 | 83–640 | 1.7–4.2 / 1.9–6.1 | 1.8–5.2 / 2.4–6.0 | 11–114 (0–63) | 8–76 |
| YCB, threshold 0.02 | 9–16 | 1440–2560 | 0.43–1.30 / 0.62–1.94 | 0.55–1.39 / 1.7–3.0 | 4–28 (0) | 161–290 |

Reading: capping pieces at 64 face planes costs almost nothing (all-planes hull error ≈ capped error); the
surface error on YCB is the convex decomposition's (hulls bridge concavities), as DESIGN.md's table says;
the edge/vertex planes cut the error 14 mm off the surface (where fingertip centres are) near edges, e.g.
on the box from 3.96 mm to 0.35 mm (p99).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import tempfile
import time

import casadi as ca
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from machine import machine_info  # noqa: E402

from regrasp_casadi import convex, signed_distance  # noqa: E402
from regrasp_casadi.mesh_repair import genus, shells  # noqa: E402
from regrasp_casadi.objects import ObjectModel  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
YCB = ROOT.parent / "shared" / "reference" / "ycb"
YCB_NAMES = ["001_chips_can", "004_sugar_box", "006_mustard_bottle", "011_banana", "021_bleach_cleanser"]


def timing(obj: ObjectModel) -> dict:
    f = obj.signed_distance_function()
    p = ca.SX.sym("p", 3)
    d = f(p)
    fg = ca.Function("fg", [p], [d, ca.gradient(d, p)])
    x = np.array([0.01, 0.02, 0.03])
    out = {}
    for name, fun in (("value", f), ("value_grad", fg)):
        n = 2000
        t0 = time.perf_counter()
        for _ in range(n):
            fun(x)
        out[f"{name}_call_us"] = (time.perf_counter() - t0) / n * 1e6
        k = 1000
        fm = fun.map(k)
        X = np.random.default_rng(0).uniform(-0.05, 0.05, (3, k))
        fm(X)
        t0 = time.perf_counter()
        for _ in range(10):
            fm(X)
        out[f"{name}_vm_us"] = (time.perf_counter() - t0) / 10 / k * 1e6
    out["n_instructions_value_grad"] = int(fg.n_instructions())
    pm = ca.MX.sym("p", 3)
    dm = obj.signed_distance_function(symbolic="MX")(pm)
    fgm = ca.Function("fgm", [pm], [dm, ca.gradient(dm, pm)]).map(1000)
    X = np.random.default_rng(0).uniform(-0.05, 0.05, (3, 1000))
    fgm(X)
    t0 = time.perf_counter()
    for _ in range(10):
        fgm(X)
    out["value_grad_vm_mx_us"] = (time.perf_counter() - t0) / 10 / 1000 * 1e6
    return out


def quant(e: np.ndarray) -> dict:
    if len(e) == 0:
        return {"n": 0}
    q = np.quantile(e, [0.5, 0.95, 0.99])
    return {"n": int(len(e)), "p50_mm": q[0] * 1e3, "p95_mm": q[1] * 1e3, "p99_mm": q[2] * 1e3,
            "max_mm": float(e.max()) * 1e3}


def evaluate(name: str, make, n: int) -> dict:
    t0 = time.perf_counter()
    n_before = convex.decomposition_count()
    obj = make()
    build = time.perf_counter() - t0
    decomposed = convex.decomposition_count() > n_before
    hull_excess, hull_dist = convex.hull_error(obj.mesh)
    over_p99, over_max = convex.decomposition_error(obj.mesh, obj.pieces)
    rng = np.random.default_rng(0)
    pts, normals = obj.sample_surface(n, seed=0)
    shell_out = pts + normals * rng.uniform(0.0, 0.03, (n, 1))
    shell_in = pts - normals * rng.uniform(0.0, 0.03, (n, 1))
    shell = np.concatenate([shell_out, shell_in])
    t0 = time.perf_counter()
    ex_surf = obj.exact_signed_distance(pts)
    ex_shell = obj.exact_signed_distance(shell)
    exact_time = (time.perf_counter() - t0) / (3 * n)
    sm_surf = obj.signed_distance(pts)
    sm_shell = obj.signed_distance(shell)
    hard_surf = np.stack([pc.hard_distance(pts) for pc in obj.pieces]).min(axis=0)
    # the same pieces with every hull facet (no plane cap): separates decomposition and simplification
    full = [convex.simplify_piece(pc.vertices, 10**9) for pc in obj.pieces]
    hull_surf = np.stack([pc.hard_distance(pts) for pc in full]).min(axis=0)
    out_mask, in_mask = ex_shell > 0, ex_shell < 0
    sign_err = np.sign(sm_shell) != np.sign(ex_shell)
    k_max = max(len(pc.offsets) for pc in obj.pieces)
    res = {
        "object": name,
        "faces": int(len(obj.mesh.faces)),
        "pieces": len(obj.pieces),
        "planes": int(sum(len(pc.offsets) for pc in obj.pieces)),
        "k_max": int(k_max),
        "build_s": build,
        "decomposed": bool(decomposed),
        "genus": int(genus(obj.mesh)) if len(shells(obj.mesh)) == 1 else None,
        "hull_volume_excess": hull_excess,
        "hull_distance_mm": hull_dist * 1e3,
        "near_convex": bool(convex.is_near_convex(obj.mesh)),
        "overcover_p99_mm": over_p99 * 1e3,
        "overcover_max_mm": over_max * 1e3,
        "tau_m": signed_distance.DEFAULT_TAU,
        "bias_bound_mm": obj.bias_bound * 1e3,
        "exact_self_distance_max_m": float(np.abs(ex_surf).max()),
        "exact_time_per_point_us": exact_time * 1e6,
        "surface": quant(np.abs(sm_surf - ex_surf)),
        "surface_hard": quant(np.abs(hard_surf - ex_surf)),
        "surface_hull_all_planes": quant(np.abs(hull_surf - ex_surf)),
        "hull_planes_all": int(sum(len(pc.offsets) for pc in full)),
        "inside": quant(np.abs(sm_shell - ex_shell)[in_mask]),
        "outside": quant(np.abs(sm_shell - ex_shell)[out_mask]),
        "outside_max_excess_mm": float((sm_shell - ex_shell)[out_mask].max()) * 1e3,
        "sign_errors": int(sign_err.sum()),
        "sign_errors_beyond_1mm": int((sign_err & (np.abs(ex_shell) > 1e-3)).sum()),
        "sign_error_max_depth_mm": float(np.abs(ex_shell[sign_err]).max() * 1e3) if sign_err.any() else 0.0,
    }
    res.update(timing(obj))
    return res


GENERATED = {
    "box": ObjectModel.box,
    "cylinder": ObjectModel.cylinder,
    "sphere": ObjectModel.sphere,  # 7 cm across (a baseball)
    "sphere (320 planes)": lambda: ObjectModel.sphere(max_planes_per_piece=320),
    "capsule": ObjectModel.capsule,
    "bottle": ObjectModel.bottle,
    "banana": ObjectModel.banana,
    "bowl": ObjectModel.bowl,
    "cup": ObjectModel.cup,
    "mug": ObjectModel.mug,
    "flat_tool": ObjectModel.flat_tool,
    "holed_box": ObjectModel.holed_box,
}


def sweep(name: str, mesh, thresholds: list[float], max_seconds: float) -> dict:
    """coacd at each threshold (coarse to fine): pieces, time and over-cover error; the chosen threshold is
    the first whose successor improves the over-cover p99 by less than 25 % (or the last one)."""
    rows = []
    for th in sorted(thresholds, reverse=True):
        t0 = time.perf_counter()
        verts = convex._decompose(mesh, th, convex.DEFAULT_MAX_PIECES, max_seconds=max_seconds,
                                  desc=f"{name} t={th:g}")
        dt = time.perf_counter() - t0
        pieces = [convex.simplify_piece(v) for v in verts]
        p99, worst = convex.decomposition_error(mesh, pieces)
        rows.append({"threshold": th, "pieces": len(pieces), "time_s": dt, "overcover_p99_mm": p99 * 1e3,
                     "overcover_max_mm": worst * 1e3})
        print(f"  sweep {name} t={th:g}: {len(pieces)} pieces, {dt:.1f} s, over-cover p99 {p99 * 1e3:.2f} mm",
              file=sys.stderr, flush=True)
    chosen = rows[-1]["threshold"]
    for a, b in zip(rows, rows[1:], strict=False):
        if b["overcover_p99_mm"] >= 0.75 * a["overcover_p99_mm"]:
            chosen = a["threshold"]
            break
    return {"object": name, "rows": rows, "chosen_threshold": chosen}


def piece_sweep(name: str, mesh, counts: list[int], max_seconds: float) -> dict:
    """`piece_count.choose_piece_count` at coacd caps `counts`: pieces, planes, over-cover error and time
    per cap, and the cap where the error stops improving."""
    from regrasp_casadi.piece_count import choose_piece_count

    choice = choose_piece_count(mesh, counts, max_seconds=max_seconds, name=name)
    rows = [{"cap": r.cap, "pieces": r.pieces, "planes": r.planes, "overcover_p99_mm": r.p99_m * 1e3,
             "overcover_max_mm": r.max_m * 1e3, "time_s": r.seconds} for r in choice.rows]
    for r in rows:
        print(f"  pieces {name} cap {r['cap']}: {r['pieces']} pieces, {r['planes']} planes, "
              f"{r['time_s']:.1f} s, over-cover p99 {r['overcover_p99_mm']:.2f} mm", file=sys.stderr, flush=True)
    return {"object": name, "rows": rows, "chosen_cap": choice.chosen}


def _cases(args) -> list[tuple[str, object]]:
    """(name, constructor) of the generated objects and YCB meshes asked for."""
    cases = [(k, v) for k, v in GENERATED.items() if not args.objects or k in args.objects]
    if args.no_ycb:
        return cases
    for nm in YCB_NAMES:
        path = YCB / nm / "mesh.obj"
        if args.objects and nm not in args.objects:
            continue
        if not path.is_file():
            print(f"skipping {nm}: {path} not present")
            continue
        for th in args.thresholds:
            cases.append((f"{nm} (t={th:g})", lambda p=path, t=th: ObjectModel.from_mesh(p, threshold=t)))
    return cases


def print_decomposition(results: list[dict], sweeps: list[dict]) -> None:
    """Markdown tables: the decomposition of each object, and the threshold sweeps."""
    hdr = ("| object | genus | hull: excess % / dist mm | pieces | planes | build s | over-cover p99/max mm | "
           "surface p99/max mm | outside p99/max mm |")
    print(hdr)
    print("|" + "---|" * (hdr.count("|") - 1))
    for r in results:
        print(f"| {r['object']} | {r['genus']} | {100 * r['hull_volume_excess']:.2f} / "
              f"{r['hull_distance_mm']:.2f}{' (hull)' if r['near_convex'] else ''} | {r['pieces']} | "
              f"{r['planes']} | {r['build_s']:.1f}{'' if r['decomposed'] else '*'} | "
              f"{r['overcover_p99_mm']:.2f}/{r['overcover_max_mm']:.2f} | "
              f"{r['surface']['p99_mm']:.2f}/{r['surface']['max_mm']:.2f} | "
              f"{r['outside']['p99_mm']:.2f}/{r['outside']['max_mm']:.2f} |")
    if sweeps:
        print("\n| object | threshold | pieces | decomp s | over-cover p99/max mm | chosen |")
        print("|---|---|---|---|---|---|")
        for sw in sweeps:
            for row in sw["rows"]:
                print(f"| {sw['object']} | {row['threshold']:g} | {row['pieces']} | {row['time_s']:.1f} | "
                      f"{row['overcover_p99_mm']:.2f}/{row['overcover_max_mm']:.2f} | "
                      f"{'yes' if row['threshold'] == sw['chosen_threshold'] else ''} |")
    print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--n", type=int, default=3000, help="surface samples (and as many per shell side)")
    ap.add_argument("--thresholds", type=float, nargs="+", default=[0.05], help="coacd thresholds (YCB)")
    ap.add_argument("--no-ycb", action="store_true")
    ap.add_argument("--objects", nargs="+", help="only these generated objects / YCB names")
    ap.add_argument("--sweep", type=float, nargs="+", metavar="T",
                    help="also decompose each non-convex generated object at these coacd thresholds")
    ap.add_argument("--sweep-pieces", type=int, nargs="+", metavar="N",
                    help="also choose coacd's piece cap among these by over-cover error (piece_count)")
    ap.add_argument("--max-seconds", type=float, default=convex.DEFAULT_MAX_SECONDS,
                    help="time cap of one sweep decomposition, s")
    ap.add_argument("--use-cache", action="store_true", help="use the user's decomposition cache")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "geometry.json"))
    args = ap.parse_args()
    if not args.use_cache:
        os.environ["REGRASP_CACHE_DIR"] = tempfile.mkdtemp(prefix="regrasp_bench_cache_")
    cases = _cases(args)
    results = []
    sweeps = []
    piece_sweeps: list[dict] = []
    for name, make in cases:
        r = evaluate(name, make, args.n)
        results.append(r)
        print(f"done {name}: surface p99 {r['surface']['p99_mm']:.2f} mm", file=sys.stderr, flush=True)
        if args.sweep and r["hull_distance_mm"] > 1e-6 and name in GENERATED:
            sweeps.append(sweep(name, make().mesh, args.sweep, args.max_seconds))
        if args.sweep_pieces and r["hull_distance_mm"] > 1e-6 and name in GENERATED:
            piece_sweeps.append(piece_sweep(name, make().mesh, args.sweep_pieces, args.max_seconds))
    print_decomposition(results, sweeps)
    for ps in piece_sweeps:
        print(f"{ps['object']}: chosen cap {ps['chosen_cap']}; " + "; ".join(
            f"cap {r['cap']}: {r['pieces']} pieces / {r['planes']} planes, p99 {r['overcover_p99_mm']:.2f} mm, "
            f"{r['time_s']:.0f} s" for r in ps["rows"]))
    hdr = ("| object | pieces | planes | decomp s | surface p50/95/99/max mm | hard / all-planes p99 mm | "
           "inside p99/max mm | outside p99/max mm | out excess / bound mm | sign err (>1 mm) | "
           "f call µs | f+grad call µs | f+grad VM µs/pt SX / MX |")
    print(hdr)
    print("|" + "---|" * (hdr.count("|") - 1))
    for r in results:
        s, i, o = r["surface"], r["inside"], r["outside"]
        print(f"| {r['object']} | {r['pieces']} | {r['planes']} | "
              f"{r['build_s']:.2f}{'' if r['decomposed'] else '*'} | "
              f"{s['p50_mm']:.3f}/{s['p95_mm']:.3f}/{s['p99_mm']:.3f}/{s['max_mm']:.3f} | "
              f"{r['surface_hard']['p99_mm']:.3f} / {r['surface_hull_all_planes']['p99_mm']:.3f} | "
              f"{i['p99_mm']:.2f}/{i['max_mm']:.2f} | "
              f"{o['p99_mm']:.2f}/{o['max_mm']:.2f} | {r['outside_max_excess_mm']:.3f} / "
              f"{r['bias_bound_mm']:.3f} | {r['sign_errors']} ({r['sign_errors_beyond_1mm']}) | "
              f"{r['value_call_us']:.1f} | {r['value_grad_call_us']:.1f} | "
              f"{r['value_grad_vm_us']:.2f} / {r['value_grad_vm_mx_us']:.2f} |")
    print("(* = no decomposition: convex primitive or cache hit; build time is then hull + planes only)")
    info = machine_info()
    v = info["versions"]
    print(f"\n{info['cpu']}, python {info['python']}, casadi {v['casadi']}, coacd {v['coacd']}, "
          f"trimesh {v['trimesh']}, commit {info['git_commit'][:10]}")
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"machine": info, "n_samples": args.n, "thresholds": args.thresholds,
                               "near_convex_rule": {"hull_distance_m": convex.DEFAULT_HULL_TOLERANCE,
                                                    "hull_volume_excess": convex.HULL_VOLUME_TOLERANCE},
                               "results": results, "sweeps": sweeps,
                               "piece_sweeps": piece_sweeps}, indent=1))


if __name__ == "__main__":
    main()
