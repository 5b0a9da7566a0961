"""Can the hand let go of its thumb? Reachable holding sets without the thumb, certified or not.

Every goal of the shipped problems and of the paper pairs moves the thumb's contact 22-72 mm while the
thumb alone opposes index, middle and ring; the force-closure planner stalls on nearly all of them
(issue 14; benchmarks/README.md). The thumb can move only by
lifting (a gait: the other three must hold the object alone), by sliding (its kinetic drag must be held
by the others: never, against three fingers on the parallel face, `tests/test_stability.py`) or by
rolling (its contact moves by ρ θ, about 14 mm per radian of the tip's turn). This script asks the
first question of the object as it sits in the hand at the initial grasp: is there ANY placement of
index, middle and ring that the fingers can reach and that holds the object without the thumb?

Per problem, at grasp0's object pose (``--at desired``: the desired grasp's object pose and joints):

1. *Reachable contacts.* Each of index, middle and ring gets `--samples` joint configurations uniform in
   its limits (the other fingers at grasp0); a configuration counts when its tip sphere touches the
   object (exact distance within 1 mm of the tip radius) and every other sphere of the finger is
   outside the object (exact distance). Its contact and normal are the exact closest point.
2. *Force closure without the thumb* (μ 0.5, the planner's `Holding` certificate, ε ≥ its
   `min_margin`): `--triples` random triples of reachable contacts, certified or not; the largest ε;
   the most opposed index-ring pair of normals (for two contacts to squeeze the object between them,
   their normals must be more than 180° − 2 atan μ = 126.9° apart: cos < −0.6).
3. *Gravity hold without the thumb* in the supporting orientation (`hand_orientation.
   supporting_gravity`: gravity presses the object onto the fingers opposite the thumb; μ 0.4, ≤ 10 N
   per finger, every finger ≥ half an equal share of the weight, the joint-torque bound; the problem's
   mass or the YCB mass): every triple is screened by whether the centre of mass projects, along
   gravity, inside the triangle of the three contacts (the necessary condition on a flat support);
   up to `--triples` / 10 of those that do are certified.

A problem with no certified triple cannot move its thumb by a gait with that certificate from this
object pose; ``--at plan`` asks the same at four steps of the paper planner's plan (other object poses).
Measures; asserts nothing.

    python benchmarks/thumb_release.py                               # shipped problems + paper pairs _0, _1
    python benchmarks/thumb_release.py --pairs 0 --out /tmp/t.json   # shipped problems only

Measured (`--pairs 5`, results/thumb_release.json, table in benchmarks/README.md): on 21 of the 30
problems no reachable placement holds the object in force closure without the thumb; under the supporting
gravity 17 of 30 have one. From the desired grasp (`--at desired`, results/thumb_release_desired.json):
5 of 30 in force closure (10 of 30 at either grasp), 15 of 30 under the supporting gravity.
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
sys.path.insert(0, str(HERE))

CONE_COS = -0.6
"""cos(180° − 2 atan 0.5): two contacts squeeze an object between them only with normals farther apart."""


def reachable_contacts(problem, finger: str, samples: int, seed: int, grasp=None) -> tuple[np.ndarray, np.ndarray]:
    """(contacts (k, 3), outward normals (k, 3)), object frame, of `finger`'s reachable touching
    configurations at `grasp`'s object pose (default grasp0; see the module docstring, item 1)."""
    from regrasp_casadi.stability import contact_normals

    hand, obj, g = problem.hand, problem.obj, grasp or problem.grasp0
    T, q0 = np.asarray(g.T_palm_object, float), np.asarray(g.q, float)
    lo, hi = hand._finite_limits()
    idx = hand.finger_joints[finger]
    rng = np.random.default_rng(seed)
    Q = np.tile(q0, (samples, 1))
    Q[:, idx] = rng.uniform(lo[idx], hi[idx], (samples, len(idx)))
    tips = np.asarray(hand.tip_position_function(finger)(Q.T), float).T.reshape(samples, 3)
    p_object_tips = (tips - T[:3, 3]) @ T[:3, :3]
    contacts, sd = obj.closest_points(p_object_tips)
    touching = np.flatnonzero(np.abs(sd - hand.tip_radius) < 1e-3)
    radii = hand.sphere_radii(finger)
    clear = []
    for j in touching:
        p_object_spheres = (np.asarray(hand.sphere_centers(Q[j], finger), float) - T[:3, 3]) @ T[:3, :3]
        if np.all(obj.exact_signed_distance(p_object_spheres) - radii > 0.0):
            clear.append(j)
    clear = np.asarray(clear, int)
    return contacts[clear], contact_normals(contacts[clear], p_object_tips[clear])


def _com_inside(holding, T, gravity_palm, cands) -> np.ndarray:
    """(a, b, c) index triples of the three candidate sets whose triangle contains the centre of mass's
    projection along gravity (object frame)."""
    g_object = T[:3, :3].T @ np.asarray(gravity_palm, float)
    d = g_object / np.linalg.norm(g_object)
    u = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(d, u)

    def plane(x):
        return np.stack([x @ u, x @ v], axis=-1)

    com = plane(holding.com)
    a, b, c = (plane(x) for x in cands)
    a, b, c = a[:, None, None], b[None, :, None], c[None, None, :]

    def side(p, q):
        return (q[..., 0] - p[..., 0]) * (com[1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (com[0] - p[..., 0])

    s1, s2, s3 = side(a, b), side(b, c), side(c, a)
    return np.argwhere(((s1 > 0) & (s2 > 0) & (s3 > 0)) | ((s1 < 0) & (s2 < 0) & (s3 < 0)))


def _pinch_search(fc, grasp, cands, others, cos, *, T, hold, triples, rng) -> dict:
    """Force closure of index and ring squeezing the object (a pair of reachable contacts whose normals
    are more than 126.9° apart, at random among them) with the middle at a random reachable contact:
    `triples` tries; the count certified and the largest ε."""
    pairs = np.argwhere(cos < CONE_COS)
    if len(pairs) == 0:
        return {"pinch_certified": 0, "pinch_tried": 0}
    i_middle = others.index("middle")
    certified, best = 0, -np.inf
    for _ in range(triples):
        a, b = pairs[rng.integers(len(pairs))]
        choice = [0, 0, 0]
        choice[others.index("index")], choice[others.index("ring")] = a, b
        choice[i_middle] = rng.integers(len(cands[i_middle][0]))
        cert = fc.hypothetical(*grasp(choice), T, hold, np.zeros(len(hold), bool))
        certified += fc.certified(cert)
        best = max(best, float(cert.margin))
    return {"pinch_certified": int(certified), "pinch_tried": int(triples), "pinch_best_eps": round(best, 5)}


def measure(path: str, samples: int, triples: int, at: str = "initial") -> dict:
    """The record of one problem (never raises) at its initial or its desired grasp (`at`), or ("plan") at
    `PLAN_POSES` steps spread over the paper planner's svd plan (their counts summed, per pose in
    "poses")."""
    from regrasp_casadi.grasp import Grasp
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem

    rec: dict = {"problem": pathlib.Path(path).stem}
    t0 = time.perf_counter()
    try:
        problem = RegraspProblem.load(path)
        if at == "plan":
            plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method="svd", stability="none")
            picks = sorted({int(round(k)) for k in np.linspace(1, len(plan.steps) - 2, PLAN_POSES)})
            grasps = [Grasp.from_joints(problem.hand, problem.obj, plan.steps[k].q, plan.steps[k].T_palm_object)
                      for k in picks]
            poses = [{"step": k, **_at_grasp(problem, g, path, samples, triples)} for k, g in zip(picks, grasps,
                                                                                               strict=True)]
            rec.update({key: sum(p.get(key, 0) for p in poses) for key in _COUNTS}, plan_status=plan.status,
                       poses=poses)
        else:
            g = problem.grasp0 if at == "initial" else problem.grasp_goal
            if g.q is None:
                raise ValueError(f"the {at} grasp states no joints")
            rec.update(_at_grasp(problem, g, path, samples, triples))
    except Exception as exc:  # recorded, not raised
        rec["error"] = f"{type(exc).__name__}: {exc}"
    rec["time_s"] = round(time.perf_counter() - t0, 1)
    return rec


PLAN_POSES = 4
"""Steps of the paper planner's plan examined by ``--at plan`` (spread from its second to its last but one)."""
_COUNTS = ("fc_certified", "fc_tried", "pinch_certified", "pinch_tried", "gravity_inside", "gravity_certified",
           "gravity_tried")


def _at_grasp(problem, g, path: str, samples: int, triples: int) -> dict:
    """Items 1-3 of the module docstring at grasp `g` (its object pose and joints)."""
    from regrasp_casadi.certificates import YCB_MASSES
    from regrasp_casadi.hand_orientation import supporting_gravity
    from regrasp_casadi.holding import Holding, HoldingOptions

    hand, rec = problem.hand, {}
    T, q0 = np.asarray(g.T_palm_object, float), np.asarray(g.q, float)
    fingers, thumb = list(hand.fingers), hand.thumb
    others = [f for f in fingers if f != thumb]
    cands = [reachable_contacts(problem, f, samples, seed=k, grasp=g) for k, f in enumerate(others)]
    rec["reachable"] = {f: len(c) for f, (c, _) in zip(others, cands, strict=True)}
    hold = np.array([f != thumb for f in fingers])
    rows = [fingers.index(f) for f in others]
    fc = Holding(hand, problem.obj, "force_closure", HoldingOptions())
    c0, n0 = fc.contacts(q0, T)
    rng = np.random.default_rng(0)
    if min(rec["reachable"].values()) == 0:
        return {**rec, **dict.fromkeys(_COUNTS, 0)}

    def grasp(choice):
        c, n = c0.copy(), n0.copy()
        for r, (cc, nn), j in zip(rows, cands, choice, strict=True):
            c[r], n[r] = cc[j], nn[j]
        return c, n

    certified, best = 0, -np.inf
    for _ in range(triples):
        c, n = grasp([rng.integers(len(cc)) for cc, _ in cands])
        cert = fc.hypothetical(c, n, T, hold, np.zeros(len(fingers), bool))
        certified += fc.certified(cert)
        best = max(best, float(cert.margin))
    i_index, i_ring = others.index("index"), others.index("ring")
    cos = cands[i_index][1] @ cands[i_ring][1].T
    rec.update(fc_certified=certified, fc_tried=triples, fc_best_eps=round(best, 5),
               min_cos_index_ring=round(float(np.min(cos)), 3), pinch_pairs=int(np.sum(cos < CONE_COS)))
    rec.update(_pinch_search(fc, grasp, cands, others, cos, T=T, hold=hold, triples=triples, rng=rng))
    text = pathlib.Path(path).read_text()
    mass = next((m for name, m in YCB_MASSES.items() if name in text), None)
    gravity_palm = supporting_gravity(g)
    grav = Holding(hand, problem.obj, "gravity", HoldingOptions(mu=0.4, min_load_share=0.5), mass=mass,
                   gravity_palm=gravity_palm)
    inside = _com_inside(grav, T, gravity_palm, [c for c, _ in cands])
    pick = inside[rng.permutation(len(inside))[:max(triples // 10, 1)]]
    ok = sum(grav.certified(grav.hypothetical(*grasp(t), T, hold, np.zeros(len(fingers), bool))) for t in pick)
    rec.update(mass_kg=round(float(grav.mass), 4), triples_total=int(np.prod([len(c) for c, _ in cands])),
               gravity_inside=int(len(inside)), gravity_certified=int(ok), gravity_tried=int(len(pick)))
    return rec


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pairs", type=int, default=2, help="paper pairs <object>_<k> with k < this (0: none)")
    ap.add_argument("--samples", type=int, default=20000, help="joint samples per finger")
    ap.add_argument("--triples", type=int, default=3000, help="random triples certified for force closure")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--at", choices=("initial", "desired", "plan"), default="initial",
                    help="the grasp whose object pose and joints the fingers start from ('plan': steps of the "
                         "paper planner's svd plan)")
    ap.add_argument("--out", type=pathlib.Path, default=HERE / "results" / "thumb_release.json")
    args = ap.parse_args(argv)
    from machine import machine_info

    files = sorted((REPO / "problems").glob("*.yaml"))
    if args.pairs > 0 and (REPO.parent / "shared" / "reference" / "ycb").is_dir():
        files += sorted(p for p in (HERE / "problems").glob("*.yaml") if int(p.stem.rsplit("_", 1)[1]) < args.pairs)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max(args.workers, 1)) as pool:
        records = list(pool.map(measure, map(str, files), [args.samples] * len(files),
                                [args.triples] * len(files), [args.at] * len(files)))
    print("| problem | reachable i/m/r | FC certified | best ε | min cos(index, ring) | pinch FC certified | "
          "COM inside | gravity certified |")
    print("|---|---|---|---|---|---|---|---|")
    for r in records:
        if "error" in r:
            print(f"| {r['problem']} | error: {r['error']} |")
            continue
        reach = "/".join(str(v) for v in r["reachable"].values()) if "reachable" in r else \
            f"{len(r.get('poses', []))} poses"
        print(f"| {r['problem']} | {reach} | {r['fc_certified']} / {r['fc_tried']} | {r.get('fc_best_eps', '—')} | "
              f"{r.get('min_cos_index_ring', '—')} | {r.get('pinch_certified', 0)} / {r.get('pinch_tried', 0)} | "
              f"{r['gravity_inside']} of {r.get('triples_total', 0)} | "
              f"{r['gravity_certified']} / {r['gravity_tried']} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": machine_info(), "wall_s": round(time.perf_counter() - t0, 1),
                                    "samples": args.samples, "triples": args.triples, "at": args.at,
                                    "records": records},
                                   indent=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
