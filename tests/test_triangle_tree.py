"""Tests of regrasp_casadi.triangle_tree and of the exact-distance steps built on it, against the code they
replace: trimesh's R-tree box query pruned by the bounding spheres, the loops of the pseudo-normals and
the sort that picked the closest candidate."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from regrasp_casadi.exact_distance import ExactDistance, _first_minima
from regrasp_casadi.triangle_tree import TriangleTree, rtree_rank


def _meshes_mm() -> list[trimesh.Trimesh]:
    torus = trimesh.creation.torus(major_radius=50.0, minor_radius=20.0, major_sections=96, minor_sections=24)
    bumpy = trimesh.creation.icosphere(subdivisions=4, radius=30.0)
    rng = np.random.default_rng(3)
    bumpy.vertices *= rng.uniform(0.9, 1.1, size=(len(bumpy.vertices), 1))
    box = trimesh.creation.box(extents=(50.0, 90.0, 175.0))  # long thin triangles, many ties
    return [torus, bumpy, box]


def _queries(mesh: trimesh.Trimesh, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    surface, _ = trimesh.sample.sample_surface(mesh, 200, seed=seed)
    return np.vstack([surface, surface + rng.normal(0.0, 2.0, surface.shape),
                      surface + rng.normal(0.0, 20.0, surface.shape), mesh.vertices[:100] * 1.05,
                      rng.uniform(*(mesh.bounds + [[-30.0] * 3, [30.0] * 3]), size=(200, 3))])


def _rtree_candidates(mesh, p, r):
    """The replaced code: box query of the R-tree, then the bounding-sphere prune (order kept)."""
    tris = np.array(mesh.triangles)
    centroids = tris.mean(axis=1)
    radii = np.max(np.linalg.norm(tris - centroids[:, None], axis=2), axis=1)
    ids, counts = mesh.triangles_tree.intersection_v(p - r[:, None], p + r[:, None])
    ids = np.asarray(ids, dtype=np.int64)
    owner = np.repeat(np.arange(len(p)), np.asarray(counts, dtype=np.int64))
    gap = centroids[ids] - p[owner]
    keep = np.sqrt(np.einsum("ij,ij->i", gap, gap)) - radii[ids] <= r[owner]
    return ids[keep], owner[keep]


@pytest.mark.parametrize("k", range(3))
def test_candidates_are_the_rtree_ones_in_its_order(k):
    mesh = _meshes_mm()[k]
    tris = np.array(mesh.triangles)
    tree = TriangleTree(tris, rank=rtree_rank(mesh.triangles_tree, tris))
    p = _queries(mesh, k)
    for r in (cKDTree(mesh.vertices).query(p)[0] + 1e-8, np.full(len(p), 3.0)):
        ids, owner = tree.candidates(p, r)
        ref_ids, ref_owner = _rtree_candidates(mesh, p, r)
        np.testing.assert_array_equal(ids, ref_ids)
        np.testing.assert_array_equal(owner, ref_owner)


def test_every_triangle_within_reach_is_a_candidate():
    """Independent of the R-tree: every triangle whose exact distance is ≤ r is among the candidates."""
    mesh = _meshes_mm()[0]
    tris = np.array(mesh.triangles)
    tree = TriangleTree(tris)
    p = _queries(mesh, 9)[::7]
    r = np.random.default_rng(9).uniform(0.5, 25.0, size=len(p))
    ids, owner = tree.candidates(p, r)
    found = set(zip(owner.tolist(), ids.tolist(), strict=True))
    for i, pi in enumerate(p):
        close = trimesh.triangles.closest_point(tris, np.repeat(pi[None], len(tris), axis=0))
        within = np.flatnonzero(np.linalg.norm(close - pi, axis=1) <= r[i])
        assert all((i, int(t)) in found for t in within)
    assert np.all(np.diff(owner) >= 0)


def test_rtree_rank_needs_one_box_per_triangle():
    mesh = _meshes_mm()[1]
    tris = np.array(mesh.triangles)
    with pytest.raises(ValueError, match="one box per triangle"):
        rtree_rank(mesh.triangles_tree, tris[:-5])


def _pseudo_normals_loop(exact: ExactDistance, c_mm, tri):
    """The replaced loops of `ExactDistance._pseudo_normals`."""
    m = exact._mesh_mm
    bary = trimesh.triangles.points_to_barycentric(exact._triangles_mm[tri], c_mm)
    small = bary < 1e-7
    n = m.face_normals[tri].copy()
    n_small = small.sum(axis=1)
    for i in np.nonzero(n_small == 1)[0]:
        k = int(np.argmax(small[i]))
        n[i] = exact._edge_normals[m.faces_unique_edges[tri[i], (k + 1) % 3]]
    for i in np.nonzero(n_small >= 2)[0]:
        n[i] = exact._vertex_normals[m.faces[tri[i], int(np.argmax(bary[i]))]]
    return n


def test_pseudo_normals_match_the_loops_on_faces_edges_and_vertices():
    mesh = _meshes_mm()[1].copy().apply_scale(1e-3)
    exact = ExactDistance(mesh)
    edges = mesh.vertices[mesh.edges_unique].mean(axis=1)
    p = np.vstack([mesh.vertices * 1.02, edges * 1.02, _queries(mesh.copy().apply_scale(1e3), 5) * 1e-3])
    c, _, tri = exact.closest(p)
    c_mm = c * 1000.0
    bary_small = (trimesh.triangles.points_to_barycentric(exact._triangles_mm[tri], c_mm) < 1e-7).sum(axis=1)
    assert (bary_small == 1).sum() > 50 and (bary_small >= 2).sum() > 50  # edges and vertices are tested
    np.testing.assert_array_equal(exact._pseudo_normals(c_mm, tri), _pseudo_normals_loop(exact, c_mm, tri))


def test_first_minima_is_the_stable_sort():
    rng = np.random.default_rng(2)
    owner = np.sort(np.concatenate([np.arange(300), rng.integers(0, 300, 2000)]))
    d2 = rng.integers(0, 5, len(owner)).astype(float)  # many ties
    starts = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=300))[:-1]])
    np.testing.assert_array_equal(_first_minima(d2, owner, 300), np.lexsort((d2, owner))[starts])
    d2[[3, 40]] = np.nan
    np.testing.assert_array_equal(_first_minima(d2, owner, 300), np.lexsort((d2, owner))[starts])


def _build_loop(tree: TriangleTree, tris: np.ndarray):
    """The replaced node-by-node build: (perm, start, stop, left, centre, reach)."""
    from regrasp_casadi.triangle_tree import _SLACK, LEAF_SIZE

    perm = np.arange(len(tris))
    start, stop, left = [0], [len(tris)], [-1]
    k = 0
    while k < len(start):
        lo, hi = start[k], stop[k]
        if hi - lo > LEAF_SIZE:
            sub = perm[lo:hi]
            c = tree.centroids[sub]
            axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
            perm[lo:hi] = sub[np.argsort(c[:, axis], kind="stable")]
            mid = (lo + hi) // 2
            left[k] = len(start)
            start += [lo, mid]
            stop += [mid, hi]
            left += [-1, -1]
        k += 1
    centre, reach = np.empty((len(start), 3)), np.empty(len(start))
    for k, (lo, hi) in enumerate(zip(start, stop, strict=True)):
        sub = perm[lo:hi]
        v = tris[sub].reshape(-1, 3)
        centre[k] = 0.5 * (v.min(axis=0) + v.max(axis=0))
        reach[k] = np.max(np.linalg.norm(tree.centroids[sub] - centre[k], axis=1) + tree.radii[sub])
    return perm, np.array(start), np.array(stop), np.array(left), centre, reach * (1.0 + 1e-12) + _SLACK


@pytest.mark.parametrize("k", range(3))
def test_level_by_level_build_is_the_node_by_node_one(k):
    mesh = _meshes_mm()[k]
    tris = np.array(mesh.triangles)
    tree = TriangleTree(tris)
    for got, want in zip((tree.perm, tree.start, tree.stop, tree.left, tree.centre, tree.reach),
                         _build_loop(tree, tris), strict=True):
        np.testing.assert_array_equal(got, want)
    small = TriangleTree(tris[:5])  # one leaf
    assert small.left.tolist() == [-1] and small.stop.tolist() == [5]
