"""The clearance model of OPT2's non-tip spheres: local plane sets and two-way exact offsets.

Each of the k spheres is given, as NLP parameters, its own small plane set: the `n_pieces` convex pieces
nearest to it and, of each, the `n_planes` planes with the largest values there
(`convex.select_local_planes_batch`, taken at the sphere's centre at the start of the move and, after a
correction, at its last solution too). Its model distance, object frame, m, is

    d_l(p) = s_l(p) + δ⁻_l + δ⁺_l · exp(−|p − c_l|² / σ²)

with s_l the smooth distance (`signed_distance.local_signed_distance`) on those planes, c_l the sphere's
centre at the start, and the exact-distance offset δ_l = e(c_l) − s_l(c_l) split into its negative part
δ⁻ (applied everywhere: where the planes over-estimate the distance the model stays cautious) and its
positive part δ⁺ (where the pieces reach beyond the mesh, e.g. a filled concavity), which fades over σ
(`offset_radius`) away from the start. So at the start the model equals the exact distance e(c_l)
whichever way the pieces err, and a grasp that is feasible on the mesh is feasible in the model; away
from it the model falls back to the pieces' distance. After a solve the exact distances at the solution
decide (`correction`): where the model was optimistic, δ⁻ is lowered by the difference.

Why local sets are safe: dropping planes of a piece only enlarges its polytope (a lower bound of its
distance); a piece left out may become the nearest one away from the start, which the exact check at
the solution catches (the move is corrected or rejected), as for the tips. The cost of the model is
k · n_pieces · n_planes plane evaluations instead of k times all the planes of the object.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.convex import ConvexPiece, select_local_planes_batch
from regrasp_casadi.signed_distance import local_signed_distance

__all__ = ["LocalClearance", "ClearanceParams"]


@dataclass(frozen=True)
class ClearanceParams:
    """Parameter values of the clearance model of k spheres (the blocks of `LocalClearance.blocks`)."""

    normals: NDArray[np.float64]
    """(3·n_pieces·n_planes, k): each column the sphere's plane normals, C order of
    `convex.select_local_planes`, object frame."""
    offsets: NDArray[np.float64]
    """(n_pieces·n_planes, k) support values, m."""
    centres: NDArray[np.float64]
    """(3, k) centres c_l where the positive offsets were taken, object frame, m."""
    delta_minus: NDArray[np.float64]
    """(k,) negative part of the exact offset (≤ 0), m."""
    delta_plus: NDArray[np.float64]
    """(k,) positive part of the exact offset (≥ 0), m, fading over `offset_radius` from `centres`."""

    def blocks(self, prefix: str) -> dict[str, NDArray[np.float64]]:
        """The values keyed by the block names of `LocalClearance.blocks(prefix)`."""
        return {f"{prefix}_normals": self.normals, f"{prefix}_offsets": self.offsets,
                f"{prefix}_centres": self.centres, f"{prefix}_delta_minus": self.delta_minus,
                f"{prefix}_delta_plus": self.delta_plus}


class LocalClearance:
    """The clearance model of k spheres on local plane sets (see the module docstring).

    Args:
        pieces: the object's convex pieces (object frame).
        k: number of spheres.
        n_pieces: pieces per sphere's plane set.
        n_planes: planes per piece.
        tau: smoothing temperature, m.
        offset_radius: σ, m: distance over which a positive offset fades.
    """

    def __init__(self, pieces: tuple[ConvexPiece, ...], k: int, n_pieces: int, n_planes: int, tau: float,
                 offset_radius: float):
        if k < 0 or n_pieces < 1 or n_planes < 1 or not offset_radius > 0:
            raise ValueError(f"LocalClearance needs k ≥ 0, n_pieces ≥ 1, n_planes ≥ 1 and offset_radius > 0; "
                             f"got {k}, {n_pieces}, {n_planes}, {offset_radius}")
        self.pieces, self.k, self.tau, self.sigma = pieces, int(k), float(tau), float(offset_radius)
        self.n_pieces = int(n_pieces)  # an object of fewer pieces repeats its nearest (`select_local_planes`)
        self.n_planes = int(n_planes)
        # one numeric function for the smooth distance s_l and the model d_l at given points
        S = ca.SX.sym("p_object", 3, self.k)
        sym = {name: ca.SX.sym(name, *shape) for name, shape in self.blocks("c").items()}
        raw, model = self.distances(S, sym, "c")
        self._eval = ca.Function("local_clearance", [S, *sym.values()], [raw, model])

    def blocks(self, prefix: str) -> dict[str, tuple[int, ...]]:
        """Parameter blocks (name → shape) of the model, names starting with `prefix`."""
        n = self.n_pieces * self.n_planes
        return {f"{prefix}_normals": (3 * n, self.k), f"{prefix}_offsets": (n, self.k),
                f"{prefix}_centres": (3, self.k), f"{prefix}_delta_minus": (self.k,),
                f"{prefix}_delta_plus": (self.k,)}

    def distances(self, p_object: ca.SX, P: dict, prefix: str) -> tuple[ca.SX, ca.SX]:
        """Symbolic (s_l, d_l) (k, 1) each, m, of the sphere centres `p_object` (3, k), object frame, with
        the parameter blocks `P` (name → symbol) of `blocks(prefix)`."""
        N, H, C = P[f"{prefix}_normals"], P[f"{prefix}_offsets"], P[f"{prefix}_centres"]
        raw = [local_signed_distance(N[:, i], H[:, i], p_object[:, i], self.n_pieces, self.tau)
               for i in range(self.k)]
        raw = ca.vertcat(*raw) if raw else ca.SX(0, 1)
        gap2 = ca.sum1((p_object - C) ** 2).T / self.sigma**2  # (k, 1)
        model = raw + P[f"{prefix}_delta_minus"] + P[f"{prefix}_delta_plus"] * ca.exp(-gap2)
        return raw, model

    def evaluate(self, p_object: NDArray[np.float64], params: ClearanceParams) -> tuple[NDArray, NDArray]:
        """Numeric (s_l, d_l) (k,) each, m, of the centres `p_object` (k, 3), object frame."""
        raw, model = self._eval(np.asarray(p_object, float).T, params.normals, params.offsets, params.centres,
                                params.delta_minus, params.delta_plus)
        return np.asarray(raw, float).ravel(), np.asarray(model, float).ravel()

    def select(self, *points: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Plane sets near each sphere's centres in `points` (each (k, 3), object frame, m): the normals
        (3·n, k) and offsets (n, k) blocks."""
        pts = np.stack([np.asarray(p, float) for p in points], axis=1)  # (k, s, 3)
        N, H = select_local_planes_batch(self.pieces, pts, self.n_pieces, self.n_planes)
        return N.reshape(self.k, -1).T.copy(), H.reshape(self.k, -1).T.copy()

    def at_start(self, p_object: NDArray[np.float64], exact: NDArray[np.float64]) -> ClearanceParams:
        """The model of a move starting with the centres `p_object` (k, 3), object frame, whose exact
        distances are `exact` (k,), m: planes selected there, offsets both ways, so d_l(c_l) = e(c_l)."""
        N, H = self.select(p_object)
        zero = np.zeros(self.k)
        p = ClearanceParams(N, H, np.asarray(p_object, float).T.copy(), zero, zero)
        raw, _ = self.evaluate(p_object, p)
        delta = np.asarray(exact, float) - raw
        return ClearanceParams(N, H, p.centres, np.minimum(delta, 0.0), np.maximum(delta, 0.0))

    def correction(self, start: ClearanceParams, p_start: NDArray, exact_start: NDArray, p_object: NDArray,
                   exact: NDArray) -> ClearanceParams:
        """The model after a solve whose centres are `p_object` (k, 3) with exact distances `exact` (k,):
        planes re-selected near the start and the solution, the two-way offsets at the start again, and δ⁻
        lowered where the model is still above the exact distance at the solution."""
        N, H = self.select(p_start, p_object)
        zero = np.zeros(self.k)
        p = ClearanceParams(N, H, start.centres, zero, zero)
        raw0, _ = self.evaluate(p_start, p)
        delta = np.asarray(exact_start, float) - raw0
        p = ClearanceParams(N, H, start.centres, np.minimum(delta, 0.0), np.maximum(delta, 0.0))
        _, model = self.evaluate(p_object, p)
        lower = np.minimum(np.asarray(exact, float) - model, 0.0)
        return ClearanceParams(N, H, start.centres, p.delta_minus + lower, p.delta_plus)
