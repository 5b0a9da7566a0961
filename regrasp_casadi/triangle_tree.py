"""Candidate triangles of exact closest-point queries: a bounding-sphere tree, in R-tree order.

`ExactDistance` finds the closest point of a query point p among the triangles that can hold it: those
whose bounding box meets the cube of half-side r around p (r = distance to the nearest vertex, an upper
bound of the distance) and whose bounding sphere (centroid, largest vertex distance) comes within r of p.
It used to get the first set from trimesh's R-tree (`Trimesh.triangles_tree`, one box query per point)
and prune it by the spheres; the cube holds many more triangles than the sphere test keeps when p is a
centimetre from a finely meshed surface (a collision sphere's centre: ≈ 245 box candidates per point,
61 kept, on the banana's 10,000 faces).

`TriangleTree` gets the same set top-down: a binary tree whose every node has a sphere enclosing the
spheres of its triangles, descended for all points at once (numpy, one level per step), then the sphere
and box tests of the triangles in the leaves reached. The candidates come out grouped by point and, per
point, in the order of the R-tree's own answer (`rtree_rank`: the R-tree answers a box query with a
subsequence of its full traversal), so the closest-point search that follows sees exactly the arrays it
saw with the R-tree, and breaks ties between equally close triangles the same way.

    >>> tree = TriangleTree(triangles_mm, rank=rtree_rank(mesh_mm.triangles_tree, triangles_mm))
    >>> ids, owner = tree.candidates(p_mm, r_mm)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["TriangleTree", "rtree_rank"]

LEAF_SIZE = 8
"""Largest number of triangles of a leaf."""

_SLACK = 1e-9
"""Added to every node's sphere radius (units of the triangles; relative slack 1e-12 too), so that
round-off never prunes a node whose triangle's own sphere test passes."""


def rtree_rank(tree, triangles: NDArray[np.float64]) -> NDArray[np.int64]:
    """(n,) position of every triangle in the R-tree's answer to a box holding them all: its answer to
    any box query lists its hits in this order. tree: the R-tree of the (n, 3, 3) triangles' boxes."""
    lo, hi = triangles.min(axis=(0, 1)) - 1.0, triangles.max(axis=(0, 1)) + 1.0
    order = np.fromiter(tree.intersection(np.concatenate([lo, hi])), dtype=np.int64)
    if len(order) != len(triangles) or len(np.unique(order)) != len(triangles):
        raise ValueError("the R-tree does not hold one box per triangle")
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    return rank


class TriangleTree:
    """Bounding-sphere tree of triangles (n, 3, 3), for `candidates`.

    Attributes:
        centroids, radii: (n, 3), (n,) every triangle's bounding sphere: centroid and largest vertex
            distance (the sphere test of `candidates`).
        lower, upper: (n, 3) every triangle's bounding box (the box test of `candidates`).
        rank: (n,) order of the candidates of one point (`rtree_rank`; default: triangle index).
    """

    def __init__(self, triangles: NDArray[np.float64], rank: NDArray[np.int64] | None = None):
        tris = np.asarray(triangles, dtype=float)
        self.centroids = tris.mean(axis=1)
        spokes = tris - self.centroids[:, None]
        self.radii = np.max(np.linalg.norm(spokes, axis=2), axis=1)
        self.lower, self.upper = tris.min(axis=1), tris.max(axis=1)
        self.rank = np.arange(len(tris), dtype=np.int64) if rank is None else np.asarray(rank, dtype=np.int64)
        self._build(tris)

    def _build(self, tris: NDArray[np.float64]) -> None:
        """Nodes by median splits of the centroids along their widest axis, level by level; node k holds
        the triangles perm[start[k]:stop[k]], children left[k], left[k] + 1 (−1: a leaf), sphere
        (centre[k], reach[k]) enclosing its triangles' spheres. tris: (n, 3, 3)."""
        perm = np.arange(len(tris))
        start, stop, left = [0], [len(tris)], [-1]
        level = np.array([0])
        while len(level):
            lo, hi = np.array(start)[level], np.array(stop)[level]
            split = hi - lo > LEAF_SIZE
            level, lo, hi = level[split], lo[split], hi[split]
            if not len(level):
                break
            pos, offsets, sizes = _ranges(lo, hi)
            c = self.centroids[perm[pos]]
            extent = np.maximum.reduceat(c, offsets, axis=0) - np.minimum.reduceat(c, offsets, axis=0)
            node_of = np.repeat(np.arange(len(level)), sizes)
            key = c[np.arange(len(c)), np.argmax(extent, axis=1)[node_of]]
            perm[pos] = perm[pos][np.lexsort((key, node_of))]  # a stable sort within every node
            mid = (lo + hi) // 2
            first = len(start) + 2 * np.arange(len(level))
            for k, child in zip(level.tolist(), first.tolist(), strict=True):
                left[k] = child
            start += np.column_stack([lo, mid]).ravel().tolist()
            stop += np.column_stack([mid, hi]).ravel().tolist()
            left += [-1] * (2 * len(level))
            level = np.column_stack([first, first + 1]).ravel()
        self.perm, self.start, self.stop = perm, np.array(start), np.array(stop)
        self.left = np.array(left)
        pos, offsets, sizes = _ranges(self.start, self.stop)
        ids = perm[pos]
        low = np.minimum.reduceat(self.lower[ids], offsets, axis=0)
        high = np.maximum.reduceat(self.upper[ids], offsets, axis=0)
        self.centre = 0.5 * (low + high)
        spread = np.linalg.norm(self.centroids[ids] - np.repeat(self.centre, sizes, axis=0), axis=1)
        self.reach = np.maximum.reduceat(spread + self.radii[ids], offsets) * (1.0 + 1e-12) + _SLACK

    def _leaves(self, p: NDArray[np.float64], r: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """(point, leaf) pairs whose leaf's sphere comes within r (n,) of the point (of p (n, 3)): point
        indices (m,), leaves (m,)."""
        pt = np.arange(len(p))
        node = np.zeros(len(p), dtype=np.int64)
        found_pt, found_node = [], []
        while len(pt):
            g = self.centre[node] - p[pt]
            keep = np.sqrt(np.einsum("ij,ij->i", g, g)) - self.reach[node] <= r[pt]
            pt, node = pt[keep], node[keep]
            leaf = self.left[node] < 0
            found_pt.append(pt[leaf])
            found_node.append(node[leaf])
            pt, first = pt[~leaf], self.left[node[~leaf]]
            pt, node = np.repeat(pt, 2), np.column_stack([first, first + 1]).ravel()
        return np.concatenate(found_pt), np.concatenate(found_node)

    def candidates(self, p: NDArray[np.float64], r: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Triangles that may hold the closest point of p (n, 3) within r (n,): box within the cube
        [p − r, p + r] and ‖centroid − p‖ − radius ≤ r. Returns triangle ids (m,) and their points'
        indices (m,), sorted by point, then by `rank` (the R-tree's order)."""
        pt, leaf = self._leaves(p, r)
        sizes = self.stop[leaf] - self.start[leaf]
        owner = np.repeat(pt, sizes)
        first = np.repeat(self.start[leaf] - np.cumsum(sizes) + sizes, sizes)
        ids = self.perm[first + np.arange(len(owner))]
        gap = self.centroids[ids] - p[owner]
        keep = np.sqrt(np.einsum("ij,ij->i", gap, gap)) - self.radii[ids] <= r[owner]
        ids, owner = ids[keep], owner[keep]
        q, rq = p[owner], r[owner, None]
        keep = np.all(self.lower[ids] <= q + rq, axis=1) & np.all(self.upper[ids] >= q - rq, axis=1)
        ids, owner = ids[keep], owner[keep]
        order = np.argsort(owner * len(self.rank) + self.rank[ids], kind="stable")
        return ids[order], owner[order]


def _ranges(lo: NDArray[np.int64], hi: NDArray[np.int64]) -> tuple[NDArray, NDArray, NDArray]:
    """The positions lo[i] … hi[i] − 1 of every range, concatenated (m,), where each range starts in
    that array (k,), and the range sizes (k,) (all ≥ 1)."""
    sizes = hi - lo
    offsets = np.cumsum(sizes) - sizes
    return np.repeat(lo - offsets, sizes) + np.arange(int(sizes.sum())), offsets, sizes
