"""Tests of regrasp_casadi.geometry: convex pieces, smooth and exact signed distance, mesh loading."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from regrasp_casadi import geometry
from regrasp_casadi.errors import MeshError
from regrasp_casadi.geometry import ObjectModel, _smooth_max, simplify_piece

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference"
TAU = geometry.DEFAULT_TAU


@pytest.fixture(scope="module")
def banana_small(tmp_path_factory):
    """A low-resolution banana (coacd, a few pieces) decomposed into a private cache."""
    mp = pytest.MonkeyPatch()
    mp.setenv("REGRASP_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    obj = ObjectModel.banana(rings=10, sections=8)
    mp.undo()
    return obj


def random_hull(seed: int, n: int = 12) -> trimesh.Trimesh:
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * rng.uniform(0.01, 0.06, size=3)
    return trimesh.convex.convex_hull(pts)


def random_rigid(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    T = np.eye(4)
    T[:3, :3] = q
    T[:3, 3] = rng.uniform(-0.5, 0.5, 3)
    return T


# ---------------------------------------------------------------- support-function distance
@settings(max_examples=30, deadline=None)
@given(
    ext=st.tuples(*[st.floats(0.01, 0.3)] * 3),
    u=st.tuples(*[st.floats(-1.5, 1.5)] * 3),
)
def test_box_distances_match_closed_form(ext, u):
    obj = ObjectModel.box(ext)
    half = np.asarray(ext) / 2
    p = (np.asarray(u) * half)[None]
    q = np.abs(p[0]) - half
    closed = np.linalg.norm(np.maximum(q, 0.0)) + min(q.max(), 0.0)
    hard = obj.pieces[0].hard_distance(p)[0]
    assert obj.exact_signed_distance(p)[0] == pytest.approx(closed, abs=1e-12)
    if q.max() <= 0:  # inside: the support-function distance is exact
        assert hard == pytest.approx(closed, abs=1e-12)
    else:
        assert hard <= closed + 1e-12
    smooth = obj.signed_distance(p)[0]
    assert hard - 1e-12 <= smooth <= hard + TAU * np.log(len(obj.pieces[0].offsets)) + 1e-12


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), kind=st.sampled_from(["hull", "cylinder"]))
def test_hard_bound_exact_inside_lower_bound_outside(seed, kind):
    if kind == "hull":
        obj = ObjectModel.from_trimesh(random_hull(seed), convex=True)
    else:
        rng = np.random.default_rng(seed)
        obj = ObjectModel.cylinder(rng.uniform(0.01, 0.05), rng.uniform(0.02, 0.2))
    piece = obj.pieces[0]
    # not simplified: the hull's faces plus edge/vertex planes
    assert len(piece.offsets) < geometry.DEFAULT_MAX_PLANES + geometry.DEFAULT_EDGE_PLANES
    rng = np.random.default_rng(seed + 1)
    lo, hi = obj.mesh.bounds
    pts = rng.uniform(lo - 0.03, hi + 0.03, size=(200, 3))
    exact = obj.exact_signed_distance(pts)
    hard = piece.hard_distance(pts)
    inside = exact < 0
    np.testing.assert_allclose(hard[inside], exact[inside], atol=1e-12)
    assert np.all(hard[~inside] <= exact[~inside] + 1e-12)


@settings(max_examples=50, deadline=None)
@given(
    z=st.lists(st.floats(-0.2, 0.2), min_size=1, max_size=40),
    tau=st.floats(1e-5, 1e-2),
)
def test_log_sum_exp_and_smooth_min_bounds(z, tau):
    z = np.asarray(z)
    k = len(z)
    smax = float(_smooth_max(ca.DM(z), tau))
    smin = -float(_smooth_max(-ca.DM(z), tau))
    slack = 1e-12 + 1e-12 * np.abs(z).max()
    assert z.max() - slack <= smax <= z.max() + tau * np.log(k) + slack
    assert z.min() - tau * np.log(k) - slack <= smin <= z.min() + slack


def test_multi_piece_smooth_distance_within_stated_bounds(banana_small):
    obj = banana_small
    assert len(obj.pieces) >= 2
    rng = np.random.default_rng(3)
    lo, hi = obj.mesh.bounds
    pts = rng.uniform(lo - 0.02, hi + 0.02, size=(300, 3))
    hard = np.stack([pc.hard_distance(pts) for pc in obj.pieces]).min(axis=0)
    smooth = obj.signed_distance(pts)
    k_max = max(len(pc.offsets) for pc in obj.pieces)
    assert np.all(smooth >= hard - TAU * np.log(len(obj.pieces)) - 1e-12)
    assert np.all(smooth <= hard + TAU * np.log(k_max) + 1e-12)
    # outside the object, the smooth value never exceeds the exact distance by more than the bias bound
    exact = obj.exact_signed_distance(pts)
    assert np.all(smooth[exact > 0] <= exact[exact > 0] + obj.bias_bound + 1e-12)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), max_planes=st.integers(4, 40))
def test_simplified_piece_contains_hull(seed, max_planes):
    pts = np.random.default_rng(seed).normal(size=(300, 3)) * 0.03
    piece = simplify_piece(pts, max_planes)
    assert len(piece.offsets) <= max_planes
    np.testing.assert_allclose(np.linalg.norm(piece.normals, axis=1), 1.0, atol=1e-12)
    # every hull vertex (and input point) lies inside every kept half-space, and each plane is tight
    assert np.all(piece.hard_distance(pts) <= 1e-12)
    np.testing.assert_allclose((piece.vertices @ piece.normals.T).max(axis=0), piece.offsets, atol=1e-15)


def test_sphere_is_simplified_to_cap_and_contains_mesh():
    obj = ObjectModel.sphere(0.035)
    assert len(obj.pieces[0].offsets) == geometry.DEFAULT_MAX_PLANES
    assert np.all(obj.pieces[0].hard_distance(obj.mesh.vertices) <= 1e-12)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_rigid_transform_invariance(seed):
    mesh = random_hull(seed)
    T = random_rigid(seed + 7)
    obj = ObjectModel.from_trimesh(mesh, convex=True)
    obj_T = ObjectModel.from_trimesh(mesh.copy().apply_transform(T), convex=True)
    pts = np.random.default_rng(seed).uniform(-0.08, 0.08, size=(50, 3))
    pts_T = trimesh.transform_points(pts, T)
    np.testing.assert_allclose(obj_T.signed_distance(pts_T), obj.signed_distance(pts), atol=1e-10)
    np.testing.assert_allclose(obj_T.exact_signed_distance(pts_T), obj.exact_signed_distance(pts), atol=1e-10)


# ---------------------------------------------------------------- derivatives
def _special_points(obj: ObjectModel) -> np.ndarray:
    m = obj.mesh
    edges = m.vertices[m.edges_unique].mean(axis=1)
    far = np.array([[1.0, 0.0, 0.0], [0.0, -2.0, 3.0]])
    return np.concatenate([m.vertices[:20], edges[:20], [m.centroid], far])


@pytest.mark.parametrize("which", ["box", "cylinder", "banana"])
def test_gradient_and_hessian_finite_at_vertices_edges_centroid(which, box_object, cylinder_object,
                                                                 banana_small):
    obj = {"box": box_object, "cylinder": cylinder_object, "banana": banana_small}[which]
    p = ca.SX.sym("p", 3)
    d = obj.signed_distance_function()(p)
    H, g = ca.hessian(d, p)
    fgh = ca.Function("fgh", [p], [d, g, H])
    for x in _special_points(obj):
        for out in fgh(x):
            assert np.all(np.isfinite(np.asarray(out))), (which, x)


@pytest.mark.parametrize("which", ["box", "cylinder", "banana"])
def test_gradient_matches_central_differences(which, box_object, cylinder_object, banana_small):
    obj = {"box": box_object, "cylinder": cylinder_object, "banana": banana_small}[which]
    tau = 2e-3  # a larger temperature keeps the curvature small enough for finite differences
    f = obj.signed_distance_function(tau)
    p = ca.SX.sym("p", 3)
    fg = ca.Function("fg", [p], [ca.gradient(f(p), p)])
    rng = np.random.default_rng(0)
    lo, hi = obj.mesh.bounds
    h = 1e-6
    for x in rng.uniform(lo - 0.02, hi + 0.02, size=(20, 3)):
        fd = [(float(f(x + h * e)) - float(f(x - h * e))) / (2 * h) for e in np.eye(3)]
        np.testing.assert_allclose(np.asarray(fg(x)).ravel(), fd, atol=1e-5)


# ---------------------------------------------------------------- exact distance
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


# ---------------------------------------------------------------- cache and specs
def test_decomposition_cache_hit(tmp_path, monkeypatch):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    n0 = geometry.decomposition_count()
    a = ObjectModel.banana(rings=8, sections=8)
    assert geometry.decomposition_count() == n0 + 1
    assert len(list((tmp_path / "coacd").glob("*.npz"))) == 1
    b = ObjectModel.banana(rings=8, sections=8)
    assert geometry.decomposition_count() == n0 + 1  # second load: no decomposition
    for pa, pb in zip(a.pieces, b.pieces, strict=True):
        np.testing.assert_array_equal(pa.offsets, pb.offsets)


def test_mesh_file_spec_round_trip(tmp_path, monkeypatch):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path / "cache"))
    mesh = trimesh.creation.cylinder(radius=0.03, height=0.1, sections=12)
    mesh.invert()  # inward winding: from_mesh must repair it
    path = tmp_path / "obj" / "can.stl"
    path.parent.mkdir()
    mesh.export(path)
    obj = ObjectModel.from_mesh(path)
    assert obj.mesh.volume > 0
    assert obj.exact_signed_distance([[0, 0, 0]])[0] == pytest.approx(-0.03 * np.cos(np.pi / 12), abs=1e-9)
    assert obj.spec["mesh"] == str(path.resolve()) and len(obj.spec["sha256"]) == 64
    again = ObjectModel.from_spec({**obj.spec, "mesh": "obj/can.stl"}, base_dir=tmp_path)
    np.testing.assert_array_equal(again.mesh.vertices, obj.mesh.vertices)


@pytest.mark.parametrize("make", [lambda: ObjectModel.box((0.1, 0.2, 0.3)),
                                  lambda: ObjectModel.cylinder(0.02, 0.1),
                                  lambda: ObjectModel.capsule(0.02, 0.05)])
def test_primitive_spec_round_trip(make):
    obj = make()
    again = ObjectModel.from_spec(obj.spec)
    np.testing.assert_array_equal(again.mesh.vertices, obj.mesh.vertices)
    np.testing.assert_array_equal(again.pieces[0].offsets, obj.pieces[0].offsets)


def test_generated_objects_are_watertight_at_ycb_size():
    from regrasp_casadi.shapes import banana_mesh, bottle_mesh

    b = banana_mesh()
    assert b.is_watertight and b.volume > 0
    assert 0.16 < b.extents.max() < 0.19 and 0.034 < b.extents.min() < 0.038
    bt = bottle_mesh()
    assert bt.is_watertight and bt.extents[2] == pytest.approx(0.19)
    assert np.linalg.norm(b.center_mass) < 1e-12


# ---------------------------------------------------------------- bad input
def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_missing_file(tmp_path):
    with pytest.raises(MeshError, match="nope.obj"):
        ObjectModel.from_mesh(tmp_path / "nope.obj")


def test_empty_file(tmp_path):
    p = _write(tmp_path / "empty.obj", "")
    with pytest.raises(MeshError, match="empty.obj"):
        ObjectModel.from_mesh(p)


def test_nan_vertex(tmp_path):
    m = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    v = m.vertices.copy()
    v[0, 0] = np.nan
    p = tmp_path / "nan.ply"
    trimesh.Trimesh(v, m.faces, process=False).export(p)
    with pytest.raises(MeshError, match="nan.ply.*NaN"):
        ObjectModel.from_mesh(p)


def test_unreadable_file(tmp_path):
    p = _write(tmp_path / "junk.obj", "v 1 2\nthis is not a mesh\n")
    with pytest.raises(MeshError, match="junk.obj"):
        ObjectModel.from_mesh(p)


def test_open_mesh(tmp_path):
    m = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    m.update_faces(np.arange(len(m.faces) - 1))
    p = tmp_path / "open.stl"
    m.export(p)
    with pytest.raises(MeshError, match="open.stl.*watertight"):
        ObjectModel.from_mesh(p)


def test_millimetre_mesh(tmp_path):
    p = tmp_path / "mm.stl"
    trimesh.creation.box(extents=(50.0, 90.0, 175.0)).export(p)
    with pytest.raises(MeshError, match=r"mm.stl.*scale=0.001"):
        ObjectModel.from_mesh(p)
    assert ObjectModel.from_mesh(p, scale=0.001).mesh.extents.max() == pytest.approx(0.175)


# ---------------------------------------------------------------- YCB reference meshes
@pytest.mark.reference_data
@pytest.mark.slow
@pytest.mark.parametrize("name", ["011_banana", "004_sugar_box"])
def test_ycb_mesh_pieces_contain_surface(name):
    path = REFERENCE / "ycb" / name / "mesh.obj"
    if not path.is_file():
        pytest.skip(f"reference data not present: {path}")
    obj = ObjectModel.from_mesh(path)
    pts, _ = obj.sample_surface(2000, seed=0)
    assert np.abs(obj.exact_signed_distance(pts)).max() <= 1e-9
    for pc in obj.pieces:
        assert len(pc.offsets) <= geometry.DEFAULT_MAX_PLANES
        assert np.all(pc.hard_distance(pc.vertices) <= 1e-12)


def test_mx_and_sx_functions_agree(banana_small):
    pts = np.random.default_rng(5).uniform(-0.1, 0.1, size=(3, 40))
    sx = banana_small.signed_distance_function().map(40)(pts)
    mx = banana_small.signed_distance_function(symbolic="MX").map(40)(pts)
    np.testing.assert_allclose(np.asarray(mx), np.asarray(sx), atol=1e-14)


@pytest.mark.parametrize("suffix", ["obj", "stl", "ply", "glb"])
def test_formats_and_repair(tmp_path, monkeypatch, suffix):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    box = trimesh.creation.box(extents=(0.04, 0.06, 0.08))
    # a duplicated face and unmerged vertices: both are repaired on load
    faces = np.concatenate([box.faces, box.faces[:1]])
    raw = trimesh.Trimesh(box.vertices[faces].reshape(-1, 3), np.arange(3 * len(faces)).reshape(-1, 3),
                          process=False)
    path = tmp_path / f"box.{suffix}"
    raw.export(path)
    obj = ObjectModel.from_mesh(path)
    assert len(obj.mesh.faces) == 12 and obj.mesh.is_watertight
    assert obj.name == "box"
    d = obj.exact_signed_distance([[0, 0, 0], [0.05, 0, 0]])
    np.testing.assert_allclose(d, [-0.02, 0.03], atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(phi=st.floats(0.0, np.pi / 2), along=st.floats(-0.9, 0.9), radius=st.floats(0.002, 0.03))
def test_edge_planes_tighten_the_bound_around_box_edges(phi, along, radius):
    """Around an edge, the hard bound is within r(1 − cos(step/2)) of the exact distance (closed form),
    where the face planes alone would read as little as r·cos 45°."""
    ext = np.array([0.05, 0.07, 0.12])
    obj = ObjectModel.box(ext)
    half = ext / 2
    edge_point = np.array([half[0], half[1], along * half[2]])  # on the +x/+y edge
    p = edge_point + radius * np.array([np.cos(phi), np.sin(phi), 0.0])
    hard = obj.pieces[0].hard_distance(p[None])[0]
    step = np.radians(20.0)
    assert hard <= radius + 1e-12
    assert hard >= radius * np.cos(step / 2) - 1e-12


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
