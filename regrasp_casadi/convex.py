"""Convex pieces of an object: half-space form, plane caps, the coacd decomposition cache, local plane sets.

A convex piece C is stored as half-spaces n_i·p ≤ h_i with unit outward normals n_i and exact support
values h_i = max_v n_i·v over its hull vertices, so the polytope always contains the hull. Its *hard
distance* ``max_i (n_i·p − h_i)`` is the exact signed distance inside C and a lower bound outside; the
smooth CasADi distance built on it lives in `regrasp_casadi.signed_distance`.

Non-convex meshes are split by coacd once and the pieces cached on disk, keyed by the mesh's content and
the decomposition parameters (`cache_dir()`, `decomposition_count()`).

Only numpy, trimesh and coacd (imported when a decomposition runs) are used here; no CasADi.

    >>> pieces = convex_pieces(mesh, convex=None)          # tuple[ConvexPiece, ...], object frame, m
    >>> N, H = select_local_planes(pieces, p_object_tip)    # (2, 16, 3), (2, 16): planes near the tip
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import pathlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "ConvexPiece",
    "DEFAULT_THRESHOLD",
    "DEFAULT_MAX_PLANES",
    "DEFAULT_EDGE_PLANES",
    "DEFAULT_MAX_PIECES",
    "LOCAL_PIECES",
    "LOCAL_PLANES",
    "add_edge_planes",
    "cache_dir",
    "coarse_pieces",
    "convex_pieces",
    "decomposition_count",
    "select_local_planes",
    "simplify_piece",
]

log = logging.getLogger(__name__)

DEFAULT_THRESHOLD = 0.05
"""coacd concavity threshold (smaller: more, finer pieces)."""
DEFAULT_MAX_PLANES = 64
"""Cap on the planes of one convex piece after simplification (bounds the expression size)."""
DEFAULT_EDGE_PLANES = 96
"""Extra edge/vertex support planes per piece (see `add_edge_planes`)."""
DEFAULT_MAX_PIECES = 16
"""Cap on the number of convex pieces coacd may return (its `max_convex_hull`)."""
LOCAL_PIECES = 2
"""Pieces in a local plane set (see `select_local_planes`)."""
LOCAL_PLANES = 16
"""Planes per piece in a local plane set."""

_COUNTERS = {"decompositions": 0}


def decomposition_count() -> int:
    """Number of coacd decompositions run in this process (cache hits do not count)."""
    return _COUNTERS["decompositions"]


def cache_dir() -> pathlib.Path:
    """Directory of the decomposition cache: ``$REGRASP_CACHE_DIR`` or ``~/.cache/regrasp_casadi``."""
    env = os.environ.get("REGRASP_CACHE_DIR")
    if env:
        return pathlib.Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or (pathlib.Path.home() / ".cache")
    return pathlib.Path(base) / "regrasp_casadi"


@dataclass(frozen=True)
class ConvexPiece:
    """One convex piece as half-spaces n_i·p ≤ h_i that contain its hull."""

    normals: NDArray[np.float64]
    """(k, 3) unit outward normals, object frame."""
    offsets: NDArray[np.float64]
    """(k,) support values h(n_i) = max_v n_i·v over the hull vertices, m."""
    vertices: NDArray[np.float64]
    """(v, 3) hull vertices, object frame, m."""

    def hard_distance(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """max_i (n_i·p − h_i) for points (n, 3), m: exact inside, a lower bound outside. Returns (n,)."""
        return np.max(np.asarray(points, float) @ self.normals.T - self.offsets, axis=1)


# ---------------------------------------------------------------------------- plane sets of one piece
def _merged_face_planes(hull: trimesh.Trimesh) -> tuple[NDArray, NDArray, NDArray]:
    """Coplanar faces of a convex hull merged: unit normals (g, 3), group of each face (f,), areas (g,)."""
    # on a convex hull, faces with the same normal lie in the same support plane
    _, group_of_face = np.unique(np.round(hull.face_normals, 9), axis=0, return_inverse=True)
    group_of_face = group_of_face.ravel()
    n_groups = int(group_of_face.max()) + 1
    areas = np.bincount(group_of_face, weights=hull.area_faces, minlength=n_groups)
    largest = np.full(n_groups, -1)
    order = np.argsort(hull.area_faces)  # the largest face of each group wins (written last)
    largest[group_of_face[order]] = order
    normals = np.array(hull.face_normals[largest])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return normals, group_of_face, areas


def _greedy_planes(hull: trimesh.Trimesh, normals: NDArray, group_of_face: NDArray, areas: NDArray,
                   max_planes: int, n_samples: int) -> list[int]:
    """Indices of at most `max_planes` of the merged planes: the largest one, then repeatedly the plane of
    the hull-surface sample lying deepest inside the current polytope."""
    hv = hull.vertices
    samples, fidx = trimesh.sample.sample_surface(hull, n_samples, seed=0)
    samples = np.concatenate([samples, hull.triangles_center, hv])
    # a hull vertex belongs to several planes: assign it the first face that uses it
    vface = np.full(len(hv), -1)
    vface[hull.faces[::-1].ravel()] = np.repeat(np.arange(len(hull.faces))[::-1], 3)
    sample_plane = group_of_face[np.concatenate([fidx, np.arange(len(hull.faces)), vface])]
    h_all = np.max(hv @ normals.T, axis=0)
    chosen = [int(np.argmax(areas))]
    depth = -(samples @ normals[chosen[0]] - h_all[chosen[0]])
    while len(chosen) < max_planes:
        worst = int(np.argmax(depth))
        if depth[worst] <= 0.0:
            break
        j = int(sample_plane[worst])
        if j in chosen:  # numerically tight already
            depth[worst] = 0.0
            continue
        chosen.append(j)
        depth = np.minimum(depth, -(samples @ normals[j] - h_all[j]))
    return chosen


def simplify_piece(
    vertices: NDArray[np.float64], max_planes: int = DEFAULT_MAX_PLANES, n_samples: int = 2000
) -> ConvexPiece:
    """Half-space form of the convex hull of `vertices`, with at most `max_planes` planes.

    Coplanar hull faces are merged. If more than `max_planes` remain, a subset of the facet normals is
    chosen greedily: start with the largest facet, then repeatedly add the facet of the hull-surface
    sample lying deepest inside the current polytope. Every kept plane uses the hull's exact support
    value, so the simplified polytope always contains the hull (it never shrinks the piece).

    Args:
        vertices: (v, 3) points, object frame, m.
        max_planes: largest number of planes kept.
        n_samples: hull-surface samples that guide the greedy choice.

    Returns:
        The piece with unit normals (k, 3), offsets (k,) and hull vertices.
    """
    hull = trimesh.convex.convex_hull(np.asarray(vertices, float))
    normals, group_of_face, areas = _merged_face_planes(hull)
    hv = hull.vertices
    if len(normals) > max_planes:
        normals = normals[_greedy_planes(hull, normals, group_of_face, areas, max_planes, n_samples)]
    offsets = np.max(hv @ normals.T, axis=0)
    return ConvexPiece(normals=normals, offsets=offsets, vertices=np.array(hv))


def _edge_plane_candidates(hull: trimesh.Trimesh, step: float) -> list[tuple[float, NDArray[np.float64]]]:
    """(priority, unit direction) of the edge and vertex directions of `add_edge_planes`."""
    fn = hull.face_normals
    candidates: list[tuple[float, NDArray[np.float64]]] = []
    for (a, b) in hull.face_adjacency:
        angle = float(np.arccos(np.clip(fn[a] @ fn[b], -1.0, 1.0)))
        if angle <= step:
            continue
        k = int(np.ceil(angle / step))
        for j in range(1, k):  # slerp between the two face normals
            t = j / k
            u = (np.sin((1 - t) * angle) * fn[a] + np.sin(t * angle) * fn[b]) / np.sin(angle)
            candidates.append((angle, u / np.linalg.norm(u)))
    vertex_faces = hull.vertex_faces
    for v in range(len(hull.vertices)):
        faces = vertex_faces[v][vertex_faces[v] >= 0]
        u = fn[faces].sum(axis=0)
        spread = float(np.max(np.arccos(np.clip(fn[faces] @ (u / np.linalg.norm(u)), -1, 1))))
        if spread > step:
            candidates.append((2 * spread, u / np.linalg.norm(u)))
    candidates.sort(key=lambda c: -c[0])
    return candidates


def add_edge_planes(piece: ConvexPiece, max_extra: int = DEFAULT_EDGE_PLANES,
                    step: float = np.radians(20.0)) -> ConvexPiece:
    """Tighten a piece's distance bound outside, near its edges and corners, with extra support planes.

    For a convex body C, d(p) = max over unit u of (u·p − h_C(u)) outside C; the face normals alone give
    only a lower bound that is worst near edges (a point 14 mm out along the bisector of a 90° edge reads
    as 9.9 mm). Here each hull edge whose dihedral angle exceeds `step` gets directions interpolated
    between its two face normals (every `step`), and each hull vertex the normalised mean of its faces'
    normals, all with exact support values h_C(u) = max_v u·v. Inside C every added plane reads at most
    the true (negative) distance, so the value inside is unchanged; the piece still contains the hull.

    Args:
        piece: the piece (face planes).
        max_extra: cap on the added planes (the edges with the largest dihedral angles first).
        step: angular spacing of the added directions, rad.

    Returns:
        A piece with the face planes followed by the added planes.
    """
    if max_extra <= 0:
        return piece
    hull = trimesh.convex.convex_hull(piece.vertices)
    normals = list(piece.normals)
    added = 0
    for _, u in _edge_plane_candidates(hull, step):
        if added >= max_extra:
            break
        if max(float(u @ n) for n in normals) > np.cos(np.radians(2.0)):
            continue  # a direction this close is there already
        normals.append(u)
        added += 1
    N = np.array(normals)
    return ConvexPiece(normals=N, offsets=np.max(piece.vertices @ N.T, axis=0), vertices=piece.vertices)


def coarse_pieces(pieces: Sequence[ConvexPiece], max_planes: int) -> list[ConvexPiece]:
    """Each piece re-simplified to at most `max_planes` planes (pieces already that small are kept).

    Exact support values, so each coarse piece contains its piece: its hard distance is a lower bound of
    the fine piece's (used for the clearance distance, where only d ≥ β matters).
    """
    return [pc if len(pc.normals) <= max_planes else simplify_piece(pc.vertices, max_planes) for pc in pieces]


# ---------------------------------------------------------------------------- decomposition and cache
def _mesh_hash(mesh: trimesh.Trimesh) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype="<i8").tobytes())
    return h.hexdigest()


def _decompose(mesh: trimesh.Trimesh, threshold: float, max_pieces: int, seed: int = 0) -> list[NDArray]:
    """coacd convex pieces (list of (v, 3) vertex arrays, m), cached on disk by content + parameters."""
    import coacd

    params = {"threshold": float(threshold), "max_convex_hull": int(max_pieces), "seed": int(seed),
              "coacd": getattr(coacd, "__version__", "?"), "format": 1}
    key = hashlib.sha256((_mesh_hash(mesh) + json.dumps(params, sort_keys=True)).encode()).hexdigest()
    path = cache_dir() / "coacd" / f"{key}.npz"
    if path.is_file():
        try:
            with np.load(path) as data:
                pieces = [data[f"piece{i}"] for i in range(int(data["n"]))]
            log.debug("convex decomposition cache hit %s", path)
            return pieces
        except Exception as exc:  # corrupt cache file: recompute
            log.warning("ignoring unreadable cache file %s (%s)", path, exc)
    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces)),
                            threshold=float(threshold), max_convex_hull=int(max_pieces), seed=int(seed))
    _COUNTERS["decompositions"] += 1
    pieces = [np.asarray(v, float) for v, _ in parts]
    log.info("coacd decomposition: %d pieces (threshold %g), cached at %s", len(pieces), threshold, path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, n=len(pieces), **{f"piece{i}": v for i, v in enumerate(pieces)})
        os.replace(tmp, path)
    except OSError as exc:
        log.warning("could not write decomposition cache %s: %s", path, exc)
    return pieces


def convex_pieces(
    mesh: trimesh.Trimesh,
    convex: bool | None = None,
    threshold: float = DEFAULT_THRESHOLD,
    max_planes_per_piece: int = DEFAULT_MAX_PLANES,
    max_pieces: int = DEFAULT_MAX_PIECES,
) -> tuple[ConvexPiece, ...]:
    """The convex pieces of a watertight mesh (metres, object frame), each simplified and edge-tightened.

    Args:
        mesh: watertight mesh, m, object frame.
        convex: True: one piece, the hull; False: coacd (cached); None: decide by `mesh.is_convex`.
        threshold: coacd concavity threshold.
        max_planes_per_piece: face-plane cap of each piece (`simplify_piece`), before `add_edge_planes`.
        max_pieces: cap on coacd pieces.
    """
    if convex is None:
        convex = bool(mesh.is_convex)
    verts = [np.asarray(mesh.vertices)] if convex else _decompose(mesh, threshold, max_pieces)
    return tuple(add_edge_planes(simplify_piece(v, max_planes_per_piece)) for v in verts)


# ---------------------------------------------------------------------------- local plane sets
def select_local_planes(pieces: Sequence[ConvexPiece], points: ArrayLike, n_pieces: int = LOCAL_PIECES,
                 k: int = LOCAL_PLANES) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The planes that decide the distance near `points`: a fixed-size set for NLP parameters.

    The `n_pieces` pieces nearest to the points (smallest hard distance) and, of each, the `k` planes
    with the largest values n·p − h over the points (the planes that are the max there). Missing
    pieces or planes repeat the first one (a repeated plane only adds τ·log 2 to the smooth value,
    which the exact-distance offsets of the NLPs absorb).

    With one point, the hard distance of these planes, min over the kept pieces of max over the kept
    planes, equals the full model's hard distance there (the nearest piece and its maximal plane are
    kept). Elsewhere it is a lower bound of the kept pieces' hard distance; a piece left out may become
    the nearest one away from the points, so an NLP whose point moves re-selects them at its solution.

    Args:
        pieces: the object's convex pieces.
        points: (s, 3) points, object frame, m (e.g. a tip centre and its goal).
        n_pieces: pieces kept.
        k: planes kept per piece.

    Returns:
        normals (n_pieces, k, 3) and offsets (n_pieces, k), object frame, m.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    values = [pts @ pc.normals.T - pc.offsets for pc in pieces]  # (s, k_c) each
    nearest = np.argsort([float(v.max(axis=1).min()) for v in values], kind="stable")[:n_pieces]
    nearest = np.resize(nearest, n_pieces)  # repeat when the object has fewer pieces
    N = np.empty((n_pieces, k, 3))
    H = np.empty((n_pieces, k))
    for j, c in enumerate(nearest):
        top = np.argsort(-values[c].max(axis=0), kind="stable")[:k]
        top = np.resize(top, k)
        N[j], H[j] = pieces[c].normals[top], pieces[c].offsets[top]
    return N, H
