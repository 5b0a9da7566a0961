"""Time of one exact closest-point query (`ExactDistance.closest`, answers not remembered) on the YCB
meshes of the paper benchmark, per batch size, for one or more checkouts interleaved.

Each checkout runs in its own process (``PYTHONPATH=<checkout>``); the rounds alternate between them so
that they see the same load. Per (mesh, batch size): the median over rounds of the mean time of
`--repeat` queries of points sampled on the surface and moved by N(0, 1 cm) per axis (where the planner's
sphere centres are). Records the machine (`machine.machine_info`) and each checkout's commit; asserts
nothing.

    git worktree add /work/wt_old <old commit>
    python benchmarks/exact_distance.py --checkouts /work/wt_old . --out benchmarks/results/exact_distance.json
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys

HERE = pathlib.Path(__file__).resolve().parent
PROBLEMS = ("mustard_0", "banana_0", "sugar-box_0", "pringles_0", "soft-scrub_0")
BATCHES = (1, 20, 100, 500)


def measure(repeat: int) -> dict[str, float]:
    """ms per `closest` call of this process's checkout: "<problem>/<batch>" -> mean of `repeat` calls."""
    import time

    import numpy as np

    from regrasp_casadi.problem import RegraspProblem

    out = {}
    for name in PROBLEMS:
        obj = RegraspProblem.load(HERE / "problems" / f"{name}.yaml").obj
        exact, rng = obj.exact, np.random.default_rng(0)
        for n in BATCHES:
            pts = obj.mesh.sample(n) + rng.normal(0.0, 0.01, size=(n, 3))
            t0 = time.perf_counter()
            for _ in range(repeat):
                exact.clear_cache()
                exact.closest(pts)
            out[f"{name}/{n}"] = (time.perf_counter() - t0) / repeat * 1e3
    return out


def _commit(checkout: pathlib.Path) -> str:
    return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=checkout, capture_output=True,
                          text=True, check=False).stdout.strip()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkouts", nargs="+", type=pathlib.Path, default=[HERE.parent])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--out", type=pathlib.Path)
    ap.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.measure:
        print(json.dumps(measure(args.repeat)))
        return 0
    runs: dict[str, list[dict[str, float]]] = {str(c): [] for c in args.checkouts}
    for _ in range(args.rounds):
        for checkout in args.checkouts:
            env = dict(os.environ, PYTHONPATH=str(checkout.resolve()))
            proc = subprocess.run([sys.executable, __file__, "--measure", "--repeat", str(args.repeat)],
                                  env=env, capture_output=True, text=True, check=True)
            runs[str(checkout)].append(json.loads(proc.stdout.strip().splitlines()[-1]))
    sys.path.insert(0, str(HERE))
    from machine import machine_info

    result = {"machine": machine_info(("numpy", "trimesh", "libigl")), "checkouts": {}}
    for checkout, rounds in runs.items():
        medians = {k: round(statistics.median(r[k] for r in rounds), 3) for k in rounds[0]}
        result["checkouts"][checkout] = {"commit": _commit(pathlib.Path(checkout)), "ms_per_call": medians}
    print("| mesh / batch | " + " | ".join(f"{v['commit']} ms" for v in result["checkouts"].values()) + " |")
    print("|---|" + "---|" * len(runs))
    for key in next(iter(result["checkouts"].values()))["ms_per_call"]:
        print(f"| {key} | " + " | ".join(f"{v['ms_per_call'][key]:.2f}" for v in result["checkouts"].values())
              + " |")
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
