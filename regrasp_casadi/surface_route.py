"""Routes over the object's surface: the gait target of a finger whose goal lies behind the object.

OPT1 moves a fingertip by at most η per gait towards its goal tip centre, lowering the straight-line
distance to it. When that straight line runs through the object — a contact on the outside of a bowl's
wall whose goal is on the inside, a thumb on one face of a box whose goal is round an edge — the nearest
surface point to the goal is a local minimum of OPT1 on the wrong side: the finger stalls there, its
contact a wall's thickness from its goal in a straight line and a rim away along the surface (measured:
the generated bowl pair of seed 3, the index stalled 27.7 mm from its goal, "the object lies between
its tip and its goal: the straight line passes 1.9 mm inside it").

The route follows the surface instead. The object's mesh, subdivided to edges of at most `MAX_EDGE`,
is a graph whose edges weigh their lengths; Dijkstra's algorithm from each goal contact gives every
vertex its graph distance to the goal along the surface, g(v), and the vertex before it on the shortest
way. A contact c with outward normal n enters the graph at its nearest vertices that face its way
(vertex normal · n ≥ `FACING`, so a contact on one face of a thin wall does not enter through the
other face), as

    G(c) = min_v ( ||c − v|| + g(v) ),

and its gait target is the vertex `ahead` (m, η) farther along the shortest way, lifted by the tip
radius ρ along its vertex normal: p_target = v_k + ρ n(v_k), where v_k is the first vertex on the way
with G(c) − g(v_k) ≥ `ahead` (the goal tip centre itself when G(c) ≤ `ahead`). OPT1 then walks the
finger over the rim in η-steps, each an ordinary gait judged by the exact checks and its path.

`gait_target` applies it only where the straight line from the tip centre to the goal tip centre
passes inside the object (`line_blocked`); elsewhere the target is the goal tip centre, as in the
paper.

    >>> routes = SurfaceRoutes(obj, goal_contacts_object)        # (m, 3) object frame, m
    >>> p_object_target = routes.target(r, p_object_contact, n_object, eta, rho)
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import trimesh
from numpy.typing import NDArray
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.planner import _Run

__all__ = ["FACING", "MAX_EDGE", "SurfaceGraph", "SurfaceRoutes", "fingers_across", "gait_target",
           "line_blocked", "line_clearance", "nearer_goal", "surface_graph", "surface_targets"]

MAX_EDGE = 0.005
"""Longest edge of the subdivided mesh the routes run on, m (η / 2)."""
FACING = 0.3
"""A contact enters the graph at vertices whose normal · the contact's normal is at least this."""
_ENTRIES = 12
"""Nearest vertices considered as a point's entries into the graph."""
_LINE_SAMPLES = 21
"""Samples of the straight tip-to-goal line in `line_blocked`."""
_NO_VERTEX = -9999
"""scipy's `dijkstra` predecessor of the source and of unreached vertices."""


class SurfaceGraph:
    """The object's mesh subdivided to `max_edge` (m), as a graph of its edges (weights: lengths, m).

    Attributes: `vertices` (v, 3) and `normals` (v, 3), object frame; `graph` (v, v) sparse, symmetric.
    """

    def __init__(self, obj: ObjectModel, max_edge: float = MAX_EDGE):
        v, f = trimesh.remesh.subdivide_to_size(np.asarray(obj.mesh.vertices, float),
                                                np.asarray(obj.mesh.faces), max_edge=max_edge)
        mesh = trimesh.Trimesh(v, f, process=True)
        self.vertices = np.asarray(mesh.vertices, dtype=float)
        self.normals = np.asarray(mesh.vertex_normals, dtype=float)
        e, w = np.asarray(mesh.edges_unique), np.asarray(mesh.edges_unique_length, dtype=float)
        n = len(self.vertices)
        self.graph = sp.csr_matrix((np.concatenate([w, w]), (np.concatenate([e[:, 0], e[:, 1]]),
                                                              np.concatenate([e[:, 1], e[:, 0]]))),
                                   shape=(n, n))
        self._tree = cKDTree(self.vertices)

    def entries(self, p_object: NDArray, n_object: NDArray) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """The vertices a surface point p_object (3,) with outward normal n_object (3,) enters the graph
        at (those of its `_ENTRIES` nearest that face its way, else the nearest), and their distances, m."""
        k = min(_ENTRIES, len(self.vertices))
        d, idx = self._tree.query(np.asarray(p_object, float), k=k)
        d, idx = np.atleast_1d(d), np.atleast_1d(idx)
        facing = self.normals[idx] @ np.asarray(n_object, float) >= FACING
        if not np.any(facing):
            facing[0] = True
        return idx[facing], d[facing]


_GRAPHS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def surface_graph(obj: ObjectModel) -> SurfaceGraph:
    """The object's `SurfaceGraph`, built once per object (0.1 s on the generated bowl, 0.5 s on the cup,
    whose 9.5 cm side triangles split into many)."""
    graph = _GRAPHS.get(obj)
    if graph is None:
        graph = _GRAPHS[obj] = SurfaceGraph(obj)
    return graph


class SurfaceRoutes:
    """Shortest ways over the surface to each goal contact (module docstring).

    Args:
        obj: the object.
        goal_contacts_object: (m, 3) goal contacts, object frame, m.
    """

    def __init__(self, obj: ObjectModel, goal_contacts_object: NDArray):
        self.surface = surface_graph(obj)
        self.goals = np.asarray(goal_contacts_object, dtype=float)
        normals = np.asarray(obj.surface_normals(self.goals), dtype=float)
        n = len(self.surface.vertices)
        self.to_goal: list[NDArray[np.float64]] = []
        """Per goal: g(v) (v,), the graph distance of each vertex to the goal contact, m."""
        self.next_vertex: list[NDArray[np.int64]] = []
        """Per goal: (v,) the vertex after each on its shortest way to the goal (n: the goal itself)."""
        coo = self.surface.graph.tocoo()
        for goal, normal in zip(self.goals, normals, strict=True):
            idx, d = self.surface.entries(goal, normal)  # the goal as one more node, n, joined to these
            rows, cols = np.concatenate([coo.row, np.full(len(idx), n)]), np.concatenate([coo.col, idx])
            graph = sp.csr_matrix((np.concatenate([coo.data, d]), (rows, cols)), shape=(n + 1, n + 1))
            # from the goal node: the predecessor of a vertex is the next one on its way to the goal
            dist, pred = dijkstra(graph, directed=True, indices=n, return_predecessors=True)
            self.to_goal.append(dist[:n])
            self.next_vertex.append(pred[:n])

    def distance(self, r: int, p_object: NDArray, n_object: NDArray) -> tuple[float, int]:
        """G(p) for goal r: the distance (m) from the surface point p_object (3,) (outward normal
        n_object (3,)) to goal contact r along the surface, and the vertex it enters the way at."""
        idx, d = self.surface.entries(p_object, n_object)
        total = d + self.to_goal[r][idx]
        k = int(np.argmin(total))
        return float(total[k]), int(idx[k])

    def target(self, r: int, p_object: NDArray, n_object: NDArray, ahead: float, rho: float
               ) -> NDArray[np.float64] | None:
        """The tip-centre target (3,), object frame, m, `ahead` (m) along the way from the contact
        p_object (normal n_object) to goal r, lifted by the tip radius rho (m); None when the goal is
        within `ahead` (or not connected to the contact): then the target is the goal tip centre."""
        total, v = self.distance(r, p_object, n_object)
        n = len(self.surface.vertices)
        if not np.isfinite(total) or total <= ahead:
            return None
        nxt = self.next_vertex[r]
        while nxt[v] not in (n, _NO_VERTEX) and total - self.to_goal[r][v] < ahead:
            v = int(nxt[v])
        return self.surface.vertices[v] + rho * self.surface.normals[v]


def line_clearance(obj: ObjectModel, a_object: NDArray, b_object: NDArray, n_samples: int = _LINE_SAMPLES
                   ) -> float:
    """Least exact signed distance (m, < 0 inside) to the object of the straight line from a_object to
    b_object ((3,) each, object frame, m), at n_samples evenly spaced points."""
    s = np.linspace(0.0, 1.0, n_samples)[:, None]
    line = np.asarray(a_object, float) + s * (np.asarray(b_object, float) - np.asarray(a_object, float))
    return float(np.min(obj.exact_signed_distance(line)))


def line_blocked(obj: ObjectModel, tip_object: NDArray, goal_tip_object: NDArray) -> bool:
    """Whether the straight line from the tip centre to the goal tip centre ((3,) each, object frame,
    m) passes inside the object (`line_clearance` < 0). Not merely closer than the tip radius: between
    two tip centres over a convex curved face the line always is (a sphere's chord), and OPT1's straight
    pull is right there (measured: with that test the generated sphere pair of seed 1 stalled with the
    SVD method, which converges without routes)."""
    return line_clearance(obj, tip_object, goal_tip_object) < 0.0


def fingers_across(obj: ObjectModel, tips_object: NDArray, goal_tips_object: NDArray, contact_error: NDArray,
                   zeta: float) -> list[int]:
    """The rows r of the fingers within ζ of their goals (contact_error[r] ≤ zeta, m) whose tip is across
    the object from its goal: the straight line from the tip centre to the goal tip centre ((m, 3) each,
    object frame, m) passes inside it (`line_blocked`). The contact error does not see a wall: a tip on
    the outside of a bowl's 4 mm wall is 4 mm from a goal right across it on the inside (measured: the
    index so placed on the bowl pair of tests/data/bowl_index_behind_the_rim.yaml, both methods said
    "converged" without a move, and `verify`'s goal_side check failed them)."""
    return [r for r, e in enumerate(np.asarray(contact_error, float))
            if e <= zeta and line_blocked(obj, tips_object[r], goal_tips_object[r])]


def gait_target(run: _Run, r: int) -> NDArray[np.float64]:
    """OPT1's tip-centre target for finger r of the planner's run (object frame, m): the goal tip centre,
    or, when the straight line to it is blocked (`line_blocked`), `PlannerOptions.surface_routes` is on
    and the plan has gone `PlannerOptions.route_after` iterations without progress, the point η along
    the surface route (`SurfaceRoutes.target`)."""
    tip = _routed_tip(run, r)
    if tip is None:
        return run.goal_tips[r]
    contact, normal = _contact(run, tip)
    target = _routes(run).target(r, contact, normal, run.options.finger_gait.eta, float(run.hand.tip_radius))
    return run.goal_tips[r] if target is None else target


def nearer_goal(run: _Run, r: int, p_object_tip: NDArray) -> bool:
    """Whether finger r's tip centre at `p_object_tip` (3,), object frame, m, has its contact nearer its
    goal contact than the finger's contact now: along the surface (`SurfaceRoutes.distance`) where
    `gait_target` routes the finger, else in a straight line (the contact error). A gait up a rim's
    outer face is nearer along the surface though farther in a straight line; one back down it is not
    (measured: the generated bowl pair of seed 19, SD, the index 71–73 mm from its goal for 20
    iterations, each route gait up the rim undone by a `long_gait` back down)."""
    tip = _routed_tip(run, r)
    if tip is not None:
        routes = _routes(run)
        after, now = (routes.distance(r, *_contact(run, p))[0] for p in (p_object_tip, tip))
        return after < now
    contact, _ = run.obj.closest_points(np.asarray(p_object_tip, float)[None])
    return float(np.linalg.norm(contact[0] - run.goal_contacts[r])) < float(run.steps[-1].contact_error[r])


def _routed_tip(run: _Run, r: int) -> NDArray | None:
    """Finger r's tip centre (3,), object frame, m, when `gait_target` routes it, else None (the cheap
    conditions first: the kinematics and the exact distances only once the plan has stalled)."""
    if not run.options.surface_routes or run.stalled < run.options.route_after:
        return None
    tip = run.tips_object()[r]
    return tip if line_blocked(run.obj, tip, run.goal_tips[r]) else None


def _routes(run: _Run) -> SurfaceRoutes:
    """The run's routes to its goal contacts, built when first needed."""
    if run.routes is None:
        run.routes = SurfaceRoutes(run.obj, run.goal_contacts)
    return run.routes


def _contact(run: _Run, tip: NDArray) -> tuple[NDArray, NDArray]:
    """The contact (3,) of the tip centre `tip` (3,), object frame, m, and its outward normal (3,): from
    the contact to the tip, or the surface's where the tip centre is on it."""
    contact = run.obj.closest_points(np.asarray(tip, float)[None])[0][0]
    normal = tip - contact
    length = float(np.linalg.norm(normal))
    normal = normal / length if length > 1e-9 else np.asarray(run.obj.surface_normals(contact[None]))[0]
    return contact, normal


def surface_targets(obj: ObjectModel, tip_radius: float, tip: NDArray, goal_tip: NDArray, distance: float,
                    n_dirs: int) -> tuple[NDArray, NDArray, NDArray]:
    """Tip-sphere centres (radius `tip_radius`, m) on the surface about `distance` (m) from `tip` (3,),
    object frame: the first towards `goal_tip` (3,) (at most as far as it), the others at `n_dirs` − 1
    more directions of the tangent plane. Returns (tips, contacts, outward normals), each (n_dirs, 3),
    object frame."""
    r = float(tip_radius)
    (c0,), _ = obj.closest_points(np.asarray(tip, float).reshape(1, 3))
    n0 = (tip - c0) / max(float(np.linalg.norm(tip - c0)), 1e-12)
    to_goal = np.asarray(goal_tip, float) - tip
    u = to_goal - (to_goal @ n0) * n0
    if np.linalg.norm(u) < 1e-9:
        u = np.cross(n0, [1.0, 0.0, 0.0] if abs(n0[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n0, u)
    theta = 2 * np.pi * np.arange(n_dirs) / n_dirs
    d = np.full(n_dirs, float(distance))
    d[0] = min(d[0], float(np.linalg.norm(to_goal)))
    moved = tip + d[:, None] * (np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v)
    contacts, sd = obj.closest_points(moved)
    away = (moved - contacts) * np.sign(np.where(sd == 0, 1.0, sd))[:, None]
    normals = away / np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-12)
    return contacts + r * normals, np.asarray(contacts, float), normals
