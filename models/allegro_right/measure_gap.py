"""Measure how far the sphere cover's outer surface lies from the vendor meshes (reads ../shared/reference).

For every body of ``fit_spheres.BODIES``: 3,000 points on each sphere, keep those on the boundary of the
union (inside no other sphere), report the distance (mm) from them to the vendor mesh (millimetre scale, so
trimesh's fixed tolerance does not bite).

    python models/allegro_right/measure_gap.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import fit_spheres as fs  # noqa: E402


def main() -> None:
    cover = json.loads((HERE / "sphere_cover.json").read_text())["bodies"]
    ref = HERE.parents[2] / "shared/reference/allegro_right"
    for name, (meshes, _k, _w, fixed) in fs.BODIES.items():
        parts = []
        for fname, T in meshes:
            m = trimesh.load(ref / "meshes" / fname)
            m.apply_transform(T)
            parts.append(m)
        mesh = trimesh.util.concatenate(parts)
        mesh.apply_scale(1000.0)
        C = np.array([s["center"] for s in cover[name]]) * 1000
        R = np.array([s["radius"] for s in cover[name]]) * 1000
        if fixed is not None:
            C = np.vstack([C, fixed[0] * 1000])
            R = np.append(R, fixed[1] * 1000)
        rng = np.random.default_rng(0)
        pts = []
        for c, r in zip(C, R, strict=True):
            u = rng.normal(size=(3000, 3))
            u /= np.linalg.norm(u, axis=1)[:, None]
            pts.append(c + r * u)
        P = np.vstack(pts)
        D = np.linalg.norm(P[:, None] - C[None], axis=-1) - R
        P = P[(D < -1e-9).sum(1) == 0]
        _, d, _ = trimesh.proximity.closest_point(mesh, P)
        print(f"{name:15s} gap cover surface -> mesh: median {np.median(d):.1f} mm, max {d.max():.1f} mm")


if __name__ == "__main__":
    main()
