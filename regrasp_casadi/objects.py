"""Object models: `ObjectModel`, a watertight mesh with its convex pieces and its distances.

An `ObjectModel` is built from a mesh file (loaded and repaired here), an in-memory mesh or a generated
primitive (box, cylinder, sphere, capsule, bottle, banana, bowl, cup, mug, flat tool, holed box; see
`shapes`), and carries a `spec` that
rebuilds it (`ObjectModel.from_spec`). It is a facade over three modules:

* `regrasp_casadi.convex`: the convex pieces (coacd, cached on disk by mesh content) and local plane sets;
* `regrasp_casadi.signed_distance`: the smooth CasADi signed distance (full and coarse), built once per
  temperature and cached on the model;
* `regrasp_casadi.exact_distance`: the exact mesh distance in millimetres (built on first use).

CasADi and the smooth side are imported only when a smooth distance is asked for, so exact-only users
(`verify`) never load them.

    >>> obj = ObjectModel.cylinder(0.035, 0.2)
    >>> f = obj.signed_distance_function()      # p_object (3,1) -> d (1,1), m
    >>> float(f([0.05, 0, 0]))                  # ≈ 0.015
    >>> obj.exact_signed_distance([[0.05, 0, 0]])
"""

from __future__ import annotations

import hashlib
import logging
import pathlib
from typing import TYPE_CHECKING

import numpy as np
import trimesh
from numpy.typing import ArrayLike, NDArray

from regrasp_casadi import shapes
from regrasp_casadi.convex import (
    DEFAULT_HULL_TOLERANCE,
    DEFAULT_MAX_PIECES,
    DEFAULT_MAX_PLANES,
    DEFAULT_MAX_SECONDS,
    DEFAULT_THRESHOLD,
    LOCAL_PIECES,
    LOCAL_PLANES,
    ConvexPiece,
    coarse_pieces,
    convex_pieces,
    hull_piece,
    select_local_planes,
)
from regrasp_casadi.errors import MeshError
from regrasp_casadi.exact_distance import ExactDistance
from regrasp_casadi.mesh_repair import repair_shells, shells

if TYPE_CHECKING:  # pragma: no cover
    import casadi as ca

__all__ = ["PRIMITIVES", "ObjectModel", "check_scale", "load_mesh"]

log = logging.getLogger(__name__)

_MAX_EXTENT_M = 2.0
WALL_TOLERANCE = 1.5e-3
"""How far (m) the convex pieces of the generated thin-walled shapes may reach into their cavity
(`shapes.bowl_pieces`)."""
CLEARANCE_WALL_FACTOR = 4.0
"""Their clearance model (`ObjectModel.clearance_pieces`) is the same construction at this many times the
tolerance: fewer pieces for the non-tip spheres' distance, which the NLPs correct with exact offsets."""

PRIMITIVES = ("box", "cylinder", "sphere", "capsule", "bottle", "banana", "bowl", "cup", "mug", "flat_tool",
              "holed_box")
"""The generated objects: `ObjectModel.<name>(...)`, `{"primitive": name, ...}` in specs and problem files."""


def _read_mesh(path: pathlib.Path) -> tuple[trimesh.Trimesh, bytes]:
    """The raw triangles of a mesh file and the file's bytes; MeshError naming the file if unusable."""
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
    return loaded, data


def _repair(mesh: trimesh.Trimesh, path: pathlib.Path) -> trimesh.Trimesh:
    """Merge vertices, drop degenerate/duplicate faces, wind outwards (in place); MeshError if not solid."""
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
    return mesh


def check_scale(scale, where: str = "scale") -> float:
    """`scale` as a float if it is a finite number > 0; else MeshError naming `where` and the value."""
    ok = isinstance(scale, (int, float, np.integer, np.floating)) and not isinstance(scale, (bool, np.bool_))
    if not (ok and np.isfinite(scale) and scale > 0):
        raise MeshError(f"{where}: expected a positive finite number (the factor from file units to metres), "
                        f"got {scale!r}")
    return float(scale)


def load_mesh(path, scale: float = 1.0) -> tuple[trimesh.Trimesh, str]:
    """Load an OBJ/STL/PLY/GLB mesh, scale it to metres and repair it.

    Repairs: merged vertices, removed degenerate and duplicate faces, consistent outward winding; shells
    that intersect or lie inside one another are replaced by their union (`mesh_repair.repair_shells`).

    Args:
        path: mesh file (resolved to an absolute path).
        scale: factor applied to the file's coordinates to get metres (0.001 for millimetres).

    Returns:
        The watertight mesh (metres, file frame) and the sha256 of the file's bytes.

    Raises:
        MeshError: naming the file, if it is missing, empty or unreadable, has non-finite vertices,
            is not watertight after repair, intersects itself within one shell, or looks like
            millimetres (largest extent > 2 m); naming `scale` if it is not a finite number > 0.
    """
    path = pathlib.Path(path).expanduser().resolve()
    scale = check_scale(scale, f"{path}: scale")
    loaded, data = _read_mesh(path)
    mesh = trimesh.Trimesh(np.asarray(loaded.vertices, float) * scale, loaded.faces, process=False)
    _repair(mesh, path)
    mesh = repair_shells(mesh, str(path))
    ext = float(np.max(mesh.extents))
    if ext > _MAX_EXTENT_M:
        raise MeshError(f"{path}: largest extent is {ext:.4g} m after scale={scale}; the file looks like "
                        "millimetres — pass scale=0.001")
    return mesh, hashlib.sha256(data).hexdigest()


class ObjectModel:
    """A rigid object: watertight mesh, convex pieces, smooth (CasADi) and exact signed distances.

    Attributes:
        name: object name (free text; CasADi function names are made valid from it).
        mesh: watertight `trimesh.Trimesh`, metres, object frame.
        pieces: convex pieces (half-space form), object frame.
        spec: how to rebuild the object (`ObjectModel.from_spec`).
    """

    def __init__(self, name: str, mesh: trimesh.Trimesh, pieces: tuple[ConvexPiece, ...], spec: dict, *,
                 clearance_pieces: tuple[ConvexPiece, ...] | None = None,
                 local_pieces: tuple[ConvexPiece, ...] | None = None):
        self.name = name
        self.mesh = mesh
        self.pieces = tuple(pieces)
        self.clearance_pieces = None if clearance_pieces is None else tuple(clearance_pieces)
        """Coarser pieces that also contain the mesh, for `clearance_distance_function` (None: `pieces`)."""
        self.local_pieces = self.pieces if local_pieces is None else tuple(local_pieces)
        """The pieces `local_planes` selects from (the fingertips' distance in OPT1 and OPT2): `pieces`, or,
        for the thin-walled shapes (`_walled`), the same hulls with every face plane and edge planes
        (`convex.hull_piece`), where `pieces` keeps the fewest face planes for the full smooth model."""
        self.spec = dict(spec)
        self._sd_functions: dict[tuple, ca.Function] = {}
        self._sd_maps: dict[tuple[float, int], ca.Function] = {}
        self._exact: ExactDistance | None = None

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
        *,
        hull_tolerance: float = DEFAULT_HULL_TOLERANCE,
        max_seconds: float = DEFAULT_MAX_SECONDS,
    ) -> ObjectModel:
        """Build from a watertight mesh in metres (no repair; see `from_mesh` for files).

        Args:
            mesh: watertight mesh, metres, object frame.
            name: object name.
            convex: True: each shell one piece, its hull; False: coacd; None: the hull for convex shells
                and shells within `hull_tolerance` of convex, else coacd (see `convex.convex_pieces`).
            threshold: coacd concavity threshold.
            max_planes_per_piece: plane cap of each piece.
            max_pieces: cap on coacd pieces.
            spec: rebuild recipe; default an inline copy of the mesh.
            hull_tolerance: see `convex.is_near_convex`, m (0: never replace a decomposition by the hull).
            max_seconds: time cap of a coacd decomposition, s.
        """
        pieces = convex_pieces(mesh, convex, threshold, max_planes_per_piece, max_pieces,
                               hull_tolerance=hull_tolerance, max_seconds=max_seconds, name=name)
        if spec is None:
            spec = {"inline_mesh": {"vertices": mesh.vertices.tolist(), "faces": mesh.faces.tolist()}}
            if convex is None:
                convex = bool(mesh.is_convex) and len(shells(mesh)) == 1
            if not convex:
                spec.update(threshold=threshold)
            if max_planes_per_piece != DEFAULT_MAX_PLANES:
                spec.update(max_planes_per_piece=max_planes_per_piece)
            if hull_tolerance != DEFAULT_HULL_TOLERANCE:
                spec.update(hull_tolerance=hull_tolerance)
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
        *,
        hull_tolerance: float = DEFAULT_HULL_TOLERANCE,
        max_seconds: float = DEFAULT_MAX_SECONDS,
    ) -> ObjectModel:
        """Load an OBJ/STL/PLY/GLB mesh (metres after `scale`), repair it and decompose it.

        Repairs: merged vertices, removed degenerate and duplicate faces, consistent outward winding;
        overlapping or nested shells are replaced by their union (see `load_mesh`). A mesh within
        `hull_tolerance` of convex is one piece, its hull (`convex.is_near_convex`); else coacd, cached.

        Args:
            path: mesh file.
            scale: factor applied to the file's coordinates to get metres (0.001 for millimetres).
            name: object name (default: the file's parent folder or stem).
            threshold: coacd concavity threshold (0.02 gives finer pieces, see benchmarks/geometry.py).
            max_planes_per_piece: plane cap of each convex piece.
            max_pieces: cap on the number of coacd pieces.
            hull_tolerance: largest hull-to-mesh distance, m, at which the hull replaces coacd (0: never).
            max_seconds: time cap of the coacd decomposition, s (then cheaper settings, then the hull).

        Raises:
            MeshError: naming the file, if it is missing, empty or unreadable, has non-finite vertices,
                is not watertight after repair, intersects itself within one shell, or looks like
                millimetres (largest extent > 2 m); naming `scale` if it is not a finite number > 0.
        """
        path = pathlib.Path(path).expanduser().resolve()
        mesh, sha256 = load_mesh(path, scale)
        spec = {"mesh": str(path), "scale": float(scale), "sha256": sha256}
        if threshold != DEFAULT_THRESHOLD:
            spec["threshold"] = threshold
        if max_planes_per_piece != DEFAULT_MAX_PLANES:
            spec["max_planes_per_piece"] = max_planes_per_piece
        if hull_tolerance != DEFAULT_HULL_TOLERANCE:
            spec["hull_tolerance"] = hull_tolerance
        if name is None:
            name = path.parent.name if path.stem == "mesh" else path.stem
        return cls.from_trimesh(mesh, name, None, threshold, max_planes_per_piece, max_pieces, spec,
                                hull_tolerance=hull_tolerance, max_seconds=max_seconds)

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
               neck_radius: float = 0.012, neck_height: float = 0.04, sections: int = 32, *,
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
               rings: int = 24, sections: int = 16, *, threshold: float = DEFAULT_THRESHOLD,
               max_planes_per_piece: int = DEFAULT_MAX_PLANES) -> ObjectModel:
        """Banana-like curved, tapered tube, 0.18 m long and 0.036 m thick; see `shapes.banana_mesh`."""
        dims = {"length": float(length), "thickness": float(thickness), "bend_radius": float(bend_radius),
                "rings": int(rings), "sections": int(sections)}
        return cls._primitive(shapes.banana_mesh(**dims), "banana", {"primitive": "banana", **dims},
                              max_planes_per_piece, convex=False, threshold=threshold)

    @classmethod
    def _walled(cls, name: str, dims: dict, decomposition: str, tolerance: float, threshold: float,
                max_planes: int) -> ObjectModel:
        """A thin-walled generated shape (`shapes.<name>_mesh(**dims)`): its convex pieces by construction
        (decomposition "walls": `shapes.<name>_pieces(**dims, tolerance=tolerance)`, each with the fewest
        face planes, at most `max_planes`, whose polytope reaches at most `tolerance` beyond its hull,
        `piece_count.fewest_planes_piece`; no edge planes, which the full smooth model and the grasp NLP
        use; the fingertips' local planes select from the same hulls with all their face planes and
        edge planes, `local_pieces`)
        or by coacd ("coacd", `threshold`)."""
        from regrasp_casadi.piece_count import PLANE_COUNTS, fewest_planes_piece

        mesh = getattr(shapes, f"{name}_mesh")(**dims)
        spec = {"primitive": name, **dims}
        if decomposition == "coacd":
            spec["decomposition"] = "coacd"
            return cls._primitive(mesh, name, spec, max_planes, convex=False, threshold=threshold)
        if decomposition != "walls":
            raise ValueError(f"decomposition must be 'walls' or 'coacd', not {decomposition!r}")
        if tolerance != WALL_TOLERANCE:
            spec["tolerance"] = float(tolerance)
        if max_planes != DEFAULT_MAX_PLANES:
            spec["max_planes_per_piece"] = max_planes
        vertex_sets = getattr(shapes, f"{name}_pieces")(**dims, tolerance=float(tolerance))
        counts = [k for k in PLANE_COUNTS if k < max_planes] + [max_planes]
        pieces = [fewest_planes_piece(v, float(tolerance), counts) for v in vertex_sets]
        coarse_tol = CLEARANCE_WALL_FACTOR * float(tolerance)
        coarse = [fewest_planes_piece(v, coarse_tol, counts)
                  for v in getattr(shapes, f"{name}_pieces")(**dims, tolerance=coarse_tol)]
        local = [hull_piece(v) for v in vertex_sets]
        return cls(name, mesh, tuple(pc for pc in pieces if pc is not None), spec,
                   clearance_pieces=tuple(pc for pc in coarse if pc is not None),
                   local_pieces=tuple(pc for pc in local if pc is not None))

    @classmethod
    def bowl(cls, radius: float = 0.06, wall: float = 0.004, *, decomposition: str = "walls",
             tolerance: float = WALL_TOLERANCE, threshold: float = DEFAULT_THRESHOLD,
             max_planes_per_piece: int = DEFAULT_MAX_PLANES) -> ObjectModel:
        """Thin-walled hemispherical bowl, 0.12 m across, 4 mm wall, open to +z; see `shapes.bowl_mesh`.

        Convex pieces: decomposition "walls" (default), the wall cut into bands and sectors whose hulls
        reach at most ≈ `tolerance` (m) into the bowl (`shapes.bowl_pieces`); "coacd": coacd at
        `threshold` (over-covers the wall by several mm, see benchmarks/geometry.py).
        """
        dims = {"radius": float(radius), "wall": float(wall)}
        return cls._walled("bowl", dims, decomposition, tolerance, threshold, max_planes_per_piece)

    @classmethod
    def cup(cls, radius: float = 0.04, height: float = 0.095, wall: float = 0.004, bottom: float = 0.004, *,
            decomposition: str = "walls", tolerance: float = WALL_TOLERANCE,
            threshold: float = DEFAULT_THRESHOLD, max_planes_per_piece: int = DEFAULT_MAX_PLANES,
            ) -> ObjectModel:
        """Thin-walled cylindrical cup, 0.08 m across, 0.1 m tall, 4 mm walls; see `shapes.cup_mesh`.
        Convex pieces as `bowl`'s (`shapes.cup_pieces`: the bottom disc and the wall's sectors)."""
        dims = {"radius": float(radius), "height": float(height), "wall": float(wall),
                "bottom": float(bottom)}
        return cls._walled("cup", dims, decomposition, tolerance, threshold, max_planes_per_piece)

    @classmethod
    def mug(cls, radius: float = 0.04, height: float = 0.095, wall: float = 0.004, bottom: float = 0.004,
            handle_radius: float = 0.028, handle_thickness: float = 0.01, *, decomposition: str = "walls",
            tolerance: float = WALL_TOLERANCE, threshold: float = DEFAULT_THRESHOLD,
            max_planes_per_piece: int = DEFAULT_MAX_PLANES) -> ObjectModel:
        """`cup` with a handle (genus 1), 0.11 m across with the handle; see `shapes.mug_mesh`.
        Convex pieces as `bowl`'s (`shapes.mug_pieces`: the cup's and the handle's arcs)."""
        dims = {"radius": float(radius), "height": float(height), "wall": float(wall),
                "bottom": float(bottom), "handle_radius": float(handle_radius),
                "handle_thickness": float(handle_thickness)}
        return cls._walled("mug", dims, decomposition, tolerance, threshold, max_planes_per_piece)

    @classmethod
    def flat_tool(cls, length: float = 0.20, thickness: float = 0.015, handle_width: float = 0.025,
                  head_length: float = 0.08, head_width: float = 0.045, corner_radius: float = 0.01, *,
                  threshold: float = DEFAULT_THRESHOLD, max_planes_per_piece: int = DEFAULT_MAX_PLANES,
                  ) -> ObjectModel:
        """Flat spatula-like tool, 0.2 m long, 15 mm thick, in the x-y plane; see `shapes.flat_tool_mesh`."""
        dims = {"length": float(length), "thickness": float(thickness), "handle_width": float(handle_width),
                "head_length": float(head_length), "head_width": float(head_width),
                "corner_radius": float(corner_radius)}
        return cls._primitive(shapes.flat_tool_mesh(**dims), "flat_tool", {"primitive": "flat_tool", **dims},
                              max_planes_per_piece, convex=False, threshold=threshold)

    @classmethod
    def holed_box(cls, extents=(0.05, 0.07, 0.09), hole_radius: float = 0.002, *,
                  threshold: float = DEFAULT_THRESHOLD, max_planes_per_piece: int = DEFAULT_MAX_PLANES,
                  ) -> ObjectModel:
        """Box with three 4 mm tunnels through it (a scan artefact, genus 3); see `shapes.holed_box_mesh`."""
        dims = {"extents": [float(e) for e in extents], "hole_radius": float(hole_radius)}
        return cls._primitive(shapes.holed_box_mesh(**dims), "holed_box", {"primitive": "holed_box", **dims},
                              max_planes_per_piece, convex=False, threshold=threshold)

    @classmethod
    def from_spec(cls, spec: dict, base_dir=None) -> ObjectModel:
        """Rebuild from `obj.spec`; a relative "mesh" path is resolved against `base_dir`.

        Raises:
            MeshError: unknown primitive or unreadable mesh.
        """
        spec = dict(spec)
        opts = {k: spec.pop(k) for k in ("threshold", "max_planes_per_piece") if k in spec}
        if "hull_tolerance" in spec and ("mesh" in spec or "inline_mesh" in spec):
            opts["hull_tolerance"] = spec.pop("hull_tolerance")
        if "mesh" in spec:
            path = pathlib.Path(spec["mesh"]).expanduser()
            if not path.is_absolute() and base_dir is not None:
                path = pathlib.Path(base_dir) / path
            obj = cls.from_mesh(path, scale=check_scale(spec.get("scale", 1.0), f"{path}: scale"), **opts)
            sha = spec.get("sha256")
            if sha and obj.spec["sha256"] != sha:
                log.warning("%s: content differs from the spec's sha256 (file changed since)", path)
            return obj
        if "inline_mesh" in spec:
            m = trimesh.Trimesh(spec["inline_mesh"]["vertices"], spec["inline_mesh"]["faces"], process=False)
            return cls.from_trimesh(m, spec=None, **opts)
        kind = spec.pop("primitive", None)
        if kind not in PRIMITIVES:
            raise MeshError(f"object spec {spec!r}: unknown primitive {kind!r}")
        return getattr(cls, kind)(**spec, **opts)

    # ------------------------------------------------------------------ smooth distance (CasADi, lazy)
    def signed_distance_function(self, tau: float | None = None, symbolic: str = "SX") -> ca.Function:
        """Smooth signed distance p_object (3,1) -> d (1,1), m; built once per (τ, symbolic) and cached.

        d_C(p) = τ·LSE((N_C p − h_C)/τ) per piece, d = −τ·LSE(−d_C/τ) over pieces (see
        `regrasp_casadi.signed_distance` for the bounds). Value, gradient and Hessian are finite everywhere.

        Args:
            tau: temperature, m (default `signed_distance.DEFAULT_TAU`).
            symbolic: "SX" (default; scalar graph, best for few planes and for embedding in SX NLPs) or
                "MX" (matrix graph; about 2.5× faster value+gradient at ~250 planes, see
                benchmarks/geometry.py). Both give the same values.
        """
        from regrasp_casadi import signed_distance as sd

        tau = float(sd.DEFAULT_TAU if tau is None else tau)
        if symbolic not in ("SX", "MX"):
            raise ValueError(f"symbolic must be 'SX' or 'MX', not {symbolic!r}")
        key = (tau, symbolic)
        f = self._sd_functions.get(key)
        if f is None:
            f = sd.pieces_distance_function(f"sd_{self.name}", self.pieces, tau, symbolic)
            self._sd_functions[key] = f
        return f

    def clearance_distance_function(self, max_planes: int = 16, tau: float | None = None) -> ca.Function:
        """A coarse smooth signed distance for clearance constraints: p_object (3,1) -> d (1,1), m.

        Each piece is re-simplified to at most `max_planes` planes (`convex.coarse_pieces`: exact support
        values, so each coarse piece contains its piece and the value is a lower bound of the fine model's
        hard distance up to the smoothing bias): cheaper to differentiate, and conservative where only
        d ≥ β matters. The pieces are `clearance_pieces` when the model has them (the thin-walled shapes:
        coarser pieces that still contain the mesh, so outside it the hard value stays a lower bound of
        the exact distance), else `pieces`. Cached.
        """
        from regrasp_casadi import signed_distance as sd

        tau = float(sd.DEFAULT_TAU if tau is None else tau)
        key = ("coarse", int(max_planes), tau)
        f = self._sd_functions.get(key)
        if f is None:
            coarse = coarse_pieces(self.clearance_pieces or self.pieces, max_planes)
            f = sd.pieces_distance_function(f"sd_coarse_{self.name}", coarse, tau, "SX")
            self._sd_functions[key] = f
        return f

    def local_planes(self, points, n_pieces: int = LOCAL_PIECES,
                     k: int = LOCAL_PLANES) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The planes that decide the distance near `points` (s, 3), object frame, m: normals
        (n_pieces, k, 3) and offsets (n_pieces, k) for `signed_distance.local_signed_distance`.

        See `convex.select_local_planes` (the nearest pieces, their largest planes at the points).
        """
        return select_local_planes(self.local_pieces, points, n_pieces, k)

    def signed_distance_map_function(self, k: int, tau: float | None = None) -> ca.Function:
        """Vectorised smooth distance: points (3, k), object frame -> d (1, k), m (cached)."""
        from regrasp_casadi.signed_distance import DEFAULT_TAU

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
        from regrasp_casadi.signed_distance import smoothing_bias

        return smoothing_bias(self.pieces)

    # ------------------------------------------------------------------ exact distance (numpy)
    @property
    def exact(self) -> ExactDistance:
        """The exact-distance queries of this object's mesh (built on first use)."""
        if self._exact is None:
            self._exact = ExactDistance(self.mesh, self.pieces)
        return self._exact

    def closest_points(self, points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Exact closest points on the mesh and signed distances (positive outside).

        Args:
            points: (n, 3) object frame, m.

        Returns:
            closest (n, 3) object frame, m; signed distance (n,), m.
        """
        return self.exact.closest_points(points)

    def exact_signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Exact signed distance of points (n, 3), object frame, m, to the mesh; positive outside. (n,)."""
        return self.exact.signed_distance(points)

    def near_signed_distance(self, points: ArrayLike, near=0.01) -> NDArray[np.float64]:
        """Exact signed distance (n,) of points (n, 3) that may be within `near` (m; a scalar or one
        value per point) of the surface, the pieces' cheap support-plane estimate (> `near`) elsewhere.
        See `ExactDistance.near_signed_distance`."""
        return self.exact.near_signed_distance(points, near)

    def surface_normals(self, points: ArrayLike) -> NDArray[np.float64]:
        """Outward unit normal (n, 3), object frame, at the closest point of each point (n, 3), m (the
        face's, or the edge's or vertex's pseudo-normal: `ExactDistance.surface_normals`)."""
        return self.exact.surface_normals(points)

    def sample_surface(self, n: int, seed: int = 0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Area-uniform surface samples: points (n, 3) m and outward face normals (n, 3), object frame."""
        pts, fidx = trimesh.sample.sample_surface(self.mesh, int(n), seed=seed)
        return np.asarray(pts), np.array(self.mesh.face_normals[fidx])

