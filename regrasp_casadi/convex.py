"""Convex pieces of an object: half-space form, plane caps, the coacd decomposition cache, local plane sets.

A convex piece C is stored as half-spaces n_i·p ≤ h_i with unit outward normals n_i and exact support
values h_i = max_v n_i·v over its hull vertices, so the polytope always contains the hull. Its *hard
distance* ``max_i (n_i·p − h_i)`` is the exact signed distance inside C and a lower bound outside; the
smooth CasADi distance built on it lives in `regrasp_casadi.signed_distance`.

`convex_pieces` handles each shell of a mesh on its own: a convex shell, or one whose hull is within
`DEFAULT_HULL_TOLERANCE` (1 mm) of it and at most `HULL_VOLUME_TOLERANCE` (2 %) larger (`is_near_convex`),
is one piece, its hull; other shells are split by coacd once and the pieces cached on disk, keyed by the
mesh's content and the decomposition parameters (`cache_dir()`, `decomposition_count()`). A cache file
stores the mesh hash and the parameters and is checked against them and against the mesh on load. coacd
runs in a child process under a time cap (`DEFAULT_MAX_SECONDS`, then `FALLBACK_COACD`, then the hull),
with a progress bar on a terminal. Degenerate pieces (flat or collinear points) are dropped with a
warning. `decomposition_error` measures how far the pieces' union reaches beyond the mesh.

Only numpy, trimesh, scipy and coacd (in the child process) are used here; no CasADi.

    >>> pieces = convex_pieces(mesh, convex=None)          # tuple[ConvexPiece, ...], object frame, m
    >>> N, H = select_local_planes(pieces, p_object_tip)    # (2, 16, 3), (2, 16): planes near the tip
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import pathlib
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import ArrayLike, NDArray

from regrasp_casadi.errors import MeshError
from regrasp_casadi.mesh_repair import shells

__all__ = [
    "ConvexPiece",
    "DEFAULT_THRESHOLD",
    "DEFAULT_MAX_PLANES",
    "DEFAULT_EDGE_PLANES",
    "DEFAULT_MAX_PIECES",
    "DEFAULT_HULL_TOLERANCE",
    "DEFAULT_MAX_SECONDS",
    "HULL_VOLUME_TOLERANCE",
    "LOCAL_PIECES",
    "LOCAL_PLANES",
    "add_edge_planes",
    "hull_piece",
    "cache_dir",
    "coarse_pieces",
    "convex_pieces",
    "decomposition_count",
    "decomposition_error",
    "hull_error",
    "is_near_convex",
    "select_local_planes",
    "select_local_planes_batch",
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
DEFAULT_HULL_TOLERANCE = 1e-3
"""A shell whose convex hull is within this distance (m) of it is one piece (see `is_near_convex`)."""
HULL_VOLUME_TOLERANCE = 0.02
"""... and whose hull's volume exceeds its own by at most this fraction."""
DEFAULT_MAX_SECONDS = 300.0
"""Time cap of one coacd decomposition, s (then cheaper settings, then the hull; see `_decompose`)."""
FALLBACK_COACD = {"resolution": 500, "mcts_iterations": 30, "mcts_max_depth": 2, "mcts_nodes": 10}
"""coacd settings of the second, cheaper attempt after a timeout."""
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


def hull_error(mesh: trimesh.Trimesh, n_samples: int = 5000) -> tuple[float, float]:
    """How far a watertight mesh is from convex: ((V_hull − V)/V, largest distance in m from
    `n_samples` area-uniform samples of its convex hull's surface (seed 0) to the mesh)."""
    hull = mesh.convex_hull
    excess = float((hull.volume - mesh.volume) / mesh.volume)
    pts, _ = trimesh.sample.sample_surface(hull, int(n_samples), seed=0)
    _, dist, _ = trimesh.proximity.closest_point(mesh, pts)
    return excess, float(np.max(dist))


def is_near_convex(mesh: trimesh.Trimesh, tolerance: float = DEFAULT_HULL_TOLERANCE) -> bool:
    """True if the mesh's convex hull can stand for it: (V_hull − V)/V ≤ `HULL_VOLUME_TOLERANCE` and every
    one of 5000 hull-surface samples lies within `tolerance` (m) of the mesh (see `hull_error`)."""
    if tolerance <= 0:
        return False
    hull = mesh.convex_hull
    if (hull.volume - mesh.volume) / mesh.volume > HULL_VOLUME_TOLERANCE:  # cheap test first
        return False
    return hull_error(mesh)[1] <= tolerance


def decomposition_error(mesh: trimesh.Trimesh, pieces: Sequence[ConvexPiece],
                        n_samples: int = 3000) -> tuple[float, float]:
    """How far the union of the pieces reaches beyond the mesh (where hulls bridge a concavity or fill a
    cavity): (p99, max), m, over area-uniform samples of the union's boundary (each piece's hull surface,
    less what lies inside another piece) of their distance outside the mesh (0 on or inside it)."""
    hulls = [trimesh.convex.convex_hull(pc.vertices) for pc in pieces]
    areas = np.array([h.area for h in hulls])
    counts = np.maximum(1, np.round(n_samples * areas / areas.sum()).astype(int))
    samples = []
    for k, (hull, count) in enumerate(zip(hulls, counts, strict=True)):
        pts, _ = trimesh.sample.sample_surface(hull, int(count), seed=k)
        others = [pc.hard_distance(pts) for j, pc in enumerate(pieces) if j != k]
        samples.append(pts if not others else pts[np.min(others, axis=0) > -1e-9])
    pts = np.concatenate(samples)
    outside = np.maximum(0.0, -trimesh.proximity.signed_distance(mesh, pts))  # trimesh: positive inside
    return float(np.quantile(outside, 0.99)), float(outside.max())


def _pieces_fit(pieces: list[NDArray], mesh: trimesh.Trimesh) -> str | None:
    """Why cached pieces cannot be this mesh's (None if they can): every mesh vertex must lie in the union
    of the pieces' hulls and every piece vertex in the mesh's bounding box, within 1 mm + 2 % of its size."""
    tol = 1e-3 + 0.02 * float(np.max(mesh.extents))
    if not pieces or any(v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)) for v in pieces):
        return "pieces are not finite (v, 3) arrays"
    lo, hi = mesh.bounds
    outside = max(float(np.max(np.maximum(lo - v, v - hi))) for v in pieces)
    if outside > tol:
        return f"a piece reaches {outside * 1e3:.1f} mm outside the mesh's bounding box"
    hulls = [pc for pc in (_piece_or_none(v, 10**6, edge_planes=False) for v in pieces) if pc is not None]
    if not hulls:
        return "no piece spans a volume"
    gap = float(np.max(np.min([pc.hard_distance(mesh.vertices) for pc in hulls], axis=0)))
    if gap > tol:
        return f"a mesh vertex lies {gap * 1e3:.1f} mm outside every piece"
    return None


def _read_cache(path: pathlib.Path, mesh_hash: str, params: dict, mesh: trimesh.Trimesh,
                max_seconds: float) -> list[NDArray] | None:
    """The pieces in a cache file if it holds this mesh's decomposition with these parameters, else None
    (with a warning naming the file and the reason, except when the file is absent)."""
    if not path.is_file():
        return None
    try:
        with np.load(path) as data:
            pieces = [np.array(data[f"piece{i}"], dtype=float) for i in range(int(data["n"]))]
            stored_hash = str(data["mesh_sha256"]) if "mesh_sha256" in data else None
            stored_params = json.loads(str(data["params"])) if "params" in data else None
            budget = float(data["timed_out_after_s"]) if "timed_out_after_s" in data else None
    except Exception as exc:
        log.warning("ignoring unreadable cache file %s (%s: %s); decomposing again", path,
                    type(exc).__name__, exc)
        return None
    if stored_hash is not None and (stored_hash != mesh_hash or stored_params != params):
        what = "mesh hash" if stored_hash != mesh_hash else "parameters"
        log.warning("cache file %s holds another decomposition (its %s differ); decomposing again", path,
                    what)
        return None
    reason = _pieces_fit(pieces, mesh)
    if reason is not None:
        log.warning("cache file %s does not fit this mesh (%s); decomposing again", path, reason)
        return None
    if budget is not None and max_seconds > budget:
        log.info("cache file %s is a fallback after coacd timed out at %g s; trying again with %g s",
                 path, budget, max_seconds)
        return None
    if stored_hash is None:  # a file of an older version: record what it belongs to
        _write_cache(path, pieces, mesh_hash, params, None)
    log.debug("convex decomposition cache hit %s", path)
    return pieces


def _write_cache(path: pathlib.Path, pieces: list[NDArray], mesh_hash: str, params: dict,
                 timed_out_after_s: float | None) -> None:
    from regrasp_casadi.files import atomic_write_bytes

    buf = io.BytesIO()
    extra = {} if timed_out_after_s is None else {"timed_out_after_s": float(timed_out_after_s)}
    np.savez(buf, n=len(pieces), mesh_sha256=mesh_hash, params=json.dumps(params, sort_keys=True),
             **extra, **{f"piece{i}": v for i, v in enumerate(pieces)})
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(path, buf.getvalue())
    except OSError as exc:
        log.warning("could not write decomposition cache %s: %s", path, exc)


def _decompose(mesh: trimesh.Trimesh, threshold: float, max_pieces: int, seed: int = 0,
               max_seconds: float = DEFAULT_MAX_SECONDS, desc: str = "coacd") -> list[NDArray]:
    """coacd convex pieces (list of (v, 3) vertex arrays, m), cached on disk by content + parameters.

    The cache file stores the mesh hash and the parameters and is checked against them (and against the
    mesh's extent) on load. coacd runs in a child process with a progress bar: after 3/4 of `max_seconds`
    it is stopped and run again with cheaper settings (`FALLBACK_COACD`), and if that also runs out, the
    mesh's convex hull is used (with warnings); such a fallback is cached with the time it was given.
    """
    import coacd

    from regrasp_casadi.coacd_worker import CoacdError, run_coacd

    params = {"threshold": float(threshold), "max_convex_hull": int(max_pieces), "seed": int(seed),
              "coacd": getattr(coacd, "__version__", "?"), "format": 1}
    mesh_hash = _mesh_hash(mesh)
    key = hashlib.sha256((mesh_hash + json.dumps(params, sort_keys=True)).encode()).hexdigest()
    path = cache_dir() / "coacd" / f"{key}.npz"
    cached = _read_cache(path, mesh_hash, params, mesh, max_seconds)
    if cached is not None:
        return cached
    kwargs = {"threshold": float(threshold), "max_convex_hull": int(max_pieces), "seed": int(seed)}
    t0 = time.monotonic()
    try:
        pieces = run_coacd(mesh.vertices, mesh.faces, kwargs, 0.75 * max_seconds, desc)
        timed_out = None
        if pieces is None:
            log.warning("coacd (threshold %g) did not finish in %.0f s; trying cheaper settings %s",
                        threshold, 0.75 * max_seconds, FALLBACK_COACD)
            rest = max(1.0, max_seconds - (time.monotonic() - t0))
            pieces = run_coacd(mesh.vertices, mesh.faces, {**kwargs, **FALLBACK_COACD}, rest, desc)
            timed_out = max_seconds
    except CoacdError as exc:
        raise MeshError(f"convex decomposition failed: {exc}") from None
    _COUNTERS["decompositions"] += 1
    if pieces is None:
        log.warning("coacd did not finish within %g s; using the convex hull as the only piece", max_seconds)
        pieces = [np.array(mesh.convex_hull.vertices)]
    log.info("coacd decomposition: %d pieces (threshold %g) in %.1f s, cached at %s", len(pieces), threshold,
             time.monotonic() - t0, path)
    _write_cache(path, pieces, mesh_hash, params, timed_out)
    return pieces


def hull_piece(vertices: NDArray) -> ConvexPiece | None:
    """The convex hull of `vertices` (v, 3), m, with every face plane and the edge planes of
    `add_edge_planes`: its max of plane distances is a lower bound of the hull's Euclidean distance
    outside that the edge planes keep close near edges and corners (the cup's wall pieces: within 0.7 mm
    at a fingertip's radius, tests/test_walls_tip_model.py); None if the points span no volume. For a
    model that only ever reads a few planes at a time (`select_local_planes`)."""
    return _piece_or_none(vertices, 10**6)


def _piece_or_none(vertices: NDArray, max_planes: int, edge_planes: bool = True) -> ConvexPiece | None:
    """The simplified (and edge-tightened) piece of `vertices`, or None if they span no volume (flat,
    collinear or too few points: Qhull fails or the hull is degenerate)."""
    v = np.asarray(vertices, dtype=float)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4 or not np.all(np.isfinite(v)):
        return None
    centred = v - v.mean(axis=0)
    size = float(np.max(np.ptp(v, axis=0)))
    thinnest = np.linalg.svd(centred, full_matrices=False)[2][-1]  # the direction of least spread
    if not size > 0 or float(np.ptp(centred @ thinnest)) <= 1e-6 * size:
        return None
    try:
        if not trimesh.convex.convex_hull(v).is_volume:
            return None
        piece = simplify_piece(v, max_planes)
        if edge_planes:
            piece = add_edge_planes(piece)
    except (RuntimeError, ValueError, IndexError, ZeroDivisionError):  # QhullError is a RuntimeError
        return None
    ok = np.all(np.isfinite(piece.normals)) and np.all(np.isfinite(piece.offsets))
    return piece if ok else None


def _pieces_of(vertex_sets: list[NDArray], max_planes: int, fallback: NDArray,
               what: str) -> list[ConvexPiece]:
    """Pieces of each vertex set; degenerate ones are dropped (logged). If none is left, the hull of
    `fallback` (m) is the only piece."""
    pieces = [_piece_or_none(v, max_planes) for v in vertex_sets]
    kept = [pc for pc in pieces if pc is not None]
    if len(kept) < len(pieces):
        log.warning("%s: dropped %d degenerate convex piece(s) of %d (flat or collinear points; no volume)",
                    what, len(pieces) - len(kept), len(pieces))
    if not kept:
        log.warning("%s: no convex piece with volume; using the convex hull", what)
        kept = [add_edge_planes(simplify_piece(fallback, max_planes))]
    return kept


def convex_pieces(
    mesh: trimesh.Trimesh,
    convex: bool | None = None,
    threshold: float = DEFAULT_THRESHOLD,
    max_planes_per_piece: int = DEFAULT_MAX_PLANES,
    max_pieces: int = DEFAULT_MAX_PIECES,
    *,
    hull_tolerance: float = DEFAULT_HULL_TOLERANCE,
    max_seconds: float = DEFAULT_MAX_SECONDS,
    name: str = "mesh",
) -> tuple[ConvexPiece, ...]:
    """The convex pieces of a watertight mesh (metres, object frame), each simplified and edge-tightened.

    Each shell (face-connected component; shells touching only at a vertex are separate) is handled on
    its own, so two convex shells give two pieces. Degenerate pieces (no volume) are dropped with a
    warning.

    Args:
        mesh: watertight mesh, m, object frame.
        convex: True: each shell is one piece, its hull; False: coacd (cached); None: the hull for a
            convex shell or one within `hull_tolerance` of convex (`is_near_convex`), else coacd.
        threshold: coacd concavity threshold.
        max_planes_per_piece: face-plane cap of each piece (`simplify_piece`), before `add_edge_planes`.
        max_pieces: cap on coacd pieces (per shell).
        hull_tolerance: largest hull-to-mesh distance, m, at which a shell's hull is used (0: never).
        max_seconds: time cap of one coacd decomposition, s (see `_decompose`).
        name: the object's name, for messages and the progress bar.
    """
    groups = shells(mesh)
    parts = [mesh] if len(groups) == 1 else [mesh.submesh([g], append=True, repair=False) for g in groups]
    if len(parts) > 1:
        log.info("%s: %d shells (face-connected parts), each split into convex pieces on its own", name,
                 len(parts))
    vertex_sets: list[NDArray] = []
    for k, part in enumerate(parts):
        use_hull = convex
        if use_hull is None:
            use_hull = bool(part.is_convex)
            if not use_hull and is_near_convex(part, hull_tolerance):
                log.info("%s: within %g mm of its convex hull; one piece, no decomposition", name,
                         hull_tolerance * 1e3)
                use_hull = True
        if use_hull:
            vertex_sets.append(np.asarray(part.vertices))
        else:
            desc = f"decomposing {name}" + (f" (shell {k + 1}/{len(parts)})" if len(parts) > 1 else "")
            vertex_sets += _decompose(part, threshold, max_pieces, max_seconds=max_seconds, desc=desc)
    return tuple(_pieces_of(vertex_sets, max_planes_per_piece, np.asarray(mesh.vertices), name))


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


def select_local_planes_batch(pieces: Sequence[ConvexPiece], points: ArrayLike, n_pieces: int = LOCAL_PIECES,
                              k: int = LOCAL_PLANES) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """`select_local_planes` for b point sets at once (one numpy pass over all planes).

    Args:
        pieces: the object's convex pieces.
        points: (b, s, 3) — b sets of s points each, object frame, m (e.g. a sphere's centre at the start
            and at the last solution).
        n_pieces, k: pieces kept per set, planes kept per piece.

    Returns:
        normals (b, n_pieces, k, 3) and offsets (b, n_pieces, k): entry i is
        ``select_local_planes(pieces, points[i], n_pieces, k)``.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 3 or pts.shape[2] != 3:
        raise ValueError(f"points must be (b, s, 3), got {pts.shape}")
    counts = np.array([len(pc.offsets) for pc in pieces])
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    normals = np.concatenate([pc.normals for pc in pieces])
    offsets = np.concatenate([pc.offsets for pc in pieces])
    values = pts @ normals.T - offsets  # (b, s, T)
    piece_hard = np.maximum.reduceat(values, starts, axis=2).min(axis=1)  # (b, P): hard distance
    nearest = np.argsort(piece_hard, axis=1, kind="stable")[:, :n_pieces]
    nearest = nearest[:, np.resize(np.arange(nearest.shape[1]), n_pieces)]  # repeat when too few
    plane_value = values.max(axis=1)  # (b, T): each plane's largest value over the set's points
    k_max = int(counts.max())
    pad = np.arange(k_max)
    index = np.where(pad < counts[:, None], starts[:, None] + pad, -1)  # (P, k_max) into T, -1: none
    gathered = np.where(index[nearest] >= 0, np.take_along_axis(
        plane_value[:, None, :], np.maximum(index[nearest], 0), axis=2), -np.inf)  # (b, n, k_max)
    order = np.argsort(-gathered, axis=2, kind="stable")
    kc = counts[nearest][..., None]  # (b, n, 1) planes of each kept piece
    pos = np.arange(k)
    order = np.take_along_axis(order, np.where(pos < kc, pos, pos % kc), axis=2)  # (b, n, k)
    plane = np.take_along_axis(index[nearest], order, axis=2)
    return normals[plane], offsets[plane]
