"""The smooth signed distance (CasADi): one log-sum-exp core for every distance the NLPs use.

For a convex piece C with unit outward normals n_i and support values h_i = max_v n_i·v (see
`regrasp_casadi.convex`), the smooth distance is ``d_C(p) = τ·LSE((n_i·p − h_i)/τ)`` with
``LSE(y) = m + log Σ_i exp(y_i − m)``, m = max y (`log_sum_exp`). It satisfies
``max_i(n_i·p − h_i) ≤ d_C(p) ≤ max_i(n_i·p − h_i) + τ·log k``; the hard max is the exact signed distance
inside C and a lower bound outside. Pieces are combined with a smooth minimum
``d(p) = −τ·LSE(−d_C(p)/τ)`` with ``min_C d_C − τ·log P ≤ d ≤ min_C d_C`` (`smooth_union`). So outside the
smooth value exceeds the exact distance by at most ``τ·log k_max`` (k_max: the largest plane count of a
piece). For a sphere of radius r the distance is d − r (callers subtract it).

Four distances are built from this core:

* `pieces_distance_function`: the full model p_object (3,1) -> d, m (`ObjectModel.signed_distance_function`);
  the normals and offsets are divided by τ before they enter the graph (one operation less per plane);
* the coarse clearance distance: the same on `convex.coarse_pieces`
  (`ObjectModel.clearance_distance_function`);
* `local_signed_distance`: the same model on a few planes passed as NLP parameters
  (`convex.select_local_planes`);
* `hull_signed_distance`: one polytope, the workspace hull of a finger (OPT2-SD), ``τ·LSE(s/τ)`` evaluated as
  ``m + τ·log Σ exp((s − m)/τ)`` on the plane values s.

Accuracy (benchmarks/geometry.py): on convex primitives with ≤ 64 facets the smooth distance is within
0.14 mm of the exact one on the surface (τ's bias only). Capping each piece at `convex.DEFAULT_MAX_PLANES`
(64) planes changes the YCB surface error by < 0.25 mm; the error there is the decomposition's: p99
1.7–4.2 mm at threshold 0.05, 0.4–1.3 mm at 0.02 (9–16 pieces). Inside a non-convex object the union of
pieces under-estimates the penetration depth (min over pieces); the planner corrects contacts with the
exact distance (`regrasp_casadi.exact_distance`).

    >>> f = pieces_distance_function("sd_box", obj.pieces, DEFAULT_TAU)   # p_object (3,1) -> d (1,1), m
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.convex import ConvexPiece

__all__ = [
    "DEFAULT_TAU",
    "function_name",
    "log_sum_exp",
    "smooth_max",
    "smooth_min",
    "smooth_union",
    "pieces_distance_function",
    "local_signed_distance",
    "hull_signed_distance",
    "smoothing_bias",
]

DEFAULT_TAU = 2e-4
"""Default smoothing temperature τ, m. Bias on a face ≈ 0, on an edge τ·log 2 = 0.14 mm, at a 3-face
vertex τ·log 3 = 0.22 mm; the worst-case bound is τ·log k (0.83 mm for k = 64 planes)."""

def function_name(*parts: str) -> str:
    """A valid CasADi function name from `parts` joined by "_", e.g. ("sd", "sugar-box") -> "sd_sugar_box".

    CasADi accepts a letter followed by letters, digits and single underscores: every run of other
    characters (non-ASCII letters included) becomes one "_", leading/trailing ones are dropped, and a
    name that would not start with a letter, or that CasADi reserves ("null", "jac", "hess"), gets an "f"
    in front.
    """
    name = re.sub(r"[^A-Za-z0-9]+", "_", "_".join(parts)).strip("_")
    if not name[:1].isalpha() or name in _RESERVED_NAMES:
        name = "f" + name
    return name


_RESERVED_NAMES = frozenset({"null", "jac", "hess"})
"""Names CasADi refuses for a Function although they are valid identifiers (found by hypothesis)."""


# ---------------------------------------------------------------------------- the core
def log_sum_exp(z: ca.SX | ca.MX, tau: float | None = None) -> ca.SX | ca.MX:
    """Smooth max of the entries of `z` (n, 1): τ·log Σ_i exp(z_i/τ), computed as
    ``m + τ·log Σ exp((z − m)/τ)`` with m = max z (no overflow, log argument ≥ 1; finite value and
    derivatives everywhere). `tau=None` is the unit form ``m + log Σ exp(z − m)`` (no scaling operations).

    Bounds: ``max z ≤ log_sum_exp(z, τ) ≤ max z + τ·log n``. A single entry is returned as it is.
    """
    if z.numel() == 1:
        return z
    m = ca.mmax(z)
    if tau is None:
        return m + ca.log(ca.sum1(ca.exp(z - m)))
    return m + tau * ca.log(ca.sum1(ca.exp((z - m) / tau)))


def smooth_max(z: ca.SX | ca.MX, tau: float) -> ca.SX | ca.MX:
    """τ·log Σ exp(z/τ) of `z` (n, 1), in [max z, max z + τ·log n]."""
    return log_sum_exp(z, tau)


def smooth_min(z: ca.SX | ca.MX, tau: float) -> ca.SX | ca.MX:
    """−τ·log Σ exp(−z/τ) of `z` (n, 1), in [min z − τ·log n, min z]."""
    return -log_sum_exp(-z, tau)


def smooth_union(plane_values: Sequence[ca.SX | ca.MX], tau: float) -> ca.SX | ca.MX:
    """Smooth distance to a union of convex pieces from each piece's plane values divided by τ.

    Args:
        plane_values: per piece, y_C = (n_i·p − h_i)/τ (k_C, 1).
        tau: temperature τ, m.

    Returns:
        ``−τ·LSE(−[LSE(y_C)]_C)`` (1, 1), m: the smooth minimum over pieces of d_C = τ·LSE(y_C).
    """
    d_pieces_over_tau = [log_sum_exp(y) for y in plane_values]
    return -tau * log_sum_exp(-ca.vertcat(*d_pieces_over_tau))


# ---------------------------------------------------------------------------- the four distances
def pieces_distance_function(name: str, pieces: Sequence[ConvexPiece], tau: float,
                             symbolic: str = "SX") -> ca.Function:
    """Smooth distance p_object (3,1) -> d (1,1), m, to the union of `pieces` (object frame).

    Args:
        name: function name (made valid with `function_name`, e.g. "sd_sugar-box" -> "sd_sugar_box").
        pieces: convex pieces, object frame.
        tau: temperature τ, m.
        symbolic: "SX" (scalar graph, best for few planes and for embedding in SX NLPs) or "MX" (matrix
            graph; about 2.5× faster value+gradient at ~250 planes, see benchmarks/geometry.py); both give
            the same values.
    """
    if symbolic not in ("SX", "MX"):
        raise ValueError(f"symbolic must be 'SX' or 'MX', not {symbolic!r}")
    p = getattr(ca, symbolic).sym("p_object", 3)
    # normals and offsets pre-divided by τ: one operation less per plane
    ys = [ca.mtimes(ca.DM(piece.normals / tau), p) - ca.DM(piece.offsets / tau) for piece in pieces]
    return ca.Function(function_name(name), [p], [smooth_union(ys, tau)], ["p_object"], ["d"])


def local_signed_distance(normals: ca.SX, offsets: ca.SX, p: ca.SX, n_pieces: int, tau: float) -> ca.SX:
    """Smooth signed distance (1,) of `p` (3,) from local plane sets passed as parameters.

    `normals` is (n_pieces·k·3,) and `offsets` (n_pieces·k,), laid out as `ObjectModel.local_planes`
    returns them (C order). Per piece τ·LSE((n_i·p − h_i)/τ), then a smooth minimum over the pieces:
    the same model as `ObjectModel.signed_distance_function`, restricted to the planes near `p`.
    """
    k = offsets.shape[0] // n_pieces
    ys = []
    for j in range(n_pieces):
        N = ca.reshape(normals[3 * k * j: 3 * k * (j + 1)], 3, k).T  # (k, 3): rows are normals
        ys.append((N @ p - offsets[k * j: k * (j + 1)]) / tau)
    return smooth_union(ys, tau)


def hull_signed_distance(normals: NDArray[np.float64], offsets: NDArray[np.float64], p: ca.SX,
                         tau: float) -> ca.SX:
    """Smooth signed distance (1,) of point `p` (3,) to the convex polytope {x : n_i·x ≤ h_i}.

    d(p) = τ · log Σ_i exp((n_i·p − h_i)/τ), the max of the plane distances subtracted first for
    numerical safety; exact inside up to τ·log k, a lower bound of the Euclidean distance outside.
    """
    return log_sum_exp(ca.DM(normals) @ p - ca.DM(offsets), tau)


def smoothing_bias(pieces: Sequence[ConvexPiece], tau: float = DEFAULT_TAU) -> float:
    """τ·log k_max, m: how far the smooth value may exceed the hard plane bound of `pieces`."""
    return tau * float(np.log(max(len(p.offsets) for p in pieces)))
