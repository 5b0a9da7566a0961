"""Distances over the surface (`SurfaceWay`) against closed forms: over a cup's rounded rim (the outer face
up, the half torus of the rim, the inner face down) and across a box's edge (the two faces unfolded into
a plane); way points that walk over the rim, not through the wall."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from regrasp_casadi.shapes import box_mesh, cup_mesh
from regrasp_casadi.surface_way import MAX_EDGE, SurfaceWay

R, H, W = 0.04, 0.095, 0.004  # the cup's outer radius, wall height and wall thickness, m


@pytest.fixture(scope="module")
def cup():
    mesh = cup_mesh(R, H, W, 0.004, sections=64)
    z_top = float(mesh.bounds[1, 2]) - W / 2  # where the walls meet the rim's half torus
    return mesh, SurfaceWay(mesh), z_top


def test_the_way_from_the_outer_face_to_the_inner_goes_over_the_rim(cup):
    mesh, way, z_top = cup
    outer = np.array([R, 0.0, z_top - 0.030])  # both in the meridian plane y = 0 (a vertex line)
    inner = np.array([R - W, 0.0, z_top - 0.020])
    for p in (outer, inner):  # the points are on the mesh
        assert abs(trimesh.proximity.signed_distance(mesh, p[None])[0]) < 1e-6
    over_the_rim = 0.030 + math.pi * W / 2 + 0.020  # up, the half circle of the rim, down: 56.3 mm
    d = way.distance(way.field(inner), outer)
    assert abs(d - over_the_rim) <= 0.1 * over_the_rim + MAX_EDGE, (d, over_the_rim)
    assert d > 4 * np.linalg.norm(outer - inner)  # not through the wall (10.8 mm straight)


def test_the_way_across_a_box_edge_is_the_unfolded_straight_line():
    a, b, c = 0.025, 0.045, 0.0875  # the half extents of a 5 × 9 × 17.5 cm box
    mesh = box_mesh((2 * a, 2 * b, 2 * c))
    way = SurfaceWay(mesh)
    p = np.array([a, 0.0, 0.0])  # on the face x = a
    goal = np.array([0.0, b, 0.03])  # on the face y = b
    unfolded = math.hypot(b + a, 0.03)  # the faces unfolded about their common edge: 76.2 mm
    d = way.distance(way.field(goal), p)
    assert abs(d - unfolded) <= 0.1 * unfolded + MAX_EDGE, (d, unfolded)
    assert d >= np.linalg.norm(p - goal)  # never shorter than the straight line (59.6 mm)


def test_way_points_walk_over_the_rim_to_the_goal(cup):
    mesh, way, z_top = cup
    start, goal = np.array([R, 0.0, z_top - 0.030]), np.array([R - W, 0.0, z_top - 0.020])
    to_goal = way.field(goal)
    reach = 0.01
    points, p = [], start
    for _ in range(12):
        nxt, normal = way.way_point(to_goal, p, reach)
        assert np.linalg.norm(nxt - p) <= reach + 1e-9  # within reach (over the surface, so straight too)
        assert abs(np.linalg.norm(normal) - 1.0) < 1e-9
        if np.allclose(nxt, p):
            break
        assert way.distance(to_goal, nxt) < way.distance(to_goal, p)  # always nearer the goal
        points.append(nxt)
        p = nxt
    points = np.array(points)
    assert np.max(np.abs(trimesh.proximity.signed_distance(mesh, points))) < 1e-6  # on the surface
    assert np.linalg.norm(points[-1] - goal) <= 2 * MAX_EDGE  # arrived
    assert np.max(points[:, 2]) >= z_top - 1e-9  # up to the top of the wall: over the rim, not through
    assert len(points) <= math.ceil(0.0563 / reach) + 3


def test_a_surface_gait_from_inside_a_bowl_aims_over_the_rim_first():
    """The index of the generated bowl pair of seed 3 stalled on the inner face, its goal on the outer: the
    way point nearest the goal over the surface lies along the inner face, from where the goal is still
    behind the wall; `way_target` picks one on the rim's top, from where the straight line to the goal
    tip centre is clear of the bowl (trimesh's exact distances)."""
    from pathlib import Path

    from regrasp_casadi.long_gait import way_target
    from regrasp_casadi.problem import RegraspProblem

    problem = RegraspProblem.load(Path(__file__).parent / "data" / "bowl_index_inside_the_rim.yaml")
    hand, mesh = problem.hand, problem.obj.mesh
    mesh_mm = trimesh.Trimesh(mesh.vertices * 1e3, mesh.faces)  # (trimesh's tolerance: in mm, DESIGN.md)
    r, rho = hand.fingers.index("index"), hand.tip_radius
    contact, goal_tip = problem.grasp0.contacts_object[r], problem.grasp_goal.tip_centers_object[r]
    way = SurfaceWay(mesh)
    to_goal = way.field(problem.grasp_goal.contacts_object[r])

    def blocked(tip):  # the deepest point of the straight line from tip to the goal tip inside the bowl, m
        line = tip + np.linspace(0.0, 1.0, 41)[:, None] * (goal_tip - tip)
        return float(np.max(trimesh.proximity.signed_distance(mesh_mm, line * 1e3))) * 1e-3  # > 0 inside

    assert blocked(problem.grasp0.tip_centers_object[r]) > 0.001  # the wall between (2.0 mm deep)
    nearest, n = way.way_point(to_goal, contact, 0.01)
    assert blocked(nearest + rho * n) > 0.0005
    target = way_target(way, problem.obj, to_goal, contact, goal_tip, reach=0.01, tip_radius=rho)
    assert blocked(target) < -0.0005
    closest, distance, _ = trimesh.proximity.closest_point(mesh_mm, target[None] * 1e3)
    assert abs(distance[0] * 1e-3 - rho) < 2e-4  # the tip centre ρ off the surface
    assert closest[0, 2] * 1e-3 >= float(mesh.bounds[1, 2]) - 0.002  # on the rim's top
