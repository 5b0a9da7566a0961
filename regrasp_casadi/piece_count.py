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
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import trimesh

from regrasp_casadi import convex

__all__ = ["PieceCountRow", "PieceCountChoice", "choose_piece_count"]


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
