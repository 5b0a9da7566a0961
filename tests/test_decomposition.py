"""Tests of the convex decomposition's robustness (regrasp_casadi.convex, regrasp_casadi.coacd_worker): the
cache file checked against the mesh it claims to hold, degenerate pieces dropped, the hull reused for
nearly convex shells, coacd run in a child process under a time cap."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from regrasp_casadi import coacd_worker, convex
from regrasp_casadi.objects import ObjectModel, load_mesh
from regrasp_casadi.shapes import banana_mesh

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference"


def _dented_box(depth: float, side: float = 0.05, height: float = 0.1) -> trimesh.Trimesh:
    """A box whose top face is a shallow inverted pyramid, apex `depth` below the top at the centre."""
    s, h = side / 2, height / 2
    v = [[x, y, z] for z in (-h, h) for y in (-s, s) for x in (-s, s)] + [[0.0, 0.0, h - depth]]
    top = [[4, 5, 8], [5, 7, 8], [7, 6, 8], [6, 4, 8]]
    sides = [[0, 2, 1], [1, 2, 3], [0, 1, 5], [0, 5, 4], [1, 3, 7], [1, 7, 5], [3, 2, 6], [3, 6, 7],
             [2, 0, 4], [2, 4, 6]]
    mesh = trimesh.Trimesh(v, top + sides, process=False)
    trimesh.repair.fix_normals(mesh)
    assert mesh.is_watertight and mesh.volume > 0
    return mesh


def _cache_file(tmp_path: Path) -> Path:
    (path,) = (tmp_path / "coacd").glob("*.npz")
    return path


# ---------------------------------------------------------------- cache integrity
def test_cache_file_holding_another_mesh_is_detected(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    banana = ObjectModel.banana(rings=8, sections=8)
    own = _cache_file(tmp_path)
    shutil.copy(own, tmp_path / "banana.npz")
    own.unlink()
    ObjectModel.bottle(sections=8)
    bottle_file = _cache_file(tmp_path)
    shutil.copy(bottle_file, own)  # a valid file, the bottle's, under the banana's key
    n0 = convex.decomposition_count()
    with caplog.at_level("WARNING"):
        again = ObjectModel.banana(rings=8, sections=8)
    assert "holds another decomposition (its mesh hash differ)" in caplog.text and own.name in caplog.text
    assert convex.decomposition_count() == n0 + 1
    for a, b in zip(banana.pieces, again.pieces, strict=True):
        np.testing.assert_array_equal(a.vertices, b.vertices)


def test_legacy_cache_file_is_checked_against_the_mesh(tmp_path, monkeypatch, caplog):
    """A file of the previous format (pieces only) is accepted when its pieces cover the mesh (and then
    upgraded with the mesh hash) and rejected when they are another object's."""
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    banana = ObjectModel.banana(rings=8, sections=8)
    path = _cache_file(tmp_path)

    def write_legacy(pieces):
        np.savez(path, n=len(pieces), **{f"piece{i}": pc.vertices for i, pc in enumerate(pieces)})

    write_legacy(banana.pieces)
    n0 = convex.decomposition_count()
    ObjectModel.banana(rings=8, sections=8)
    assert convex.decomposition_count() == n0
    with np.load(path) as data:
        assert "mesh_sha256" in data
    box = ObjectModel.box((0.03, 0.2, 0.03))
    write_legacy(box.pieces)
    with caplog.at_level("WARNING"):
        ObjectModel.banana(rings=8, sections=8)
    assert "does not fit this mesh" in caplog.text
    assert convex.decomposition_count() == n0 + 1


# ---------------------------------------------------------------- degenerate pieces
def test_degenerate_coacd_piece_is_dropped(monkeypatch, caplog):
    """A flat piece (coplanar points, as coacd returned on a tuna-can scan) is dropped with a message."""
    cube = trimesh.creation.box(extents=(0.04, 0.04, 0.04))
    rng = np.random.default_rng(0)
    flat = np.c_[rng.uniform(-0.02, 0.02, (30, 2)), np.full(30, 0.02)]  # on the cube's top face
    collinear = np.linspace([0, 0, 0], [0.02, 0.02, 0.02], 7)
    monkeypatch.setattr(convex, "_decompose", lambda *a, **k: [np.array(cube.vertices), flat, collinear])
    with caplog.at_level("WARNING"):
        obj = ObjectModel.from_trimesh(cube, name="can", convex=False)
    assert len(obj.pieces) == 1
    assert "can: dropped 2 degenerate convex piece(s) of 3" in caplog.text
    assert obj.signed_distance([[0.0, 0.0, 0.03]])[0] == pytest.approx(0.01, abs=obj.bias_bound + 1e-9)


def test_only_degenerate_pieces_fall_back_to_the_hull(monkeypatch, caplog):
    cube = trimesh.creation.box(extents=(0.04, 0.04, 0.04))
    monkeypatch.setattr(convex, "_decompose", lambda *a, **k: [np.zeros((5, 3)), np.eye(3)])
    with caplog.at_level("WARNING"):
        pieces = convex.convex_pieces(cube, convex=False, name="flat")
    assert "no convex piece with volume; using the convex hull" in caplog.text
    assert len(pieces) == 1
    np.testing.assert_allclose(np.sort(pieces[0].offsets[:6]), 0.02, atol=1e-15)


# ---------------------------------------------------------------- nearly convex
def test_hull_error_of_a_dented_box():
    depth, side = 0.002, 0.05
    mesh = _dented_box(depth, side)
    excess, dist = convex.hull_error(mesh)
    dent = side * side * depth / 3  # the inverted pyramid's volume
    assert excess == pytest.approx(dent / (side * side * 0.1 - dent), rel=1e-9)
    # the deepest hull-surface point is above the apex: δ·cos φ from the pyramid's faces, tan φ = δ/(s/2);
    # ~200 of the 2000 samples fall on the top face, the best of them within 20 % of the apex's depth
    deepest = depth * np.cos(np.arctan(depth / (side / 2)))
    assert 0.8 * deepest <= dist <= deepest + 1e-12


def test_nearly_convex_shell_is_one_piece(tmp_path, monkeypatch):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    n0 = convex.decomposition_count()
    shallow = ObjectModel.from_trimesh(_dented_box(0.0005))  # 0.5 mm: within 1 mm of its hull
    assert len(shallow.pieces) == 1 and convex.decomposition_count() == n0
    np.testing.assert_allclose(np.sort(shallow.pieces[0].offsets[:6]), [0.025] * 4 + [0.05] * 2, atol=1e-15)
    # the same with the shortcut switched off, and a 3 mm dent: coacd runs
    ObjectModel.from_trimesh(_dented_box(0.0005), hull_tolerance=0.0)
    assert convex.decomposition_count() == n0 + 1
    ObjectModel.from_trimesh(_dented_box(0.003))
    assert convex.decomposition_count() == n0 + 2


@pytest.mark.reference_data
@pytest.mark.parametrize("name", ["001_chips_can", "004_sugar_box", "006_mustard_bottle", "011_banana",
                                  "021_bleach_cleanser"])
def test_ycb_meshes_are_not_replaced_by_their_hull(name):
    """The paper's objects keep their coacd pieces (the chips can's hull is within 2 % in volume but
    2.9 mm from the mesh)."""
    path = REFERENCE / "ycb" / name / "mesh.obj"
    if not path.is_file():
        pytest.skip(f"reference data not present: {path}")
    mesh, _ = load_mesh(path)
    assert not convex.is_near_convex(mesh)


# ---------------------------------------------------------------- child process, time cap
def test_child_process_gives_coacd_s_pieces_silently(capfd):
    import coacd

    mesh = banana_mesh(rings=8, sections=8)
    kwargs = {"threshold": 0.05, "max_convex_hull": 16, "seed": 0}
    child = coacd_worker.run_coacd(mesh.vertices, mesh.faces, kwargs, max_seconds=120)
    coacd.set_log_level("error")
    direct = coacd.run_coacd(coacd.Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces)), **kwargs)
    assert len(child) == len(direct)
    for c, (v, _) in zip(child, direct, strict=True):
        np.testing.assert_array_equal(c, v)
    assert capfd.readouterr().err == ""  # no progress bar when stderr is not a terminal


def test_time_cap_kills_coacd():
    mesh = banana_mesh(rings=8, sections=8)
    t0 = time.monotonic()
    assert coacd_worker.run_coacd(mesh.vertices, mesh.faces, {"threshold": 0.05}, max_seconds=0.05) is None
    assert time.monotonic() - t0 < 5.0


def test_timeouts_fall_back_to_the_hull_and_retry_with_more_time(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))
    mesh = banana_mesh(rings=8, sections=8)
    calls = []
    monkeypatch.setattr(coacd_worker, "run_coacd", lambda v, f, kw, cap, desc: calls.append((kw, cap)))
    with caplog.at_level("WARNING"):
        pieces = convex._decompose(mesh, 0.05, 16, max_seconds=8.0)
    assert [kw.get("mcts_iterations") for kw, _ in calls] == [None, 30]  # full, then cheaper settings
    assert calls[0][1] == pytest.approx(6.0)
    assert "using the convex hull as the only piece" in caplog.text
    np.testing.assert_array_equal(pieces[0], mesh.convex_hull.vertices)
    with np.load(_cache_file(tmp_path)) as data:
        assert float(data["timed_out_after_s"]) == 8.0
    convex._decompose(mesh, 0.05, 16, max_seconds=8.0)  # same budget: the cached fallback
    assert len(calls) == 2
    convex._decompose(mesh, 0.05, 16, max_seconds=20.0)  # more time: try again
    assert len(calls) == 4


def test_decomposition_error_of_an_l_shape():
    """L = [0,2]×[0,1] ∪ [0,1]×[0,2] (× [0,1] in z, scaled to 5 cm): exact pieces have no error; its
    hull bridges the inner corner, the farthest bridged point (1.5, 1.5) lying 1/2 from the L (from
    (1.5, 1) and (1, 1.5))."""
    s = 0.05
    a = trimesh.creation.box(bounds=[[0, 0, 0], [2 * s, s, s]])
    b = trimesh.creation.box(bounds=[[0, s, 0], [s, 2 * s, s]])
    from regrasp_casadi.mesh_repair import union_of_shells

    ell = union_of_shells([a, b])
    exact = [convex.simplify_piece(m.vertices) for m in (a, b)]
    assert convex.decomposition_error(ell, exact)[1] < 1e-9
    p99, worst = convex.decomposition_error(ell, [convex.simplify_piece(ell.vertices)])
    assert 0.95 * s / 2 <= worst <= s / 2 + 1e-12
    assert p99 <= worst
