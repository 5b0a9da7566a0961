"""Tests of the thin-walled shapes' convex pieces by construction (`shapes.bowl_pieces`, `cup_pieces`,
`mug_pieces`) and of the `ObjectModel`s built on them: the pieces' union covers the mesh (scipy's hulls,
independent of `ConvexPiece`), it reaches beyond the mesh by no more than the chord sag of the
construction (trimesh's exact distance against closed forms), and the model's distance follows the
exact one near the surface."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from regrasp_casadi import shapes
from regrasp_casadi.objects import WALL_TOLERANCE, ObjectModel

KINDS = ("bowl", "cup", "mug")


def _hull_depth(points: np.ndarray, vertex_sets: list[np.ndarray]) -> np.ndarray:
    """Per point (n, 3), the smallest over the hulls (scipy) of max_i (n_i·p + d_i): ≤ 0 inside one."""
    out = np.full(len(points), np.inf)
    for v in vertex_sets:
        eq = ConvexHull(v).equations
        out = np.minimum(out, np.max(points @ eq[:, :3].T + eq[:, 3], axis=1))
    return out


def _overcover(mesh: trimesh.Trimesh, vertex_sets: list[np.ndarray], n: int = 200) -> float:
    """Largest exact distance (m) outside the mesh of `n` samples on each hull's surface."""
    worst = 0.0
    for k, v in enumerate(vertex_sets):
        pts, _ = trimesh.sample.sample_surface(trimesh.convex.convex_hull(v), n, seed=k)
        outside = -trimesh.proximity.signed_distance(mesh, pts)  # trimesh: positive inside
        worst = max(worst, float(np.max(outside)))
    return worst


@pytest.fixture(scope="module", params=KINDS)
def walled(request):
    kind = request.param
    return kind, getattr(shapes, f"{kind}_mesh")(), getattr(shapes, f"{kind}_pieces")()


def test_pieces_cover_the_mesh(walled):
    """Every vertex and 3000 surface samples of the mesh lie in some piece's hull (within 1 µm)."""
    _, mesh, pieces = walled
    pts, _ = trimesh.sample.sample_surface(mesh, 3000, seed=3)
    assert np.max(_hull_depth(np.vstack([mesh.vertices, pts]), pieces)) <= 1e-6


def test_pieces_reach_beyond_the_mesh_by_at_most_their_chords(walled):
    """Along the profile and around the axis, each chord is within the tolerance; at a piece's corner the
    two add up: the union stays within 2 × tolerance of the mesh (trimesh's exact distance)."""
    _, mesh, pieces = walled
    assert _overcover(mesh, pieces) <= 2 * WALL_TOLERANCE


def test_cup_overcover_is_the_inner_chord_sag():
    """The cup's wall sectors span 2π/K with K the fewest (a power of two) whose chord at the outer
    radius R dips ≤ tolerance: their hulls reach (R − w)(1 − cos(π/K)) into the cup (closed form)."""
    R, w, tol = 0.04, 0.004, 1.5e-3
    k = 2
    while R * (1 - np.cos(np.pi / k)) > tol:
        k *= 2
    pieces = shapes.cup_pieces(radius=R, wall=w, tolerance=tol)
    assert len(pieces) == 1 + k  # the bottom disc and K wall sectors
    sag = (R - w) * (1 - np.cos(np.pi / k))
    measured = _overcover(shapes.cup_mesh(radius=R, wall=w), pieces, n=400)
    assert 0.9 * sag <= measured <= sag + 1e-6


def test_bowl_polar_cap_meets_the_tolerance():
    """The bowl's first piece is its polar cap: the hull fills the cavity down to the plane of its top
    inner circle, (R − w)(1 − cos φ₀) deep, φ₀ = g₀·(π/2)/segments ≤ the tolerance (closed form)."""
    R, w, seg = 0.06, 0.004, 24
    cap = shapes.bowl_pieces(radius=R, wall=w, segments=seg)[0]
    mesh = shapes.bowl_mesh(radius=R, wall=w, segments=seg)
    g0 = int(np.floor(np.arccos(1 - WALL_TOLERANCE / (R - w)) / (np.pi / 2 / seg)))
    depth = (R - w) * (1 - np.cos(g0 * np.pi / 2 / seg))
    assert depth <= WALL_TOLERANCE
    assert _overcover(mesh, [cap], n=2000) <= depth + 1e-6


@pytest.mark.parametrize("kind", KINDS)
def test_model_distance_follows_the_exact_one_near_the_walls(kind):
    """The model's hard distance (the pieces' planes) at surface samples and 2 mm out along the normal
    is within 2 × tolerance of trimesh's exact signed distance."""
    obj = getattr(ObjectModel, kind)()
    pts, face = trimesh.sample.sample_surface(obj.mesh, 1500, seed=5)
    for offset in (0.0, 0.002):
        q = pts + offset * obj.mesh.face_normals[face]
        exact = -trimesh.proximity.signed_distance(obj.mesh, q)
        hard = np.min([pc.hard_distance(q) for pc in obj.pieces], axis=0)
        assert np.max(np.abs(hard - exact)) <= 2 * WALL_TOLERANCE


def test_tolerance_round_trips_through_the_spec():
    """A non-default tolerance is kept in the spec and rebuilds the same pieces."""
    obj = ObjectModel.cup(tolerance=3e-3)
    assert obj.spec["tolerance"] == 3e-3
    again = ObjectModel.from_spec(obj.spec)
    assert len(again.pieces) == len(obj.pieces)
    for a, b in zip(again.pieces, obj.pieces, strict=True):
        np.testing.assert_array_equal(a.vertices, b.vertices)


def test_unknown_decomposition_is_an_error():
    with pytest.raises(ValueError, match="decomposition must be 'walls' or 'coacd', not 'voxels'"):
        ObjectModel.bowl(decomposition="voxels")


@pytest.mark.parametrize("kind", KINDS)
def test_clearance_model_is_a_lower_bound_outside(kind):
    """The clearance pieces contain the mesh, so outside it their hard distance never exceeds the exact
    distance (trimesh) and, by their construction at CLEARANCE_WALL_FACTOR × tolerance, undershoots it by
    at most twice that tolerance near the surface."""
    from regrasp_casadi.objects import CLEARANCE_WALL_FACTOR

    obj = getattr(ObjectModel, kind)()
    assert obj.clearance_pieces is not None
    pts, face = trimesh.sample.sample_surface(obj.mesh, 1500, seed=6)
    q = pts + np.random.default_rng(0).uniform(0.0, 0.02, (len(pts), 1)) * obj.mesh.face_normals[face]
    exact = -trimesh.proximity.signed_distance(obj.mesh, q)
    hard = np.min([pc.hard_distance(q) for pc in obj.clearance_pieces], axis=0)
    outside = exact > 0
    assert np.all(hard[outside] <= exact[outside] + 1e-9)
    assert np.max(exact - hard) <= 2 * CLEARANCE_WALL_FACTOR * WALL_TOLERANCE
