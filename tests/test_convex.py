"""Tests of regrasp_casadi.convex: pieces, plane caps, edge planes, the decomposition cache, local planes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from random_shapes import random_hull

from regrasp_casadi import convex
from regrasp_casadi.convex import select_local_planes, simplify_piece
from regrasp_casadi.objects import ObjectModel

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference"


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
    assert len(piece.offsets) < convex.DEFAULT_MAX_PLANES + convex.DEFAULT_EDGE_PLANES
    rng = np.random.default_rng(seed + 1)
    lo, hi = obj.mesh.bounds
    pts = rng.uniform(lo - 0.03, hi + 0.03, size=(200, 3))
    exact = obj.exact_signed_distance(pts)
    hard = piece.hard_distance(pts)
    inside = exact < 0
    np.testing.assert_allclose(hard[inside], exact[inside], atol=1e-12)
    assert np.all(hard[~inside] <= exact[~inside] + 1e-12)


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
    assert len(obj.pieces[0].offsets) == convex.DEFAULT_MAX_PLANES
    assert np.all(obj.pieces[0].hard_distance(obj.mesh.vertices) <= 1e-12)


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


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), offset=st.floats(-0.01, 0.03))
def test_one_point_local_planes_give_the_full_hard_distance_there(banana_small, seed, offset):
    """With one point, min over the kept pieces of max over the kept planes is the hard distance of all
    pieces at that point, and the arrays have the fixed NLP-parameter size."""
    obj = banana_small
    pts, normals = obj.sample_surface(1, seed=seed)
    p = pts[0] + offset * normals[0]
    N, H = select_local_planes(obj.pieces, p, n_pieces=2, k=16)
    assert N.shape == (2, 16, 3) and H.shape == (2, 16)
    local_hard = min(float(np.max(N[j] @ p - H[j])) for j in range(2))
    full_hard = min(float(pc.hard_distance(p[None])[0]) for pc in obj.pieces)
    assert local_hard == pytest.approx(full_hard, abs=1e-15)


def test_local_planes_repeat_a_lone_piece():
    box = ObjectModel.box((0.04, 0.06, 0.08))
    N, H = select_local_planes(box.pieces, [0.0, 0.0, 0.05], n_pieces=2, k=4)
    np.testing.assert_array_equal(N[0], N[1])
    np.testing.assert_array_equal(H[0], H[1])
    # the top plane at a point above the box is its +z face, at support value 0.04
    np.testing.assert_allclose(N[0, 0], [0, 0, 1], atol=1e-15)
    assert H[0, 0] == pytest.approx(0.04, abs=1e-15)


def test_decomposition_cache_hit(tmp_path, monkeypatch):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    assert convex.cache_dir() == tmp_path
    n0 = convex.decomposition_count()
    a = ObjectModel.banana(rings=8, sections=8)
    assert convex.decomposition_count() == n0 + 1
    assert len(list((tmp_path / "coacd").glob("*.npz"))) == 1
    b = ObjectModel.banana(rings=8, sections=8)
    assert convex.decomposition_count() == n0 + 1  # second load: no decomposition
    for pa, pb in zip(a.pieces, b.pieces, strict=True):
        np.testing.assert_array_equal(pa.offsets, pb.offsets)


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
    for pc in obj.pieces:  # face planes capped, then at most DEFAULT_EDGE_PLANES edge/vertex planes added
        assert len(pc.offsets) <= convex.DEFAULT_MAX_PLANES + convex.DEFAULT_EDGE_PLANES
        assert np.all(pc.hard_distance(pc.vertices) <= 1e-12)
