"""Fit the conservative sphere cover of the Allegro right hand (v4) links to the vendor meshes.

Reads the vendor STL meshes from ``../shared/reference/allegro_right/meshes`` (reference data, not shipped),
fits a few spheres per rigid body and writes ``sphere_cover.json`` beside this file, which ``generate.py``
turns into ``<collision><sphere>`` elements of ``allegro_right.urdf``. Run from anywhere:

    python models/allegro_right/fit_spheres.py [--reference DIR]

Method (per rigid body, in its link frame, metres):
1. Points = every mesh vertex plus 20,000 area-uniform surface samples (seed 0).
2. Points already inside a fixed sphere (the fingertip contact sphere on distal bodies) are dropped.
3. k-means (scipy ``kmeans2``, 8 seeds) on the points scaled by per-axis weights (finger links cluster along
   their length, the palm in its plane), then per cluster an enclosing sphere (Badoiu-Clarkson centre,
   radius =
   farthest point + margin).
4. Greedy shrink: each sphere in turn is re-centred and shrunk to enclose only the points no other sphere
   covers (so coverage is kept at every step); repeated 3 times.
5. The seed with the smallest sum of r^3 wins. Coordinates are rounded outwards (radius up by the rounding
   error of the centre) to 0.1 mm and the enclosure is re-checked on all vertices.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import trimesh
from scipy.cluster.vq import kmeans2

HERE = Path(__file__).resolve().parent
MARGIN = 0.0002  # m, added to every radius (covers faces spanning two spheres)
TIP_CENTER = np.array([0.0, 0.0, 0.002])  # tip link frame
TIP_RADIUS = 0.014

# body name -> (meshes [(file, T_link_mesh)], number of spheres, k-means axis weights, fixed sphere or None)
FINGER_TIP_OFFSET = 0.0267
THUMB_TIP_OFFSET = 0.0423


def _T_z(z: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = z
    return T


def _T_rx_pi() -> np.ndarray:
    T = np.eye(4)
    T[1, 1] = T[2, 2] = -1.0
    return T


BODIES = {
    "palm": ([("base_link.STL", np.eye(4))], 14, (0.15, 1.0, 1.0), None),
    "proximal_base": ([("link_0.0.STL", np.eye(4))], 2, (0.1, 0.1, 1.0), None),
    "proximal": ([("link_1.0.STL", np.eye(4))], 4, (0.1, 0.1, 1.0), None),
    "middle": ([("link_2.0.STL", np.eye(4))], 3, (0.1, 0.1, 1.0), None),
    "distal": (
        [("link_3.0.STL", np.eye(4)), ("link_3.0_tip.STL", _T_z(FINGER_TIP_OFFSET))],
        3,
        (0.1, 0.1, 1.0),
        (TIP_CENTER + [0, 0, FINGER_TIP_OFFSET], TIP_RADIUS),
    ),
    "thumb_base": ([("link_12.0_right.STL", _T_rx_pi())], 3, (1.0, 1.0, 1.0), None),
    "thumb_proximal": ([("link_13.0.STL", np.eye(4))], 2, (0.1, 0.1, 1.0), None),
    "thumb_middle": ([("link_14.0.STL", np.eye(4))], 4, (0.1, 0.1, 1.0), None),
    "thumb_distal": (
        [("link_15.0.STL", np.eye(4)), ("link_15.0_tip.STL", _T_z(THUMB_TIP_OFFSET))],
        4,
        (0.1, 0.1, 1.0),
        (TIP_CENTER + [0, 0, THUMB_TIP_OFFSET], TIP_RADIUS),
    ),
}


def enclosing_sphere(P: np.ndarray, iters: int = 400) -> tuple[np.ndarray, float]:
    """Approximate minimum enclosing sphere (Badoiu-Clarkson); the radius is exact for the returned centre."""
    c = P.mean(axis=0)
    for i in range(1, iters + 1):
        far = P[np.argmax(((P - c) ** 2).sum(1))]
        c = c + (far - c) / (i + 1)
    return c, float(np.sqrt(((P - c) ** 2).sum(1).max()))


def fit_body(P: np.ndarray, k: int, w: np.ndarray, seeds: int = 8):
    best = None
    for seed in range(seeds):
        _, lab = kmeans2(P * w, k, seed=seed, minit="++")
        if len(np.unique(lab)) < k:
            continue
        C, R = [], []
        for j in range(k):
            c, r = enclosing_sphere(P[lab == j])
            C.append(c)
            R.append(r + MARGIN)
        C, R = np.array(C), np.array(R)
        for _ in range(3):
            for j in range(k):
                D = np.sqrt(((P[:, None, :] - C[None]) ** 2).sum(-1))
                others = np.delete(np.arange(k), j)
                own = ~(D[:, others] <= R[others]).any(axis=1)
                if own.sum() == 0:
                    continue
                c, r = enclosing_sphere(P[own])
                C[j], R[j] = c, r + MARGIN
        score = float((R**3).sum())
        if best is None or score < best[0]:
            best = (score, C.copy(), R.copy())
    return best[1], best[2]


def body_points(ref: Path, meshes) -> tuple[np.ndarray, np.ndarray, float]:
    verts, samples, vol = [], [], 0.0
    for fname, T in meshes:
        m = trimesh.load(ref / "meshes" / fname)
        m.apply_transform(T)
        verts.append(np.asarray(m.vertices))
        samples.append(np.asarray(trimesh.sample.sample_surface(m, 20000, seed=0)[0]))
        vol += m.volume
    return np.vstack(verts), np.vstack(samples), vol


def union_volume(C, R, lo, hi, n=400_000, seed=0) -> float:
    rng = np.random.default_rng(seed)
    X = rng.uniform(lo, hi, size=(n, 3))
    inside = np.zeros(n, bool)
    for c, r in zip(C, R, strict=True):
        inside |= ((X - c) ** 2).sum(1) <= r * r
    return float(inside.mean() * np.prod(hi - lo))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", type=Path, default=HERE.parents[2] / "shared/reference/allegro_right")
    args = ap.parse_args()
    out, report = {}, {}
    for name, (meshes, k, w, fixed) in BODIES.items():
        V, S, vol = body_points(args.reference, meshes)
        P = np.vstack([V, S])
        if fixed is not None:
            P = P[np.sqrt(((P - fixed[0]) ** 2).sum(1)) > fixed[1]]
        C, R = fit_body(P, k, np.asarray(w))
        # round outwards to 0.1 mm: centre error <= 0.05 mm per axis -> radius += 0.0866 mm, rounded up
        Cr = np.round(C, 4)
        Rr = np.ceil((R + np.linalg.norm(C - Cr, axis=1)) * 1e4) / 1e4
        allC, allR = list(Cr), list(Rr)
        if fixed is not None:
            allC.append(fixed[0])
            allR.append(fixed[1])
        allC, allR = np.array(allC), np.array(allR)
        d_out = (np.sqrt(((V[:, None] - allC[None]) ** 2).sum(-1)) - allR).min(axis=1).max()
        d_out_s = (np.sqrt(((S[:, None] - allC[None]) ** 2).sum(-1)) - allR).min(axis=1).max()
        lo = np.minimum(V.min(0), (allC - allR[:, None]).min(0))
        hi = np.maximum(V.max(0), (allC + allR[:, None]).max(0))
        uv = union_volume(allC, allR, lo, hi)
        out[name] = [
            {"center": [float(x) for x in c], "radius": float(r)} for c, r in zip(Cr, Rr, strict=True)
        ]
        report[name] = {
            "spheres": int(k),
            "max_outside_vertices_m": float(d_out),
            "max_outside_samples_m": float(d_out_s),
            "mesh_volume_m3": vol,
            "union_volume_m3": uv,
            "volume_ratio": uv / vol,
            "max_radius_m": float(Rr.max()),
        }
        print(
            f"{name:15s} k={k} max_out_vert={d_out * 1e3:+.3f} mm max_out_samples={d_out_s * 1e3:+.3f} mm "
            f"union/mesh volume={uv / vol:.2f} rmax={Rr.max() * 1e3:.1f} mm"
        )
    (HERE / "sphere_cover.json").write_text(json.dumps({"bodies": out, "check": report}, indent=1) + "\n")


if __name__ == "__main__":
    main()
