"""Choosing coacd's piece cap by measured error: the piece count where the over-cover error stops improving.

For caps k₁ < k₂ < … (coacd's `max_convex_hull`), decompose the mesh at each (`convex._decompose`: a
child process under a time cap, with a progress bar, cached on disk) and measure the over-cover error
e(k), the p99 distance by which the pieces' union reaches beyond the mesh
(`convex.decomposition_error`). The chosen cap is the first k_i whose successor improves the error by
less than `improvement` (a fraction of e(k_i)) or by less than `floor` (m): more pieces would cost
planes (and NLP time) without a better model. A cap whose decomposition gives fewer pieces than the
previous one's cap already gave stops the sweep (coacd found no use for more pieces).

    >>> choice = choose_piece_count(mesh, counts=(1, 2, 4, 8, 16, 32))
    >>> choice.chosen, [(r.cap, r.pieces, r.p99_m) for r in choice.rows]

The plane count of one piece is chosen the same way (`fewest_planes_piece`): the fewest face planes whose
polytope (`convex.simplify_piece`: exact support values, so it contains the hull) reaches at most a
tolerance beyond the piece's hull (`polytope_excess`). The thin-walled shapes' pieces by construction
(`shapes.bowl_pieces`, …) use it: a wall sector spans many mesh facets that a few planes cover.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray

from regrasp_casadi import convex

__all__ = ["PLANE_COUNTS", "PieceCountRow", "PieceCountChoice", "choose_piece_count", "fewest_planes_piece",
           "polytope_excess"]

PLANE_COUNTS = (6, 8, 12, 16, 24, 32, 48, 64)
"""Face-plane caps `fewest_planes_piece` tries, in this order."""


@dataclass(frozen=True)
class PieceCountRow:
    """One decomposition of the sweep."""

    cap: int
    """coacd's `max_convex_hull`."""
    pieces: int
    """Pieces it returned."""
    planes: int
    """Face + edge planes of the simplified pieces (`convex.convex_pieces`' model)."""
    p99_m: float
    """Over-cover error, p99, m (`convex.decomposition_error`)."""
    max_m: float
    """Over-cover error, max, m."""
    seconds: float
    """Wall time of the decomposition (0 for a cache hit), s."""


@dataclass(frozen=True)
class PieceCountChoice:
    """The sweep's rows (by cap, ascending) and the chosen cap."""

    chosen: int
    rows: tuple[PieceCountRow, ...]


def _row(mesh: trimesh.Trimesh, cap: int, threshold: float, max_seconds: float, desc: str) -> PieceCountRow:
    t0 = time.perf_counter()
    vertex_sets = convex._decompose(mesh, threshold, cap, max_seconds=max_seconds, desc=f"{desc} ≤{cap}")
    seconds = time.perf_counter() - t0
    pieces = convex._pieces_of(vertex_sets, convex.DEFAULT_MAX_PLANES, mesh.vertices, desc)
    p99, worst = convex.decomposition_error(mesh, pieces)
    return PieceCountRow(int(cap), len(pieces), int(sum(len(pc.normals) for pc in pieces)), p99, worst,
                         seconds)


def choose_piece_count(mesh: trimesh.Trimesh, counts: Sequence[int] = (1, 2, 4, 8, 16, 32), *,
                       threshold: float = convex.DEFAULT_THRESHOLD, improvement: float = 0.25,
                       floor: float = 2e-4, max_seconds: float = convex.DEFAULT_MAX_SECONDS,
                       name: str = "mesh") -> PieceCountChoice:
    """The cap where the over-cover error stops improving (see the module docstring).

    Args:
        mesh: watertight mesh, m (one shell).
        counts: caps to try, ascending after sorting.
        threshold: coacd's concavity threshold.
        improvement: relative improvement below which a larger cap is not worth it.
        floor: absolute improvement (m) below which a larger cap is not worth it.
        max_seconds: time cap of each decomposition, s.
        name: for the progress bars.
    """
    rows: list[PieceCountRow] = []
    chosen = None
    for cap in sorted({int(c) for c in counts}):
        row = _row(mesh, cap, threshold, max_seconds, name)
        if rows:
            prev = rows[-1]
            gain = prev.p99_m - row.p99_m
            if row.pieces <= prev.pieces or gain < max(improvement * prev.p99_m, floor):
                rows.append(row)
                chosen = prev.cap
                break
        rows.append(row)
    if chosen is None:
        chosen = rows[-1].cap
    return PieceCountChoice(chosen, tuple(rows))


def polytope_excess(piece: convex.ConvexPiece) -> float:
    """How far (m) the polytope {p: N p ≤ h} of a piece reaches beyond the convex hull of its vertices:
    the largest exact distance of the polytope's vertices (scipy's half-space intersection) to the hull
    (trimesh); inf if the polytope is unbounded or degenerate."""
    from scipy.spatial import HalfspaceIntersection, QhullError

    v = np.asarray(piece.vertices, float)
    inside = v.mean(axis=0)
    try:
        halfspaces = np.column_stack([piece.normals, -piece.offsets])
        with np.errstate(divide="ignore", invalid="ignore"):  # an unbounded polytope: inf corners
            corners = HalfspaceIntersection(halfspaces, inside).intersections
    except (QhullError, ValueError):
        return float("inf")
    if not np.all(np.isfinite(corners)) or np.max(np.abs(corners - inside)) > 1e3:
        return float("inf")
    _, dist, _ = trimesh.proximity.closest_point(trimesh.convex.convex_hull(v), corners)
    return float(np.max(dist))


def fewest_planes_piece(vertices: NDArray[np.float64], tolerance: float,
                        counts: Sequence[int] = PLANE_COUNTS) -> convex.ConvexPiece | None:
    """The piece of the hull of `vertices` (v, 3), m, with the fewest face planes among `counts` whose
    polytope reaches at most `tolerance` (m) beyond the hull (`polytope_excess`), without edge planes; the
    largest count's piece if none does; None if the points span no volume."""
    piece = None
    for k in sorted(int(c) for c in counts):
        piece = convex._piece_or_none(vertices, k, edge_planes=False)
        if piece is None or len(piece.normals) < k or polytope_excess(piece) <= tolerance:
            return piece
    return piece
