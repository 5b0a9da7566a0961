"""Decomposition that scales: the piece cap chosen by measured over-cover error (an L-shape, whose exact
decomposition is two boxes), and the single hull kept for a near-convex object."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from regrasp_casadi import convex
from regrasp_casadi.mesh_repair import union_of_shells
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.piece_count import choose_piece_count


@pytest.fixture()
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("REGRASP_CACHE_DIR", str(tmp_path))


def _ell(s: float = 0.05) -> trimesh.Trimesh:
    a = trimesh.creation.box(bounds=[[0, 0, 0], [2 * s, s, s]])
    b = trimesh.creation.box(bounds=[[0, s, 0], [s, 2 * s, s]])
    return union_of_shells([a, b])


def test_piece_cap_stops_where_the_error_stops_improving(cache):
    s = 0.05
    choice = choose_piece_count(_ell(s), (1, 2, 4, 8))
    errors = [r.p99_m for r in choice.rows]
    # monotone: more pieces never over-cover more (within 0.1 mm)
    assert all(b <= a + 1e-4 for a, b in zip(errors, errors[1:], strict=False))
    one = choice.rows[0]
    assert one.pieces == 1
    # one piece is the hull: it bridges the inner corner by up to s/2 (closed form, see test_decomposition)
    assert 0.9 * s / 2 <= one.max_m <= s / 2 + 1e-9
    # two pieces are exact (the two boxes), so the sweep stops there
    assert choice.chosen == 2
    assert choice.rows[1].max_m < 1e-4
    assert len(choice.rows) == 3  # the cap of 4 was tried and did not help


def _wavy_sphere(radius: float = 0.04, amplitude: float = 2e-4) -> trimesh.Trimesh:
    m = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    v = m.vertices
    wave = np.sin(7 * np.arctan2(v[:, 1], v[:, 0])) * np.sin(5 * v[:, 2] / radius)
    bumps = 1.0 + (amplitude / radius) * wave
    return trimesh.Trimesh(v * bumps[:, None], m.faces, process=True)


def test_near_convex_object_reuses_its_single_hull(cache):
    mesh = _wavy_sphere()
    assert not mesh.is_convex
    n0 = convex.decomposition_count()
    obj = ObjectModel.from_trimesh(mesh)
    assert convex.decomposition_count() == n0  # coacd never ran
    assert len(obj.pieces) == 1
    piece_hull = trimesh.convex.convex_hull(obj.pieces[0].vertices)
    assert piece_hull.volume == pytest.approx(mesh.convex_hull.volume, rel=1e-9)
