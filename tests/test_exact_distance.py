"""Tests of regrasp_casadi.exact_distance: exact closest points, pseudo-normal signs, near distance."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from random_shapes import random_hull

from regrasp_casadi.exact_distance import ExactDistance
from regrasp_casadi.objects import ObjectModel


@pytest.mark.parametrize("make", [ObjectModel.box, lambda: ObjectModel.bottle(sections=16),
                                  ObjectModel.sphere])
def test_exact_distance_of_surface_samples_is_zero(make, tmp_path, monkeypatch):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    obj = make()
    pts, normals = obj.sample_surface(500, seed=1)
    assert np.abs(obj.exact_signed_distance(pts)).max() <= 1e-9
    closest, d = obj.closest_points(pts)
    np.testing.assert_allclose(closest, pts, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)


def test_exact_sign_and_normals_on_box(box_object):
    pts, normals = box_object.sample_surface(200, seed=2)
    away = pts + 0.002 * normals
    into = pts - 0.002 * normals
    half = np.array([0.025, 0.045, 0.0875])
    closed = lambda p: np.linalg.norm(np.maximum(np.abs(p) - half, 0), axis=1) + np.minimum(  # noqa: E731
        (np.abs(p) - half).max(axis=1), 0)
    np.testing.assert_allclose(box_object.exact_signed_distance(away), closed(away), atol=1e-12)
    np.testing.assert_allclose(box_object.exact_signed_distance(into), closed(into), atol=1e-12)
    np.testing.assert_allclose(box_object.surface_normals(away), normals, atol=1e-12)


def test_exact_sign_at_vertex_and_edge_regions(box_object):
    half = np.array([0.025, 0.045, 0.0875])
    # diagonally outside a corner and an edge: the closest feature is a vertex / edge
    pts = np.array([half + 0.01, [0.0, half[1] + 0.01, half[2] + 0.01], [0.0, 0.0, 0.0]])
    d = box_object.exact_signed_distance(pts)
    np.testing.assert_allclose(d, [np.sqrt(3) * 0.01, np.sqrt(2) * 0.01, -half.min()], atol=1e-12)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_matches_trimesh_on_a_millimetre_mesh_and_its_inside_test(seed):
    """Against an independent reference: trimesh's own closest point on the millimetre copy (where its
    tolerance is harmless) for the distance, and its ray-parity `contains` for the sign."""
    mesh = random_hull(seed)
    exact = ExactDistance(mesh)
    rng = np.random.default_rng(seed)
    lo, hi = mesh.bounds
    pts = rng.uniform(lo - 0.02, hi + 0.02, size=(100, 3))
    closest, d = exact.closest_points(pts)
    mesh_mm = mesh.copy().apply_scale(1000.0)
    ref_closest, ref_dist, _ = trimesh.proximity.closest_point(mesh_mm, pts * 1000.0)
    np.testing.assert_allclose(np.abs(d), ref_dist / 1000.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(closest - ref_closest / 1000.0, axis=1), 0.0, atol=1e-9)
    clear = np.abs(d) > 1e-6  # the parity test is unreliable on the surface itself
    np.testing.assert_array_equal(d[clear] < 0, mesh.contains(pts[clear]))


def test_near_signed_distance_is_exact_near_and_a_bound_far():
    obj = ObjectModel.banana()
    rng = np.random.default_rng(4)
    pts, normals = obj.sample_surface(200, seed=4)
    offsets = rng.uniform(-0.01, 0.05, size=len(pts))
    p = pts + offsets[:, None] * normals
    near = rng.uniform(0.005, 0.03, size=len(pts))  # one threshold per point, as for spheres of radii
    approx = obj.near_signed_distance(p, near)
    exact = obj.exact_signed_distance(p)
    close = exact <= near
    np.testing.assert_allclose(approx[close], exact[close], atol=1e-12)  # exact wherever it matters
    estimated = approx != exact
    assert np.all(approx[estimated] > near[estimated])  # elsewhere an estimate beyond `near` ...
    # ... of a point that is really beyond `near`, up to the pieces' error (≤ 2 mm on this object)
    assert np.all(exact[estimated] > near[estimated] - 0.002)


def test_near_signed_distance_needs_pieces(box_object):
    with pytest.raises(ValueError, match="pieces"):
        ExactDistance(box_object.mesh).near_signed_distance([[0.0, 0.0, 0.0]])


def test_matches_trimesh_on_a_fine_non_convex_mesh_far_and_near():
    """On a finely tessellated torus (non-convex, 4,608 faces), points on, near, inside and up to 6 cm
    from the surface get trimesh's distances and closest points (the tree's pruning keeps the closest
    triangle)."""
    mesh = trimesh.creation.torus(major_radius=0.05, minor_radius=0.02, major_sections=96, minor_sections=24)
    exact = ExactDistance(mesh)
    rng = np.random.default_rng(7)
    surface, _ = trimesh.sample.sample_surface(mesh, 300, seed=7)
    pts = np.vstack([surface, surface + rng.normal(0.0, 0.002, surface.shape),
                     surface + rng.normal(0.0, 0.03, surface.shape)])
    closest, d = exact.closest_points(pts)
    ref_closest, ref_dist, _ = trimesh.proximity.closest_point(mesh.copy().apply_scale(1000.0), pts * 1000.0)
    np.testing.assert_allclose(np.abs(d), ref_dist / 1000.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(closest - ref_closest / 1000.0, axis=1), 0.0, atol=1e-9)


def test_remembered_answers_are_the_computed_ones(monkeypatch):
    """`closest` answers repeated points (within a call and across calls) from its cache bit for bit as a
    fresh object computes them, and starts again when the cache is full."""
    from regrasp_casadi import exact_distance

    mesh = trimesh.creation.torus(major_radius=0.05, minor_radius=0.02, major_sections=48, minor_sections=16)
    rng = np.random.default_rng(11)
    pts = rng.uniform(-0.08, 0.08, size=(300, 3))
    reference = ExactDistance(mesh).closest(pts)
    monkeypatch.setattr(exact_distance, "CACHE_SIZE", 250)
    exact = ExactDistance(mesh)
    exact.closest(pts[::3])
    mixed = np.vstack([pts[:150], pts[:10], pts[150:]])  # cached, repeated and new points
    for got, ref in zip(exact.closest(mixed), reference, strict=True):
        np.testing.assert_array_equal(np.delete(got, np.s_[150:160], axis=0), ref)
        np.testing.assert_array_equal(got[150:160], ref[:10])
    assert len(exact._cache) <= 250
    exact.clear_cache()
    assert not exact._cache
    for got, ref in zip(exact.closest(pts), reference, strict=True):
        np.testing.assert_array_equal(got, ref)
    assert exact.closest(pts[:1])[2].dtype == np.int64


def _pseudo_normals_loop(exact: ExactDistance, c_mm, tri):
    """The pseudo-normals of `ExactDistance._pseudo_normals` written as loops over the points."""
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
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.03)
    rng = np.random.default_rng(3)
    mesh.vertices *= rng.uniform(0.9, 1.1, size=(len(mesh.vertices), 1))  # bumpy: edges and vertices matter
    exact = ExactDistance(mesh)
    edges = mesh.vertices[mesh.edges_unique].mean(axis=1)
    surface, _ = trimesh.sample.sample_surface(mesh, 200, seed=5)
    p = np.vstack([mesh.vertices * 1.02, edges * 1.02, surface + rng.normal(0.0, 0.002, surface.shape)])
    c, _, tri = exact.closest(p)
    c_mm = c * 1000.0
    bary_small = (trimesh.triangles.points_to_barycentric(exact._triangles_mm[tri], c_mm) < 1e-7).sum(axis=1)
    assert (bary_small == 1).sum() > 50 and (bary_small >= 2).sum() > 50  # edges and vertices are tested
    np.testing.assert_array_equal(exact._pseudo_normals(c_mm, tri), _pseudo_normals_loop(exact, c_mm, tri))


def test_pickled_copy_gives_the_same_answers():
    """An `ExactDistance` (and the `ObjectModel` holding it) pickles: the tree is rebuilt on loading and
    answers as the original, bit for bit."""
    import pickle

    obj = ObjectModel.box()
    pts = np.random.default_rng(12).uniform(-0.1, 0.1, size=(200, 3))
    reference = obj.exact.closest(pts)
    copy = pickle.loads(pickle.dumps(obj))
    copy.exact.clear_cache()
    for got, ref in zip(copy.exact.closest(pts), reference, strict=True):
        np.testing.assert_array_equal(got, ref)


def test_normals_on_a_box_edge_and_corner_are_the_bisectors(box_object):
    """On an edge of the box (closest point on it), the normal is the bisector of its two faces; at a
    corner the three faces' mean (equal angles π/2): closed forms, whichever triangle the tree names."""
    half = np.array([0.025, 0.045, 0.0875])
    pts = np.array([[0.0, half[1] + 0.01, half[2] + 0.02],  # off the y-z edge, nearer the z face
                    [half[0] + 0.03, 0.0, -half[2] - 0.01],  # off the x-(−z) edge
                    half + [0.01, 0.02, 0.03],  # off the corner
                    [0.0, 0.0, half[2] + 0.01]])  # off the middle of the +z face
    expected = np.array([[0.0, 1.0, 1.0], [1.0, 0.0, -1.0], [1.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(box_object.surface_normals(pts), expected, atol=1e-12)
