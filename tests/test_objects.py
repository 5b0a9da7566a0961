"""Tests of regrasp_casadi.objects: mesh loading and repair, primitives, specs, the `ObjectModel` facade."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from random_shapes import random_hull, random_rigid

from regrasp_casadi.errors import MeshError
from regrasp_casadi.objects import ObjectModel


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


# ---------------------------------------------------------------- specs
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


def test_inline_mesh_spec_round_trip():
    mesh = random_hull(3)
    obj = ObjectModel.from_trimesh(mesh, name="rock", convex=True, max_planes_per_piece=8)
    again = ObjectModel.from_spec(obj.spec)
    np.testing.assert_array_equal(again.mesh.vertices, mesh.vertices)
    np.testing.assert_array_equal(again.pieces[0].normals, obj.pieces[0].normals)


def test_unknown_primitive_is_a_mesh_error():
    with pytest.raises(MeshError, match="torus"):
        ObjectModel.from_spec({"primitive": "torus", "radius": 0.1})


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


def test_hyphenated_mesh_file_builds_its_distances(tmp_path, monkeypatch):
    """A file named like a YCB object ("sugar-box.stl") gives an object of that name whose smooth
    distances build (CasADi rejects such function names unless they are made valid)."""
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    path = tmp_path / "sugar-box.stl"
    trimesh.creation.box(extents=(0.05, 0.09, 0.175)).export(path)
    obj = ObjectModel.from_mesh(path)
    assert obj.name == "sugar-box"
    assert float(obj.signed_distance_function()([0.0, 0.0, 0.1])) == pytest.approx(0.0125, abs=1e-6)
    assert float(obj.clearance_distance_function()([0.0, 0.0, 0.1])) == pytest.approx(0.0125, abs=1e-6)


@pytest.mark.parametrize("scale", [0, 0.0, -0.001, float("nan"), float("inf"), "0.001", None, True])
def test_bad_scale_names_the_argument_and_file(tmp_path, scale):
    path = tmp_path / "cube.stl"
    trimesh.creation.box(extents=(0.04, 0.04, 0.04)).export(path)
    message = rf"cube.stl: scale: expected a positive finite number .*got {scale!r}"
    with pytest.raises(MeshError, match=message):
        ObjectModel.from_mesh(path, scale=scale)
    with pytest.raises(MeshError, match=r"cube.stl: scale: expected a positive finite number"):
        ObjectModel.from_spec({"mesh": str(path), "scale": scale})


@pytest.mark.parametrize("kind", ["bowl", "cup", "mug", "flat_tool", "holed_box"])
def test_new_primitive_specs_rebuild_the_same_mesh(kind, monkeypatch):
    """The generated objects' specs rebuild them (pieces not compared: no coacd run here)."""
    from regrasp_casadi import objects

    monkeypatch.setattr(objects, "convex_pieces", lambda mesh, *a, **k: ())
    obj = getattr(ObjectModel, kind)()
    assert obj.spec["primitive"] == kind and obj.name == kind
    again = ObjectModel.from_spec(obj.spec)
    np.testing.assert_array_equal(again.mesh.vertices, obj.mesh.vertices)
    np.testing.assert_array_equal(again.mesh.faces, obj.mesh.faces)
