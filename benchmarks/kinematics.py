"""Benchmark: CasADi SX forward kinematics of the Allegro hand vs yourdfpy, and symbolic build time.

Measures, in one run on the shipped model (models/allegro_right/allegro_right.urdf):
* full-hand FK (21 links): CasADi numeric call of ``hand.fk_function()`` (one output per link), of the stacked
  single-output function behind ``hand.fk``, and the ``hand.fk(q)`` convenience (dict of numpy arrays);
  yourdfpy ``URDF.update_cfg(q)`` + ``get_transform`` for every link;
* one tip Jacobian (3 x 16): CasADi numeric call and ``hand.tip_jacobian``;
* building the symbolic Hand in a fresh process (``Hand.allegro_right()`` + FK, tip, Jacobian and sphere
  functions), with ``import casadi`` timed separately.

Prints a markdown table and writes benchmarks/results/kinematics.json with machine info.

    python benchmarks/kinematics.py [--reps 2000]

Representative output (Intel Xeon Processor, 2 shared cores, Python 3.11.7, CasADi 3.8.2, yourdfpy 0.0.60;
machine loaded by other jobs, so absolute times vary ~2x between runs):

| operation | time per call | yourdfpy / this |
| --- | --- | --- |
| FK, yourdfpy update_cfg + get_transform x21 | 1063.5 µs | 1x |
| FK, CasADi fk_function()(q), 21 outputs | 75.2 µs | 14x |
| FK, CasADi stacked (4, 84) single output | 29.8 µs | 36x |
| FK, hand.fk(q) -> dict of numpy (4,4) (buffer) | 29.7 µs | 36x |
| FK, CasADi stacked, buffer evaluation (raw) | 3.9 µs | 270x |
| tip Jacobian, CasADi J_tip_index(q) | 35.7 µs | 30x |
| tip Jacobian, CasADi buffer evaluation (raw) | 0.7 µs | 1556x |
| tip Jacobian, hand.tip_jacobian(q) -> numpy (buffer) | 10.7 µs | 99x |

Build in a fresh process: import casadi 162 ms, Hand parse 10.5 ms + all functions 38 ms = 48.5 ms.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yourdfpy

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import machine_info  # noqa: E402

from regrasp_casadi.hand import Hand  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

_BUILD_SNIPPET = """
import time, json
t0 = time.perf_counter()
import casadi
t1 = time.perf_counter()
from regrasp_casadi.hand import Hand
t2 = time.perf_counter()
h = Hand.allegro_right()
t3 = time.perf_counter()
h.fk_function(); h.tip_positions_function()
for f in h.fingers:
    h.tip_position_function(f); h.tip_jacobian_function(f); h.sphere_centers_function(f, True)
h.sphere_centers_function(None, True)
t4 = time.perf_counter()
print(json.dumps({"import_casadi": t1 - t0, "import_hand": t2 - t1, "parse": t3 - t2, "functions": t4 - t3}))
"""


def _time_per_call(fn, reps: int, repeats: int = 5) -> float:
    """Median over `repeats` of the mean time per call (s) of `reps` calls."""
    fn()
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(reps):
            fn()
        out.append((time.perf_counter() - t) / reps)
    return statistics.median(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=2000, help="calls per timing repeat (CasADi)")
    ap.add_argument("--build-runs", type=int, default=3, help="fresh processes for the build time")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "kinematics.json")
    args = ap.parse_args()

    hand = Hand.allegro_right()
    rng = np.random.default_rng(0)
    q = rng.uniform(hand.q_lower, hand.q_upper)
    urdf = yourdfpy.URDF.load(str(hand.urdf_path), load_meshes=False, build_collision_scene_graph=False)
    links = [link.name for link in urdf.robot.links]

    def yourdfpy_fk():
        urdf.update_cfg(q)
        return [urdf.get_transform(ln, urdf.base_link) for ln in links]

    fk = hand.fk_function()
    fk_stacked = hand._fk_stacked_function()
    jac = hand.tip_jacobian_function("index")
    t_ref = _time_per_call(yourdfpy_fk, max(50, args.reps // 20))

    keep = []

    def raw_buffer(fn):
        """Numeric evaluation through a preallocated CasADi buffer (no conversion, no copy)."""
        q_buf = np.array(q)
        out = np.zeros(fn.size_out(0)[::-1])
        buf, evaluate = fn.buffer()
        buf.set_arg(0, memoryview(q_buf))
        buf.set_res(0, memoryview(out))
        keep.append((buf, q_buf, out))  # the buffer reads/writes these arrays: keep them alive
        return evaluate

    fk_raw = raw_buffer(fk_stacked)
    jac_raw = raw_buffer(jac)
    rows = [
        ("FK, yourdfpy update_cfg + get_transform x21", t_ref),
        ("FK, CasADi fk_function()(q), 21 outputs", _time_per_call(lambda: fk(q), args.reps)),
        ("FK, CasADi stacked (4, 84) single output", _time_per_call(lambda: fk_stacked(q), args.reps)),
        ("FK, hand.fk(q) -> dict of numpy (4,4) (buffer)", _time_per_call(lambda: hand.fk(q), args.reps)),
        ("FK, CasADi stacked, buffer evaluation (raw)", _time_per_call(fk_raw, args.reps)),
        ("tip Jacobian, CasADi J_tip_index(q)", _time_per_call(lambda: jac(q), args.reps)),
        ("tip Jacobian, CasADi buffer evaluation (raw)", _time_per_call(jac_raw, args.reps)),
        (
            "tip Jacobian, hand.tip_jacobian(q) -> numpy (buffer)",
            _time_per_call(lambda: hand.tip_jacobian(q, "index"), args.reps),
        ),
    ]
    builds = []
    for _ in range(args.build_runs):
        res = subprocess.run(
            [sys.executable, "-c", _BUILD_SNIPPET], capture_output=True, text=True, check=True
        )
        builds.append(json.loads(res.stdout))
    build = {k: statistics.median(b[k] for b in builds) for k in builds[0]}

    info = machine_info(("casadi", "numpy", "yourdfpy"))
    print(
        f"Machine: {info['cpu']}, Python {info['python']}, CasADi {info['versions']['casadi']}, "
        f"commit {info['git_commit'][:8]}"
    )
    print()
    print("| operation | time per call | yourdfpy / this |")
    print("| --- | --- | --- |")
    for name, t in rows:
        print(f"| {name} | {t * 1e6:.1f} µs | {t_ref / t:.0f}x |")
    print()
    print("| build step (fresh process, median of %d) | time |" % args.build_runs)
    print("| --- | --- |")
    for k, v in build.items():
        print(f"| {k} | {v * 1e3:.1f} ms |")
    print(f"| Hand build (parse + functions) | {(build['parse'] + build['functions']) * 1e3:.1f} ms |")

    result = {
        "machine": info,
        "date": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "q_seed": 0,
        "timings_s": {name: t for name, t in rows},
        "ratio_yourdfpy_over": {name: t_ref / t for name, t in rows},
        "build_s": build,
        "hand_build_s": build["parse"] + build["functions"],
        "command": "python benchmarks/kinematics.py",
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
