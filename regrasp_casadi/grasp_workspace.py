"""The fingertip workspaces of grasp generation, and which of their joint samples keep a finger clear of
an object at a given pose.

`Workspace`: `N_WORKSPACE` uniform joint samples over the limits (seed 12345) with, per finger, the tip
centres (palm frame, a KD-tree over them) and the centres of the finger's non-tip collision spheres.

`ClearanceGrid`: a lower bound of the object's signed distance on a regular grid (object frame), the
convex pieces' plane bound d(p) = min_C max_i (n_i·p − h_i) (exact inside a piece, a lower bound outside
it), interpolated trilinearly — cheap enough to test every workspace sample's spheres at each attempt
(the exact mesh distance costs ≈ 1 ms a point on the bowl).

`clear_samples`: per finger, the samples whose non-tip spheres keep grid distance − radius ≥ a clearance at
the object pose. On a thin-walled object (the 12 cm bowl) most samples that put a tip on a target pass a
link through the wall; the grasp NLP cannot pull a link back across a wall it straddles (its smooth
distance is about −(radius + half the wall) on either side), so targets and start configurations are drawn
from the clear samples only.

    >>> ws = workspace(hand)
    >>> grid = clearance_grid(obj)
    >>> clear = clear_samples(ws, grid, T_palm_object)   # finger -> ClearSamples
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import map_coordinates
from scipy.spatial import cKDTree

from regrasp_casadi.transforms import inv_T, transform_points

__all__ = ["N_WORKSPACE", "ClearSamples", "ClearanceGrid", "Workspace", "clear_samples", "clearance_grid",
           "joint_tip_samples", "workspace"]

N_WORKSPACE = 20000
"""Joint samples of the fingertip workspaces."""
_GRID_SPACING = 0.003  # m
_GRID_PAD = 0.03  # the grid reaches this far beyond the object's bounding box, m (> every sphere radius)


@dataclass
class Workspace:
    """Joint samples over the limits and, per finger, tip centres (palm frame, m) with a KD-tree and the
    centres of the finger's non-tip spheres."""

    Q: NDArray[np.float64]
    """(N, n) joint samples, rad."""
    tips: dict[str, NDArray[np.float64]]
    """finger -> (N, 3) tip-sphere centres, palm frame, m."""
    trees: dict[str, cKDTree]
    """finger -> KD-tree over `tips[finger]`."""
    p_palm_spheres: dict[str, NDArray[np.float64]]
    """finger -> (N, k_f, 3) centres of its non-tip spheres, palm frame, m."""
    radii: dict[str, NDArray[np.float64]]
    """finger -> (k_f,) their radii, m."""


_WORKSPACES: dict[int, tuple[object, Workspace]] = {}


def joint_tip_samples(hand, n: int, seed: int) -> tuple[NDArray[np.float64], dict[str, NDArray[np.float64]]]:
    """`n` joint samples uniform over the limits (generator seeded with `seed`), (n, n_joints) rad, and per
    finger the tip-sphere centres of those samples, (n, 3) palm frame, m (one mapped CasADi call)."""
    rng = np.random.default_rng(seed)
    Q = rng.uniform(hand.q_lower, hand.q_upper, size=(n, hand.n_joints))
    T = np.asarray(hand.tip_positions_function().map(n)(Q.T)).reshape(3, n, len(hand.fingers))  # (3, n, m)
    return Q, {f: np.ascontiguousarray(T[:, :, i].T) for i, f in enumerate(hand.fingers)}


def workspace(hand) -> Workspace:
    """The `Workspace` of `hand` (computed once per hand object)."""
    hit = _WORKSPACES.get(id(hand))
    if hit is not None and hit[0] is hand:
        return hit[1]
    Q, tips = joint_tip_samples(hand, N_WORKSPACE, seed=12345)
    spheres, radii = {}, {}
    for f in hand.fingers:
        radii[f] = np.asarray(hand.sphere_radii(f), float)
        # (3, N·k_f), sample-major columns
        centres = np.asarray(hand.sphere_centers_function(f).map(N_WORKSPACE)(Q.T))
        spheres[f] = np.ascontiguousarray(centres.reshape(3, N_WORKSPACE, len(radii[f])).transpose(1, 2, 0))
    ws = Workspace(Q, tips, {f: cKDTree(v) for f, v in tips.items()}, spheres, radii)
    _WORKSPACES[id(hand)] = (hand, ws)
    return ws


@dataclass(frozen=True)
class ClearanceGrid:
    """Grid values of a lower bound of the signed distance, object frame: node (i, j, k) at
    origin + spacing·(i, j, k); beyond the grid the border value (≥ the pad, i.e. clear)."""

    origin: NDArray[np.float64]
    """(3,) object frame, m."""
    spacing: float
    """m."""
    values: NDArray[np.float64]
    """(nx, ny, nz) distance bound, m."""

    def __call__(self, p_object: NDArray[np.float64]) -> NDArray[np.float64]:
        """Trilinear interpolation at points (s, 3), object frame, m. Returns (s,) m."""
        ijk = (np.asarray(p_object, float) - self.origin) / self.spacing
        return map_coordinates(self.values, ijk.T, order=1, mode="nearest")


_GRIDS: dict[int, tuple[object, ClearanceGrid]] = {}


def clearance_grid(obj) -> ClearanceGrid:
    """The `ClearanceGrid` of `obj` (its convex pieces' plane bound, `_GRID_SPACING` apart over the
    bounding box grown by `_GRID_PAD`; computed once per object)."""
    hit = _GRIDS.get(id(obj))
    if hit is not None and hit[0] is obj:
        return hit[1]
    bounds = np.asarray(obj.mesh.bounds, float)
    lo, hi = bounds[0] - _GRID_PAD, bounds[1] + _GRID_PAD
    axes = [np.arange(lo[i], hi[i] + _GRID_SPACING, _GRID_SPACING) for i in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    values = np.full(len(nodes), np.inf)
    for start in range(0, len(nodes), 20000):  # bounded memory: (chunk, planes) per piece
        chunk = nodes[start:start + 20000]
        values[start:start + 20000] = np.min(np.column_stack([pc.hard_distance(chunk) for pc in obj.pieces]),
                                             axis=1)
    grid = ClearanceGrid(lo, _GRID_SPACING, values.reshape(tuple(len(a) for a in axes)))
    _GRIDS[id(obj)] = (obj, grid)
    return grid


@dataclass(frozen=True)
class ClearSamples:
    """One finger's workspace samples that keep its links clear of the object at one pose."""

    index: NDArray[np.int64]
    """(c,) indices into `Workspace.Q`."""
    tree: cKDTree | None
    """KD-tree over their tip centres (palm frame); None if there are none."""

    def nearest(self, p_palm: NDArray[np.float64], k: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Distances (m) and `Workspace.Q` indices of the (up to) `k` clear samples whose tip centres are
        nearest to `p_palm` ((3,) or (s, 3), palm frame); distance inf, index −1 when there are none."""
        if self.tree is None:
            shape = np.shape(p_palm)[:-1] + ((k,) if k > 1 else ())
            return np.full(shape, np.inf), np.full(shape, -1)
        d, j = self.tree.query(p_palm, k=min(k, len(self.index)))
        return d, self.index[j]


def clear_samples(ws: Workspace, grid: ClearanceGrid, T_palm_object: NDArray[np.float64],
                  clearance: float = 0.0, near_tip: float = 0.03) -> dict[str, ClearSamples]:
    """Per finger, the samples whose tip centre lies within `near_tip` (m) of the object (grid value) and
    whose non-tip spheres keep grid distance − radius ≥ `clearance` (m) at the object pose
    `T_palm_object` (4, 4). The grid bound is a lower bound of the distance up to the interpolation, so a
    kept sample's links are clear up to a grid spacing's error."""
    T_object_palm = inv_T(T_palm_object)
    out = {}
    for f, tips in ws.tips.items():
        near = np.nonzero(grid(transform_points(T_object_palm, tips)) <= near_tip)[0]
        centres = ws.p_palm_spheres[f][near]  # (s, k_f, 3)
        d = grid(transform_points(T_object_palm, centres.reshape(-1, 3))).reshape(centres.shape[:2])
        keep = near[np.min(d - ws.radii[f], axis=1) >= clearance]
        out[f] = ClearSamples(keep, cKDTree(tips[keep]) if len(keep) else None)
    return out
