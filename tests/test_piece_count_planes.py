"""Tests of `piece_count.polytope_excess` and `fewest_planes_piece`: the excess of a simplified piece's
polytope over its hull is their Hausdorff distance, checked against support functions computed by linear
programs (scipy's linprog) over many directions; the chosen plane count is the fewest that meets the
tolerance."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.optimize import linprog

from regrasp_casadi import convex
from regrasp_casadi.piece_count import PLANE_COUNTS, fewest_planes_piece, polytope_excess


def _support_gap(piece: convex.ConvexPiece, n_dirs: int = 400) -> float:
    """max over random unit u of h_P(u) − h_C(u): the polytope's support by LP, the hull's from its
    vertices. For nested convex bodies C ⊂ P this is a lower bound of (and tends to) their Hausdorff
    distance."""
    rng = np.random.default_rng(0)
    u = rng.normal(size=(n_dirs, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    u = np.vstack([u, piece.normals])
    gap = 0.0
    for d in u:
        res = linprog(-d, A_ub=piece.normals, b_ub=piece.offsets, bounds=[(None, None)] * 3, method="highs")
        assert res.status == 0
        gap = max(gap, -res.fun - float(np.max(piece.vertices @ d)))
    return gap


def _cylinder_vertices(sections: int = 48) -> np.ndarray:
    return np.asarray(trimesh.creation.cylinder(radius=0.03, height=0.02, sections=sections).vertices)


def test_box_needs_six_planes_and_has_no_excess():
    box = np.asarray(trimesh.creation.box(extents=(0.02, 0.03, 0.05)).vertices)
    piece = fewest_planes_piece(box, 1e-6)
    assert len(piece.normals) == 6
    assert polytope_excess(piece) <= 1e-9


@pytest.mark.parametrize("k", [8, 12, 16])
def test_excess_is_the_hausdorff_distance(k):
    """On a 48-sided prism cut down to k planes, the excess (polytope corners to the hull) matches the
    largest support-function gap found by LP (the Hausdorff distance of nested convex bodies)."""
    piece = convex.simplify_piece(_cylinder_vertices(), k)
    excess = polytope_excess(piece)
    gap = _support_gap(piece)
    assert gap <= excess + 1e-9
    assert gap >= 0.8 * excess


def test_fewest_planes_meets_the_tolerance_and_one_count_less_does_not():
    tol = 5e-4
    v = _cylinder_vertices()
    piece = fewest_planes_piece(v, tol)
    k = len(piece.normals)
    assert _support_gap(piece) <= tol + 1e-9
    smaller = [c for c in PLANE_COUNTS if c < k]
    assert smaller, "a 48-sided prism within 0.5 mm needs more than the smallest count"
    assert _support_gap(convex.simplify_piece(v, smaller[-1])) > tol


def test_flat_points_give_no_piece():
    square = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [0.01, 0.01, 0]], float)
    assert fewest_planes_piece(square, 1e-3) is None
