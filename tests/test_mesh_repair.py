"""Tests of regrasp_casadi.mesh_repair and of the repairs `ObjectModel.from_mesh` applies: overlapping and
nested shells (union), self-intersecting shells (rejected), shells touching at a corner (two pieces)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from regrasp_casadi.errors import MeshError
from regrasp_casadi.mesh_repair import genus, repair_shells, self_intersections, shells
from regrasp_casadi.objects import ObjectModel, load_mesh

A = 0.04  # side of the test cubes, m


def _cube(offset=(0.0, 0.0, 0.0), side=A) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=(side, side, side)).apply_translation(offset)


def _figure_eight_tube(radius=0.004, n_ring=96, n_tube=12) -> trimesh.Trimesh:
    """A closed tube (one shell, torus topology) swept along a planar figure-eight: it passes through
    itself where the centre line crosses, at the origin."""
    t = np.linspace(0, 2 * np.pi, n_ring, endpoint=False)
    c = np.stack([0.05 * np.sin(2 * t), 0.06 * np.sin(t), 0 * t], axis=1)
    tangent = np.stack([0.1 * np.cos(2 * t), 0.06 * np.cos(t), 0 * t], axis=1)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.cross([0.0, 0.0, 1.0], tangent)
    a = np.linspace(0, 2 * np.pi, n_tube, endpoint=False)
    ring = (c[:, None] + radius * np.cos(a)[None, :, None] * normal[:, None]
            + radius * np.sin(a)[None, :, None] * np.array([0.0, 0.0, 1.0]))
    faces = []
    for i in range(n_ring):
        for j in range(n_tube):
            p, q = i * n_tube + j, i * n_tube + (j + 1) % n_tube
            r, s = ((i + 1) % n_ring) * n_tube + j, ((i + 1) % n_ring) * n_tube + (j + 1) % n_tube
            faces += [[p, r, q], [q, r, s]]
    mesh = trimesh.Trimesh(ring.reshape(-1, 3), faces, process=False)
    trimesh.repair.fix_normals(mesh)
    return mesh


# ---------------------------------------------------------------- detection
def test_clean_meshes_have_no_self_intersections():
    for mesh in (_cube(), trimesh.creation.icosphere(3), trimesh.creation.capsule(),
                 trimesh.creation.torus(1, 0.3)):
        assert len(self_intersections(mesh)) == 0


def test_overlapping_cubes_are_found_and_touching_ones_are_not():
    overlap = trimesh.util.concatenate([_cube(), _cube((0.02, 0.01, 0.005))])
    pairs = self_intersections(overlap)
    assert len(pairs) > 0
    # every reported pair has one face of each cube
    assert np.all((pairs[:, 0] < 12) & (pairs[:, 1] >= 12))
    apart = trimesh.util.concatenate([_cube(), _cube((A + 1e-4, 0.0, 0.0))])
    assert len(self_intersections(apart)) == 0
    corner = trimesh.util.concatenate([_cube(), _cube((A, A, A))])
    corner.merge_vertices()  # one shared vertex; faces meeting only there do not intersect
    assert len(self_intersections(corner)) == 0
    assert len(shells(corner)) == 2


def test_figure_eight_tube_intersects_itself():
    tube = _figure_eight_tube()
    assert tube.is_watertight and len(shells(tube)) == 1 and genus(tube) == 1
    pairs = self_intersections(tube)
    assert len(pairs) > 0
    # the crossing faces are near the origin, where the centre line crosses itself
    centres = tube.triangles_center[pairs.ravel()]
    assert np.abs(centres[:, :2]).max() < 0.01


# ---------------------------------------------------------------- repair through from_mesh
def test_overlapping_boxes_in_one_file_become_their_union(tmp_path, caplog):
    shift = np.array([0.02, 0.01, 0.005])
    path = tmp_path / "two_boxes.obj"
    trimesh.util.concatenate([_cube(), _cube(shift)]).export(path)
    with caplog.at_level("WARNING"):
        mesh, _ = load_mesh(path)
    assert "two_boxes.obj" in caplog.text and "union" in caplog.text
    obj = ObjectModel.from_trimesh(mesh, convex=True)  # the exact distance is the mesh's (no coacd run)
    overlap = np.prod(A - shift)
    assert obj.mesh.is_watertight and len(shells(obj.mesh)) == 1
    assert obj.mesh.volume == pytest.approx(2 * A**3 - overlap, rel=1e-9)
    # p lies in the overlap. Concatenated, A's face x = 0.02 is buried 10 mm from it; in the union the
    # nearest surface point is the concave edge (0.02, y, -0.015) of B's bottom and A's side: 18.03 mm.
    p = np.array([[0.01, 0.005, 0.0]])
    assert obj.exact_signed_distance(p)[0] == pytest.approx(-np.hypot(0.01, 0.015), abs=1e-9)
    # signs agree with the analytic union on a grid
    g = np.stack(np.meshgrid(*[np.linspace(-0.03, 0.05, 9)] * 3), axis=-1).reshape(-1, 3) + 1e-4
    inside = np.all(np.abs(g) < A / 2, axis=1) | np.all(np.abs(g - shift) < A / 2, axis=1)
    np.testing.assert_array_equal(obj.exact_signed_distance(g) < 0, inside)


def test_nested_shell_is_absorbed(tmp_path, monkeypatch):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path / "cache"))
    path = tmp_path / "nested.stl"
    inner = _cube(side=0.01)
    inner.invert()  # a cavity, wound inwards
    trimesh.util.concatenate([_cube(), inner]).export(path)
    obj = ObjectModel.from_mesh(path)  # STL: float32 coordinates
    assert obj.mesh.volume == pytest.approx(A**3, rel=1e-6)
    assert obj.exact_signed_distance([[0.0, 0.0, 0.0]])[0] == pytest.approx(-A / 2, abs=1e-8)


def test_self_intersecting_shell_is_rejected_naming_the_file(tmp_path):
    path = tmp_path / "eight.ply"
    _figure_eight_tube().export(path)
    with pytest.raises(MeshError, match=r"eight.ply: the surface intersects itself"):
        ObjectModel.from_mesh(path)


def test_boxes_touching_at_a_corner_are_two_pieces(tmp_path, monkeypatch):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path / "cache"))
    path = tmp_path / "corner.obj"
    trimesh.util.concatenate([_cube(), _cube((A, A, A))]).export(path)
    obj = ObjectModel.from_mesh(path)
    assert len(obj.pieces) == 2
    # (0.03, 0.01, 0.02) is 10 mm from either cube but inside the hull of both
    p = np.array([[0.03, 0.01, 0.02]])
    assert bool(obj.mesh.convex_hull.contains(p)[0])
    assert obj.exact_signed_distance(p)[0] == pytest.approx(0.01, abs=1e-12)
    hard = min(float(pc.hard_distance(p)[0]) for pc in obj.pieces)
    assert hard == pytest.approx(0.01, abs=1e-9)
    assert obj.signed_distance(p)[0] == pytest.approx(0.01, abs=obj.bias_bound + 1e-9)


def test_disjoint_inward_shell_is_turned_outward():
    inner = _cube((0.1, 0.0, 0.0))
    inner.invert()
    mesh = trimesh.util.concatenate([_cube(), inner])
    fixed = repair_shells(mesh, "two.obj")
    assert fixed.volume == pytest.approx(2 * A**3, rel=1e-9)
    assert len(shells(fixed)) == 2
