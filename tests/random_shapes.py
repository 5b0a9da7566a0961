"""Seeded random convex hulls and rigid transforms for the geometry tests."""

from __future__ import annotations

import numpy as np
import trimesh


def random_hull(seed: int, n: int = 12) -> trimesh.Trimesh:
    """Convex hull of `n` Gaussian points with random per-axis spreads 1–6 cm, m."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * rng.uniform(0.01, 0.06, size=3)
    return trimesh.convex.convex_hull(pts)


def random_rigid(seed: int) -> np.ndarray:
    """A random proper rigid transform (4, 4): rotation from a QR factor, translation within ±0.5 m."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    T = np.eye(4)
    T[:3, :3] = q
    T[:3, 3] = rng.uniform(-0.5, 0.5, 3)
    return T
