"""Object geometry: a watertight mesh, its convex pieces and a smooth CasADi signed distance.

An `ObjectModel` holds the object's mesh (metres, object frame), its convex pieces (coacd, cached on disk
by mesh content) and two distances:

* the **smooth** signed distance, a CasADi SX `ca.Function` built once per temperature. For a convex
  piece C with unit outward normals n_i and support values h_i = max_v n_i·v,
  ``d_C(p) = τ·log Σ_i exp((n_i·p − h_i)/τ)`` (max subtracted before the exp). It satisfies
  ``max_i(n_i·p − h_i) ≤ d_C(p) ≤ max_i(n_i·p − h_i) + τ·log k``; the hard max is the exact signed
  distance inside C and a lower bound outside. Pieces are combined with a smooth minimum
  ``d(p) = −τ·log Σ_C exp(−d_C(p)/τ)`` with ``min_C d_C − τ·log P ≤ d ≤ min_C d_C``. So outside the
  smooth value exceeds the exact distance by at most ``τ·log k_max`` (k_max: the largest plane count of a
  piece). For a sphere of radius r the distance is d − r (callers subtract it).
* the **exact** signed distance to the mesh (positive outside), computed on a cached millimetre copy of
  the mesh because trimesh 5.2's closest-point tolerance (1e-13 on length⁴) misjudges metre-scale meshes;
  the sign comes from angle-weighted pseudo-normals of the closest feature (Bærentzen & Aanæs 2005).

Accuracy (benchmarks/geometry.py): on convex primitives with ≤ 64 facets the smooth distance is within
0.14 mm of the exact one on the surface (τ's bias only). Capping each piece at `DEFAULT_MAX_PLANES` (64)
planes changes the YCB surface error by < 0.25 mm; the error there is the decomposition's: p99 1.7–4.2 mm
at threshold 0.05, 0.4–1.3 mm at 0.02 (9–16 pieces). Inside a non-convex object the union of pieces
under-estimates the penetration depth (min over pieces); the planner corrects contacts with the exact
distance.

    >>> obj = ObjectModel.cylinder(0.035, 0.2)
    >>> f = obj.signed_distance_function()      # p_object (3,1) -> d (1,1), m
    >>> float(f([0.05, 0, 0]))                  # ≈ 0.015
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import pathlib
from dataclasses import dataclass

import casadi as ca
import numpy as np
import trimesh
from numpy.typing import NDArray

from regrasp_casadi import shapes
from regrasp_casadi.errors import MeshError

__all__ = [
    "ConvexPiece",
    "ObjectModel",
    "DEFAULT_TAU",
    "DEFAULT_THRESHOLD",
    "DEFAULT_MAX_PLANES",
    "DEFAULT_MAX_PIECES",
    "cache_dir",
    "decomposition_count",
    "simplify_piece",
]

log = logging.getLogger(__name__)

DEFAULT_TAU = 2e-4
"""Default smoothing temperature τ, m. Bias on a face ≈ 0, on an edge τ·log 2 = 0.14 mm, at a 3-face
vertex τ·log 3 = 0.22 mm; the worst-case bound is τ·log k (0.83 mm for k = 64 planes)."""
DEFAULT_THRESHOLD = 0.05
"""coacd concavity threshold (smaller: more, finer pieces)."""
DEFAULT_MAX_PLANES = 64
DEFAULT_EDGE_PLANES = 96  # extra edge/vertex support planes per piece (see add_edge_planes)
LOCAL_PIECES = 2  # pieces in a local plane set (see ObjectModel.local_planes)
LOCAL_PLANES = 16  # planes per piece in a local plane set
"""Cap on the planes of one convex piece after simplification (bounds the expression size)."""
DEFAULT_MAX_PIECES = 16
"""Cap on the number of convex pieces coacd may return (its `max_convex_hull`)."""
_MAX_EXTENT_M = 2.0

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
    # merge coplanar faces: on a convex hull, faces with the same normal lie in the same support plane
    _, group_of_face = np.unique(np.round(hull.face_normals, 9), axis=0, return_inverse=True)
    group_of_face = group_of_face.ravel()
    n_groups = int(group_of_face.max()) + 1
    areas = np.bincount(group_of_face, weights=hull.area_faces, minlength=n_groups)
    largest = np.full(n_groups, -1)
    order = np.argsort(hull.area_faces)  # the largest face of each group wins (written last)
    largest[group_of_face[order]] = order
    normals = np.array(hull.face_normals[largest])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    hv = hull.vertices
    if len(normals) > max_planes:
        face_to_plane = group_of_face
        samples, fidx = trimesh.sample.sample_surface(hull, n_samples, seed=0)
        samples = np.concatenate([samples, hull.triangles_center, hv])
        # a hull vertex belongs to several planes: assign it the first face that uses it
        vface = np.full(len(hv), -1)
        vface[hull.faces[::-1].ravel()] = np.repeat(np.arange(len(hull.faces))[::-1], 3)
        sample_plane = face_to_plane[np.concatenate([fidx, np.arange(len(hull.faces)), vface])]
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
        normals = normals[chosen]
    offsets = np.max(hv @ normals.T, axis=0)
    return ConvexPiece(normals=normals, offsets=offsets, vertices=np.array(hv))


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
    normals = list(piece.normals)
    added = 0
    for _, u in candidates:
        if added >= max_extra:
            break
        if max(float(u @ n) for n in normals) > np.cos(np.radians(2.0)):
            continue  # a direction this close is there already
        normals.append(u)
        added += 1
    N = np.array(normals)
    return ConvexPiece(normals=N, offsets=np.max(piece.vertices @ N.T, axis=0), vertices=piece.vertices)


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


def _smooth_max(z: ca.SX, tau: float) -> ca.SX:
    """τ·log Σ exp(z/τ) with the max subtracted first (finite value and derivatives everywhere)."""
    if z.numel() == 1:
        return z
    return tau * _lse_unit(z / tau)


def _lse_unit(y: ca.SX) -> ca.SX:
    """log Σ exp(y) computed as m + log Σ exp(y − m), m = max y (no overflow, log argument ≥ 1)."""
    if y.numel() == 1:
        return y
    m = ca.mmax(y)
    return m + ca.log(ca.sum1(ca.exp(y - m)))


def _smooth_distance_function(name: str, pieces, tau: float, symbolic: str) -> ca.Function:
    """p_object (3,1) -> d: per piece τ·LSE((N p − h)/τ), smooth minimum over the pieces (−τ·LSE(−d/τ))."""
    p = getattr(ca, symbolic).sym("p_object", 3)
    d_pieces = []
    for piece in pieces:  # normals and offsets pre-divided by τ: one operation less per plane
        y = ca.mtimes(ca.DM(piece.normals / tau), p) - ca.DM(piece.offsets / tau)
        d_pieces.append(_lse_unit(y))  # d_C / τ
    d = -tau * _lse_unit(-ca.vertcat(*d_pieces))
    return ca.Function(name, [p], [d], ["p_object"], ["d"])


class ObjectModel:
    """A rigid object: watertight mesh, convex pieces, smooth (CasADi) and exact signed distances.

    Attributes:
        name: object name.
        mesh: watertight `trimesh.Trimesh`, metres, object frame.
        pieces: convex pieces (half-space form), object frame.
        spec: how to rebuild the object (`ObjectModel.from_spec`).
    """

    def __init__(self, name: str, mesh: trimesh.Trimesh, pieces: tuple[ConvexPiece, ...], spec: dict):
        self.name = name
        self.mesh = mesh
        self.pieces = tuple(pieces)
        self.spec = dict(spec)
        self._sd_functions: dict[tuple[float, str], ca.Function] = {}
        self._sd_maps: dict[tuple[float, int], ca.Function] = {}
        self._mm = None  # (mesh_mm, ProximityQuery, edge pseudo-normals, vertex pseudo-normals)

    def __repr__(self) -> str:
        planes = sum(len(p.offsets) for p in self.pieces)
        return (f"ObjectModel({self.name!r}, {len(self.mesh.faces)} faces, {len(self.pieces)} pieces, "
                f"{planes} planes)")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_trimesh(
        cls,
        mesh: trimesh.Trimesh,
        name: str = "mesh",
        convex: bool | None = None,
        threshold: float = DEFAULT_THRESHOLD,
        max_planes_per_piece: int = DEFAULT_MAX_PLANES,
        max_pieces: int = DEFAULT_MAX_PIECES,
        spec: dict | None = None,
    ) -> ObjectModel:
        """Build from a watertight mesh in metres (no repair; see `from_mesh` for files).

        Args:
            mesh: watertight mesh, metres, object frame.
            name: object name.
            convex: True: one piece, the hull; False: coacd; None: decide by `mesh.is_convex`.
            threshold: coacd concavity threshold.
            max_planes_per_piece: plane cap of each piece.
            max_pieces: cap on coacd pieces.
            spec: rebuild recipe; default an inline copy of the mesh.
        """
        if convex is None:
            convex = bool(mesh.is_convex)
        if convex:
            verts = [np.asarray(mesh.vertices)]
        else:
            verts = _decompose(mesh, threshold, max_pieces)
        pieces = tuple(add_edge_planes(simplify_piece(v, max_planes_per_piece)) for v in verts)
        if spec is None:
            spec = {"inline_mesh": {"vertices": mesh.vertices.tolist(), "faces": mesh.faces.tolist()}}
            if not convex:
                spec.update(threshold=threshold)
            if max_planes_per_piece != DEFAULT_MAX_PLANES:
                spec.update(max_planes_per_piece=max_planes_per_piece)
        return cls(name, mesh, pieces, spec)

    @classmethod
    def from_mesh(
        cls,
        path,
        scale: float = 1.0,
        name: str | None = None,
        threshold: float = DEFAULT_THRESHOLD,
        max_planes_per_piece: int = DEFAULT_MAX_PLANES,
        max_pieces: int = DEFAULT_MAX_PIECES,
    ) -> ObjectModel:
        """Load an OBJ/STL/PLY/GLB mesh (metres after `scale`), repair it and decompose it.

        Repairs: merged vertices, removed degenerate and duplicate faces, consistent outward winding.

        Args:
            path: mesh file.
            scale: factor applied to the file's coordinates to get metres (0.001 for millimetres).
            name: object name (default: the file's parent folder or stem).
            threshold: coacd concavity threshold (0.02 gives finer pieces, see benchmarks/geometry.py).
            max_planes_per_piece: plane cap of each convex piece.
            max_pieces: cap on the number of coacd pieces.

        Raises:
            MeshError: naming the file, if it is missing, empty or unreadable, has non-finite vertices,
                is not watertight after repair, or looks like millimetres (largest extent > 2 m).
        """
        path = pathlib.Path(path).expanduser().resolve()
        if not path.is_file():
            raise MeshError(f"{path}: mesh file not found")
        data = path.read_bytes()
        if not data.strip():
            raise MeshError(f"{path}: mesh file is empty")
        try:
            loaded = trimesh.load(str(path), force="mesh", process=False)
        except Exception as exc:
            raise MeshError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from exc
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            raise MeshError(f"{path}: no triangles found in the file")
        if not np.all(np.isfinite(loaded.vertices)):
            raise MeshError(f"{path}: mesh has NaN or infinite vertex coordinates")
        mesh = trimesh.Trimesh(np.asarray(loaded.vertices, float) * float(scale), loaded.faces, process=False)
        mesh.merge_vertices()
        mesh.update_faces(mesh.nondegenerate_faces())
        mesh.update_faces(mesh.unique_faces())
        mesh.remove_unreferenced_vertices()
        if not mesh.is_watertight:
            raise MeshError(f"{path}: mesh is not watertight after merging vertices (open or non-manifold)")
        trimesh.repair.fix_normals(mesh)
        if mesh.volume < 0:
            mesh.invert()
        if not mesh.volume > 0:
            raise MeshError(f"{path}: mesh encloses no volume")
        ext = float(np.max(mesh.extents))
        if ext > _MAX_EXTENT_M:
            raise MeshError(f"{path}: largest extent is {ext:.4g} m after scale={scale}; the file looks like "
                            "millimetres — pass scale=0.001")
        spec = {"mesh": str(path), "scale": float(scale), "sha256": hashlib.sha256(data).hexdigest()}
        if threshold != DEFAULT_THRESHOLD:
            spec["threshold"] = threshold
        if max_planes_per_piece != DEFAULT_MAX_PLANES:
            spec["max_planes_per_piece"] = max_planes_per_piece
        if name is None:
            name = path.parent.name if path.stem == "mesh" else path.stem
        return cls.from_trimesh(mesh, name, None, threshold, max_planes_per_piece, max_pieces, spec)

    @classmethod
    def _primitive(cls, mesh, name, spec, max_planes, convex=True, threshold=DEFAULT_THRESHOLD):
        if max_planes != DEFAULT_MAX_PLANES:
            spec["max_planes_per_piece"] = max_planes
        if not convex and threshold != DEFAULT_THRESHOLD:
            spec["threshold"] = threshold
        return cls.from_trimesh(mesh, name, convex, threshold, max_planes, spec=spec)

    @classmethod
    def box(cls, extents=(0.05, 0.09, 0.175), max_planes_per_piece: int = DEFAULT_MAX_PLANES) -> ObjectModel:
        """Box centred at the origin; extents (3,) full sides, m (default: YCB sugar box)."""
        ext = [float(e) for e in extents]
        return cls._primitive(shapes.box_mesh(ext), "box", {"primitive": "box", "extents": ext},
                              max_planes_per_piece)

    @classmethod
    def cylinder(cls, radius: float = 0.0375, height: float = 0.25, sections: int = 32,
                 max_planes_per_piece: int = DEFAULT_MAX_PLANES) -> ObjectModel:
        """Cylinder about z centred at the origin, m (default: YCB chips can); `sections` sides."""
        spec = {"primitive": "cylinder", "radius": float(radius), "height": float(height)}
        if sections != 32:
            spec["sections"] = int(sections)
        return cls._primitive(shapes.cylinder_mesh(radius, height, sections), "cylinder", spec,
                              max_planes_per_piece)

    @classmethod
    def sphere(cls, radius: float = 0.035, max_planes_per_piece: int = DEFAULT_MAX_PLANES) -> ObjectModel:
        """Icosphere (320 faces) centred at the origin, m."""
        return cls._primitive(shapes.sphere_mesh(radius), "sphere",
                              {"primitive": "sphere", "radius": float(radius)}, max_planes_per_piece)

    @classmethod
    def capsule(cls, radius: float = 0.02, height: float = 0.1,
                max_planes_per_piece: int = DEFAULT_MAX_PLANES) -> ObjectModel:
        """Capsule about z centred at the origin; `height` between the cap centres, m."""
        return cls._primitive(shapes.capsule_mesh(radius, height), "capsule",
                              {"primitive": "capsule", "radius": float(radius), "height": float(height)},
                              max_planes_per_piece)

    @classmethod
    def bottle(cls, body_radius: float = 0.03, body_height: float = 0.12, shoulder_height: float = 0.03,
               neck_radius: float = 0.012, neck_height: float = 0.04, sections: int = 32,
               threshold: float = DEFAULT_THRESHOLD, max_planes_per_piece: int = DEFAULT_MAX_PLANES,
               ) -> ObjectModel:
        """Bottle: solid of revolution (body, shoulder, neck), 0.19 m tall; see `shapes.bottle_mesh`."""
        dims = {"body_radius": float(body_radius), "body_height": float(body_height),
                "shoulder_height": float(shoulder_height), "neck_radius": float(neck_radius),
                "neck_height": float(neck_height), "sections": int(sections)}
        return cls._primitive(shapes.bottle_mesh(**dims), "bottle", {"primitive": "bottle", **dims},
                              max_planes_per_piece, convex=False, threshold=threshold)

    @classmethod
    def banana(cls, length: float = 0.18, thickness: float = 0.036, bend_radius: float = 0.13,
               rings: int = 24, sections: int = 16, threshold: float = DEFAULT_THRESHOLD,
               max_planes_per_piece: int = DEFAULT_MAX_PLANES) -> ObjectModel:
        """Banana-like curved, tapered tube, 0.18 m long and 0.036 m thick; see `shapes.banana_mesh`."""
        dims = {"length": float(length), "thickness": float(thickness), "bend_radius": float(bend_radius),
                "rings": int(rings), "sections": int(sections)}
        return cls._primitive(shapes.banana_mesh(**dims), "banana", {"primitive": "banana", **dims},
                              max_planes_per_piece, convex=False, threshold=threshold)

    @classmethod
    def from_spec(cls, spec: dict, base_dir=None) -> ObjectModel:
        """Rebuild from `obj.spec`; a relative "mesh" path is resolved against `base_dir`.

        Raises:
            MeshError: unknown primitive or unreadable mesh.
        """
        spec = dict(spec)
        opts = {k: spec.pop(k) for k in ("threshold", "max_planes_per_piece") if k in spec}
        if "mesh" in spec:
            path = pathlib.Path(spec["mesh"]).expanduser()
            if not path.is_absolute() and base_dir is not None:
                path = pathlib.Path(base_dir) / path
            obj = cls.from_mesh(path, scale=float(spec.get("scale", 1.0)), **opts)
            sha = spec.get("sha256")
            if sha and obj.spec["sha256"] != sha:
                log.warning("%s: content differs from the spec's sha256 (file changed since)", path)
            return obj
        if "inline_mesh" in spec:
            m = trimesh.Trimesh(spec["inline_mesh"]["vertices"], spec["inline_mesh"]["faces"], process=False)
            return cls.from_trimesh(m, spec=None, **opts)
        kind = spec.pop("primitive", None)
        if kind not in ("box", "cylinder", "sphere", "capsule", "bottle", "banana"):
            raise MeshError(f"object spec {spec!r}: unknown primitive {kind!r}")
        return getattr(cls, kind)(**spec, **opts)

    # ------------------------------------------------------------------ smooth distance
    def signed_distance_function(self, tau: float | None = None, symbolic: str = "SX") -> ca.Function:
        """Smooth signed distance p_object (3,1) -> d (1,1), m; built once per (τ, symbolic) and cached.

        d_C(p) = τ·LSE((N_C p − h_C)/τ) per piece, d = −τ·LSE(−d_C/τ) over pieces (see module docstring
        for the bounds). Value, gradient and Hessian are finite everywhere.

        Args:
            tau: temperature, m (default `DEFAULT_TAU`).
            symbolic: "SX" (default; scalar graph, best for few planes and for embedding in SX NLPs) or
                "MX" (matrix graph; about 2.5× faster value+gradient at ~250 planes, see
                benchmarks/geometry.py). Both give the same values.
        """
        tau = float(DEFAULT_TAU if tau is None else tau)
        if symbolic not in ("SX", "MX"):
            raise ValueError(f"symbolic must be 'SX' or 'MX', not {symbolic!r}")
        key = (tau, symbolic)
        f = self._sd_functions.get(key)
        if f is None:
            f = _smooth_distance_function(f"sd_{self.name}", self.pieces, tau, symbolic)
            self._sd_functions[key] = f
        return f

    def clearance_distance_function(self, max_planes: int = 16, tau: float | None = None) -> ca.Function:
        """A coarse smooth signed distance for clearance constraints: p_object (3,1) -> d (1,1), m.

        Each piece is re-simplified to at most `max_planes` planes (exact support values, so each coarse
        piece contains its piece and the value is a lower bound of the fine model's hard distance up to
        the smoothing bias): cheaper to differentiate, and conservative where only d ≥ β matters. Cached.
        """
        tau = float(DEFAULT_TAU if tau is None else tau)
        key = ("coarse", int(max_planes), tau)
        f = self._sd_functions.get(key)
        if f is None:
            coarse = [pc if len(pc.normals) <= max_planes else simplify_piece(pc.vertices, max_planes)
                      for pc in self.pieces]
            f = _smooth_distance_function(f"sd_coarse_{self.name}", coarse, tau, "SX")
            self._sd_functions[key] = f
        return f

    def local_planes(self, points, n_pieces: int = LOCAL_PIECES,
                     k: int = LOCAL_PLANES) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The planes that decide the distance near `points`: a fixed-size set for NLP parameters.

        The `n_pieces` pieces nearest to the points (smallest hard distance) and, of each, the `k` planes
        with the largest values n·p − h over the points (the planes that are the max there). Missing
        pieces or planes repeat the first one (a repeated plane only adds τ·log 2 to the smooth value,
        which the exact-distance offsets of the NLPs absorb). With these planes,
        ``terms.local_signed_distance`` equals the full model's hard distance at the points and is a
        lower bound of it elsewhere, so an NLP whose point moves re-selects them at its solution.

        Args:
            points: (s, 3) points, object frame, m (e.g. a tip centre and its goal).
            n_pieces: pieces kept.
            k: planes kept per piece.

        Returns:
            normals (n_pieces, k, 3) and offsets (n_pieces, k), object frame, m.
        """
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        values = [pts @ pc.normals.T - pc.offsets for pc in self.pieces]  # (s, k_c) each
        nearest = np.argsort([float(v.max(axis=1).min()) for v in values], kind="stable")[:n_pieces]
        nearest = np.resize(nearest, n_pieces)  # repeat when the object has fewer pieces
        N = np.empty((n_pieces, k, 3))
        H = np.empty((n_pieces, k))
        for j, c in enumerate(nearest):
            top = np.argsort(-values[c].max(axis=0), kind="stable")[:k]
            top = np.resize(top, k)
            N[j], H[j] = self.pieces[c].normals[top], self.pieces[c].offsets[top]
        return N, H

    def signed_distance_map_function(self, k: int, tau: float | None = None) -> ca.Function:
        """Vectorised smooth distance: points (3, k), object frame -> d (1, k), m (cached)."""
        key = (float(DEFAULT_TAU if tau is None else tau), int(k))
        f = self._sd_maps.get(key)
        if f is None:
            f = self.signed_distance_function(tau).map(int(k))
            self._sd_maps[key] = f
        return f

    def signed_distance(self, points, tau: float | None = None) -> NDArray[np.float64]:
        """Smooth signed distance of points (n, 3), object frame, m. Returns (n,)."""
        pts = np.atleast_2d(np.asarray(points, float))
        out = self.signed_distance_map_function(len(pts), tau)(pts.T)
        return np.asarray(out).ravel()

    @property
    def bias_bound(self) -> float:
        """τ·log k_max at the default τ, m: how far the smooth value may exceed the hard plane bound."""
        return DEFAULT_TAU * float(np.log(max(len(p.offsets) for p in self.pieces)))

    # ------------------------------------------------------------------ exact distance (millimetres)
    def _mm_cache(self):
        if self._mm is None:
            from scipy.spatial import cKDTree

            m = self.mesh.copy()
            m.apply_scale(1000.0)
            fn = m.face_normals
            edge_n = np.zeros((len(m.edges_unique), 3))
            np.add.at(edge_n, m.faces_unique_edges.ravel(), np.repeat(fn, 3, axis=0))
            vert_n = np.zeros((len(m.vertices), 3))
            np.add.at(vert_n, m.faces.ravel(), (fn[:, None, :] * m.face_angles[:, :, None]).reshape(-1, 3))
            tri = np.array(m.triangles)
            self._mm = (m, cKDTree(m.vertices), m.triangles_tree, tri, edge_n, vert_n)
        return self._mm

    def _closest(self, points):
        """Exact closest points, signed distances (m) and triangle ids for points (n, 3), m.

        Same algorithm as trimesh.proximity.closest_point (candidate triangles from the box reaching the
        nearest vertex), in millimetres, with the k-d tree built once rather than on every call.
        """
        m, kdtree, rtree, tris, edge_n, vert_n = self._mm_cache()
        p_mm = np.atleast_2d(np.asarray(points, float)) * 1000.0
        n_pts = len(p_mm)
        r = kdtree.query(p_mm)[0][:, None] + 1e-8
        ids, counts = rtree.intersection_v(p_mm - r, p_mm + r)
        ids = np.asarray(ids, dtype=np.int64)
        counts = np.asarray(counts, dtype=np.int64)
        owner = np.repeat(np.arange(n_pts), counts)
        cand = trimesh.triangles.closest_point(tris[ids], p_mm[owner])
        d2 = np.einsum("ij,ij->i", p_mm[owner] - cand, p_mm[owner] - cand)
        best = np.lexsort((d2, owner))[np.concatenate([[0], np.cumsum(counts)[:-1]])]
        c_mm, tri = cand[best], ids[best]
        dist = np.sqrt(d2[best])
        bary = trimesh.triangles.points_to_barycentric(tris[tri], c_mm)
        small = bary < 1e-7
        n = m.face_normals[tri].copy()
        n_small = small.sum(axis=1)
        for i in np.nonzero(n_small == 1)[0]:  # on an edge: the one opposite the small weight
            k = int(np.argmax(small[i]))
            n[i] = edge_n[m.faces_unique_edges[tri[i], (k + 1) % 3]]
        for i in np.nonzero(n_small >= 2)[0]:  # at a vertex: the one of the largest weight
            n[i] = vert_n[m.faces[tri[i], int(np.argmax(bary[i]))]]
        sign = np.where(np.einsum("ij,ij->i", p_mm - c_mm, n) < 0.0, -1.0, 1.0)
        return c_mm / 1000.0, sign * dist / 1000.0, tri

    def closest_points(self, points) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Exact closest points on the mesh and signed distances (positive outside).

        Args:
            points: (n, 3) object frame, m.

        Returns:
            closest (n, 3) object frame, m; signed distance (n,), m.
        """
        closest, d, _ = self._closest(points)
        return closest, d

    def exact_signed_distance(self, points) -> NDArray[np.float64]:
        """Exact signed distance of points (n, 3), object frame, m, to the mesh; positive outside. (n,)."""
        return self._closest(points)[1]

    def near_signed_distance(self, points, near=0.01) -> NDArray[np.float64]:
        """Exact signed distance (n,) of points (n, 3) that may be within `near` (m; a scalar or one
        value per point, e.g. sphere radius + margin) of the surface; for the others, the convex pieces'
        support-plane estimate min_C max_i (n_i·p − h_i) (> `near`), which is much cheaper.

        For clearance checks that only need a distance exactly where it is small. Outside the pieces the
        estimate is a lower bound of the distance to their union, which covers the mesh up to the
        decomposition's error (see benchmarks/geometry.py), so a point it calls far is at least
        `near` minus that error from the mesh.
        """
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        bound = np.min(np.column_stack([pc.hard_distance(pts) for pc in self.pieces]), axis=1)
        out = bound.copy()
        close = bound <= near
        if np.any(close):
            out[close] = self.exact_signed_distance(pts[close])
        return out

    def surface_normals(self, points) -> NDArray[np.float64]:
        """Outward unit normal (n, 3), object frame, of the mesh face closest to each point (n, 3), m."""
        tri = self._closest(points)[2]
        return np.array(self.mesh.face_normals[tri])

    def sample_surface(self, n: int, seed: int = 0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Area-uniform surface samples: points (n, 3) m and outward face normals (n, 3), object frame."""
        pts, fidx = trimesh.sample.sample_surface(self.mesh, int(n), seed=seed)
        return np.asarray(pts), np.array(self.mesh.face_normals[fidx])
