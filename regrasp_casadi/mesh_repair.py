"""Solid-mesh checks and repairs: shells, self-intersections, the union of overlapping shells, genus.

A triangle mesh read from a file may be several *shells* (face-connected components). A mesh whose
shells overlap (two boxes written into one file, a scan with a loose inner surface) is watertight and
still wrong as a solid: its exact signed distance inside the overlap measures the distance to a face
that is buried inside the object. This module finds such meshes and repairs them:

* `shells(mesh)`: the face-connected components (two boxes sharing only a corner vertex are two shells);
* `self_intersections(mesh)`: face pairs whose interiors intersect (triangles that share a vertex are
  not tested against each other), found through an R-tree of triangle bounds and a vectorised
  triangle–triangle test;
* `union_of_shells(shells)`: the Boolean union (manifold3d) of closed, non-self-intersecting shells;
* `repair_shells(mesh, where)`: the union when shells overlap or nest, a `MeshError` naming `where` when a
  shell intersects itself (manifold3d's Booleans assume each input is free of self-intersections);
* `genus(mesh)`: the genus of a closed single-shell surface from its Euler characteristic.

Only numpy, trimesh, rtree and manifold3d (imported when a union runs); no CasADi.

    >>> fixed = repair_shells(mesh, where="two_boxes.obj")   # the union if the shells overlap
"""

from __future__ import annotations

import logging

import numpy as np
import trimesh
from numpy.typing import NDArray

from regrasp_casadi.errors import MeshError

__all__ = ["from_manifold", "genus", "repair_shells", "self_intersections", "shells", "to_manifold",
           "union_of_shells"]

log = logging.getLogger(__name__)

_EDGES = ((0, 1), (1, 2), (2, 0))
_CHUNK = 100_000
"""Triangle pairs tested at once by `self_intersections`."""


def shells(mesh: trimesh.Trimesh) -> list[NDArray[np.int64]]:
    """Face indices of each face-connected component (faces sharing an edge), largest first."""
    groups = trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(mesh.faces)),
                                                min_len=1)
    return sorted((np.sort(np.asarray(g, dtype=np.int64)) for g in groups), key=len, reverse=True)


def genus(mesh: trimesh.Trimesh) -> int:
    """Genus g of a closed, connected, orientable surface: V − E + F = 2 − 2g."""
    return (2 - int(mesh.euler_number)) // 2


# ---------------------------------------------------------------------------- triangle-triangle test
def _candidate_pairs(tris: NDArray, faces: NDArray, eps: float) -> tuple[NDArray, NDArray]:
    """Face pairs (i < j) whose bounding boxes overlap and which share no vertex."""
    lo = tris.min(axis=1) - eps
    hi = tris.max(axis=1) + eps
    tree = trimesh.util.bounds_tree(np.hstack([lo, hi]))
    ids, counts = tree.intersection_v(lo, hi)
    i = np.repeat(np.arange(len(tris)), np.asarray(counts, dtype=np.int64))
    j = np.asarray(ids, dtype=np.int64)
    keep = i < j
    i, j = i[keep], j[keep]
    shared = (faces[i][:, :, None] == faces[j][:, None, :]).any(axis=(1, 2))
    return i[~shared], j[~shared]


def _interval(d: NDArray, p: NDArray) -> tuple[NDArray, NDArray]:
    """Interval (lo, hi) on the planes' common line of a triangle with signed distances d (k, 3) to the
    other plane and line coordinates p (k, 3) of its vertices: its edge crossings and on-plane vertices."""
    vals = []
    for a, b in _EDGES:
        da, db = d[:, a], d[:, b]
        cross = da * db < 0
        with np.errstate(divide="ignore", invalid="ignore"):
            t = p[:, a] + (p[:, b] - p[:, a]) * da / (da - db)
        vals.append(np.where(cross, t, np.nan))
    vals.append(np.where(d == 0, p, np.nan).T)  # (3, k) rows
    stacked = np.vstack([np.stack(vals[:3]), vals[3]])  # (6, k)
    with np.errstate(all="ignore"):
        return np.nanmin(stacked, axis=0), np.nanmax(stacked, axis=0)


def _orient(a: NDArray, b: NDArray, c: NDArray) -> NDArray:
    ab, ac = b - a, c - a
    return ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0]


def _inside_2d(q: NDArray, t: NDArray, eps: float) -> NDArray:
    """Point q (k, 2) strictly inside triangle t (k, 3, 2)."""
    o = np.stack([_orient(t[:, a], t[:, b], q) for a, b in _EDGES], axis=1)
    return np.all(o > eps, axis=1) | np.all(o < -eps, axis=1)


def _coplanar_overlap(A: NDArray, B: NDArray, normal: NDArray, eps: float) -> NDArray:
    """Coplanar triangles (k, 3, 3) whose overlap has positive area (proper edge crossing or a centroid
    strictly inside the other triangle), tested in the coordinate plane most normal to `normal`."""
    drop = np.argmax(np.abs(normal), axis=1)
    keep = np.array([[1, 2], [0, 2], [0, 1]])[drop]  # (k, 2)
    rows = np.arange(len(A))[:, None, None]
    a2 = A[rows, np.arange(3)[None, :, None], keep[:, None, :]]
    b2 = B[rows, np.arange(3)[None, :, None], keep[:, None, :]]
    eps2 = eps * eps
    hit = _inside_2d(a2.mean(axis=1), b2, eps2) | _inside_2d(b2.mean(axis=1), a2, eps2)
    for a, b in _EDGES:
        for c, d in _EDGES:
            o1 = _orient(a2[:, a], a2[:, b], b2[:, c])
            o2 = _orient(a2[:, a], a2[:, b], b2[:, d])
            o3 = _orient(b2[:, c], b2[:, d], a2[:, a])
            o4 = _orient(b2[:, c], b2[:, d], a2[:, b])
            hit |= (o1 * o2 < -eps2 * eps2) & (o3 * o4 < -eps2 * eps2)
    return hit


def _triangles_intersect(A: NDArray, B: NDArray, eps: float) -> NDArray:
    """Möller's test on k triangle pairs A, B (k, 3, 3): True where their interiors intersect (an overlap
    of more than `eps` along the planes' common line, or a coplanar overlap of positive area)."""
    nA = np.cross(A[:, 1] - A[:, 0], A[:, 2] - A[:, 0])
    nB = np.cross(B[:, 1] - B[:, 0], B[:, 2] - B[:, 0])
    nA /= np.linalg.norm(nA, axis=1, keepdims=True)
    nB /= np.linalg.norm(nB, axis=1, keepdims=True)
    dB = np.einsum("kvi,ki->kv", B - A[:, :1], nA)  # B's vertices vs A's plane
    dA = np.einsum("kvi,ki->kv", A - B[:, :1], nB)
    dB[np.abs(dB) < eps] = 0.0
    dA[np.abs(dA) < eps] = 0.0
    apart = (np.all(dB > 0, axis=1) | np.all(dB < 0, axis=1) | np.all(dA > 0, axis=1)
             | np.all(dA < 0, axis=1))
    coplanar = np.all(dB == 0, axis=1) & ~apart
    hit = np.zeros(len(A), dtype=bool)
    if coplanar.any():
        hit[coplanar] = _coplanar_overlap(A[coplanar], B[coplanar], nA[coplanar], eps)
    cut = ~apart & ~coplanar
    if cut.any():
        D = np.cross(nA[cut], nB[cut])
        D /= np.linalg.norm(D, axis=1, keepdims=True)
        loA, hiA = _interval(dA[cut], np.einsum("kvi,ki->kv", A[cut], D))
        loB, hiB = _interval(dB[cut], np.einsum("kvi,ki->kv", B[cut], D))
        hit[cut] = np.fmin(hiA, hiB) - np.fmax(loA, loB) > eps
    return hit


def self_intersections(mesh: trimesh.Trimesh, eps: float | None = None) -> NDArray[np.int64]:
    """Face pairs (m, 2), i < j, whose triangles intersect and share no vertex.

    Args:
        mesh: triangle mesh (any units).
        eps: length below which distances count as zero (default 1e-9 × the bounding-box diagonal).

    Returns:
        Face index pairs, sorted; empty (0, 2) for a mesh free of self-intersections.
    """
    tris = np.asarray(mesh.triangles, dtype=float)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if eps is None:
        eps = 1e-9 * float(np.linalg.norm(mesh.extents))
    i, j = _candidate_pairs(tris, faces, eps)
    hit = np.zeros(len(i), dtype=bool)
    for start in range(0, len(i), _CHUNK):  # bounded memory on large meshes
        k = slice(start, start + _CHUNK)
        hit[k] = _triangles_intersect(tris[i[k]], tris[j[k]], eps)
    return np.stack([i[hit], j[hit]], axis=1)


# ---------------------------------------------------------------------------- manifold3d solids
def to_manifold(mesh: trimesh.Trimesh):
    """The `manifold3d.Manifold` of a closed, outward-wound mesh (double precision).

    Raises:
        MeshError: manifold3d rejects it (not a closed 2-manifold).
    """
    import manifold3d

    solid = manifold3d.Manifold(manifold3d.Mesh64(vert_properties=np.asarray(mesh.vertices, dtype=float),
                                                  tri_verts=np.asarray(mesh.faces, dtype=np.uint32)))
    if solid.status() != manifold3d.Error.NoError:
        raise MeshError(f"not a closed 2-manifold ({solid.status().name})")
    return solid


def from_manifold(solid) -> trimesh.Trimesh:
    """A `manifold3d.Manifold` as a trimesh (shared vertices, outward winding)."""
    out = solid.to_mesh64()
    mesh = trimesh.Trimesh(np.asarray(out.vert_properties)[:, :3], np.asarray(out.tri_verts, dtype=np.int64),
                           process=False)
    mesh.merge_vertices()
    return mesh


def union_of_shells(parts: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """Boolean union (manifold3d) of closed, outward-wound shells, each free of self-intersections.

    Raises:
        MeshError: manifold3d rejects a shell (not a closed 2-manifold) or returns an empty union.
    """
    import manifold3d

    solids = []
    for k, part in enumerate(parts):
        try:
            solids.append(to_manifold(part))
        except MeshError as exc:
            raise MeshError(f"shell {k}: {exc}") from None
    union = manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add)
    if union.is_empty():
        raise MeshError("the union of the shells is empty")
    return from_manifold(union)


def _nested(parts: list[trimesh.Trimesh]) -> bool:
    """True if a vertex of one shell lies inside another shell (shells that do not cross each other lie
    wholly inside or outside one another, so one vertex per shell decides)."""
    firsts = np.array([part.vertices[0] for part in parts])
    for a, outer in enumerate(parts):
        others = np.delete(firsts, a, axis=0)
        lo, hi = outer.bounds
        maybe = np.all((others >= lo) & (others <= hi), axis=1)
        if maybe.any() and bool(outer.contains(others[maybe]).any()):
            return True
    return False


def repair_shells(mesh: trimesh.Trimesh, where: str) -> trimesh.Trimesh:
    """`mesh` if its shells are disjoint and free of self-intersections; else the union of its shells.

    Shells that intersect one another, or that lie inside one another, are replaced by their union
    (each shell first wound outward). Shells that only touch at vertices stay as they are.

    Args:
        mesh: watertight mesh (outward winding), any units.
        where: what to name in messages (the file).

    Raises:
        MeshError: naming `where`, if a shell intersects itself (two faces of one shell cross).
    """
    comps = shells(mesh)
    pairs = self_intersections(mesh)
    shell_of_face = np.empty(len(mesh.faces), dtype=np.int64)
    for k, g in enumerate(comps):
        shell_of_face[g] = k
    same = shell_of_face[pairs[:, 0]] == shell_of_face[pairs[:, 1]] if len(pairs) else np.zeros(0, bool)
    if same.any():
        fi, fj = pairs[same][0]
        raise MeshError(f"{where}: the surface intersects itself ({int(same.sum())} crossing face pairs in "
                        f"one shell, e.g. faces {fi} and {fj}); repair the mesh (e.g. remesh it) first")
    if len(comps) == 1:
        return mesh
    parts = [mesh.submesh([g], append=True, repair=False) for g in comps]
    inverted = [part.volume < 0 for part in parts]
    for part, inv in zip(parts, inverted, strict=True):
        if inv:
            part.invert()
    if len(pairs) == 0 and not _nested(parts):
        if not any(inverted):
            return mesh
        log.warning("%s: %d of %d disjoint shells were wound inward; turned outward", where, sum(inverted),
                    len(parts))
        return trimesh.util.concatenate(parts)
    try:
        union = union_of_shells(parts)
    except MeshError as exc:
        raise MeshError(f"{where}: {exc}") from None
    log.warning("%s: of its %d shells, some intersect (%d crossing face pairs) or lie inside others; using "
                "their union (%d faces, %.4g m³ instead of %.4g m³ summed)", where, len(parts), len(pairs),
                len(union.faces), union.volume, sum(p.volume for p in parts))
    return union
