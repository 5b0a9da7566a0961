"""The way over the surface: geodesic distances on the object's mesh, for a finger whose goal is across a
wall or a rim.

OPT1 pulls a tip straight towards its goal. On a thin-walled container a contact on the inner face whose
goal is on the outer face stops where the wall lies between them, and every gait towards the goal is a
local minimum (measured: the generated bowl pair of seed 3, SD, stalled with the index 51.6 mm from its
goal contact, the straight line from its tip to its goal 2.0 mm inside the bowl). Over the surface the
way goes up the inner face, over the rim and down the outer face. `SurfaceWay` measures that way: the
distance to a goal contact over the edges of the mesh subdivided to `max_edge` (Dijkstra's shortest
paths, longer than the true geodesic by at most the zig-zag of the edges, ~10 % on a fine mesh), and
gives a way point: among the mesh points within `reach` of a contact over the surface, the one nearest
the goal by that distance. OPT1 aimed at the way point (`long_gait`) walks the contact over the rim.

    >>> way = SurfaceWay(obj.mesh)                    # once per object (~0.1 s for a 10k-face mesh)
    >>> to_goal = way.field(goal_contact)             # (V,) distances to the goal, m
    >>> way.distance(to_goal, contact)                # the contact's distance to its goal, m
    >>> point, normal = way.way_point(to_goal, contact, reach=0.01)
"""

from __future__ import annotations

import numpy as np
import trimesh
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

__all__ = ["SurfaceWay", "MAX_EDGE"]

MAX_EDGE = 0.003
"""Longest edge of the subdivided mesh the distances run over, m (below the 3–5 mm walls of the generated
containers, so that no vertex of one face of a wall is nearer a point of the other than its own)."""


class SurfaceWay:
    """Distances over the surface of a closed mesh (object frame, m)."""

    def __init__(self, mesh: trimesh.Trimesh, max_edge: float = MAX_EDGE):
        v, f = trimesh.remesh.subdivide_to_size(np.asarray(mesh.vertices, float), np.asarray(mesh.faces),
                                                max_edge=max_edge)
        self.mesh = trimesh.Trimesh(v, f, process=True)  # (merges the split edges' vertices)
        """The subdivided mesh, object frame, m."""
        e, lengths = self.mesh.edges_unique, self.mesh.edges_unique_length
        n = len(self.mesh.vertices)
        self._graph = coo_matrix((np.concatenate([lengths, lengths]),
                                  (np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]]))),
                                 shape=(n, n)).tocsr()
        self._scaled = trimesh.Trimesh(self.mesh.vertices * 1e3, self.mesh.faces, process=False)
        # (closest points in mm: trimesh's fixed tolerance misjudges metre-scale meshes, DESIGN.md)

    def _face_vertices(self, p: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """The vertices (3,) of the face nearest the point p (3,) and their distances to p, m."""
        p = np.asarray(p, float).reshape(1, 3)
        _, _, face = trimesh.proximity.closest_point(self._scaled, p * 1e3)
        ids = self.mesh.faces[int(face[0])]
        return ids, np.linalg.norm(self.mesh.vertices[ids] - p, axis=1)

    def _from(self, p: ArrayLike, limit: float = np.inf) -> NDArray[np.float64]:
        """(V,) distance of every vertex from the point p (3,) on the surface over the edges (through the
        vertices of its face), m; inf beyond `limit`."""
        ids, d0 = self._face_vertices(p)
        D = dijkstra(self._graph, directed=False, indices=ids, limit=limit)
        return np.min(D + d0[:, None], axis=0)

    def field(self, p_goal: ArrayLike) -> NDArray[np.float64]:
        """(V,) distance of every vertex of `mesh` to the vertices of the face of the surface point
        p_goal (3,), m (one shortest-path search from the three: p_goal's own offset from them, below
        `max_edge`, is left out)."""
        ids, _ = self._face_vertices(p_goal)
        return np.asarray(dijkstra(self._graph, directed=False, indices=ids, min_only=True), float)

    def distance(self, field: NDArray[np.float64], p: ArrayLike) -> float:
        """The distance (m) of the surface point p (3,) to the goal of `field` (`field`), through the
        vertices of its face."""
        ids, d0 = self._face_vertices(p)
        return float(np.min(field[ids] + d0))

    def within(self, p: ArrayLike, reach: float) -> NDArray[np.int64]:
        """Indices of the vertices of `mesh` within `reach` (m, over the surface) of the surface point
        p (3,)."""
        return np.flatnonzero(self._from(p, limit=reach) <= reach)

    def way_point(self, field: NDArray[np.float64], p: ArrayLike, reach: float
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The vertex within `reach` (m, over the surface) of the surface point p (3,) nearest the goal of
        `field`, and its unit outward normal: (3,), (3,), object frame."""
        ids = self.within(p, reach)
        k = int(ids[np.argmin(field[ids])])
        return self.mesh.vertices[k].copy(), np.asarray(self.mesh.vertex_normals[k], float)
