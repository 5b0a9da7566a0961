"""Tests of `grasp_gen.open_fraction`, the openness of the approach to a contact target: every point of a
convex body is open (its cone of rays stays on the outer side of the tangent plane), and on a cup's
inner wall the fraction equals the closed-form count of rays that leave over the rim (ray–cylinder
intersection)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from regrasp_casadi import shapes
from regrasp_casadi.grasp_gen import open_fraction

TIP = 0.012


def test_convex_bodies_are_open_everywhere():
    for mesh in (trimesh.creation.box(extents=(0.05, 0.07, 0.12)), shapes.sphere_mesh(0.035)):
        pts, face = trimesh.sample.sample_surface(mesh, 500, seed=2)
        np.testing.assert_array_equal(open_fraction(mesh, pts, mesh.face_normals[face], TIP), 1.0)


def _cone(n, half_angles=(0.0, 25.0, 50.0), per_ring=8):
    """The cone directions of `open_fraction` about the unit normal n (3,), same construction."""
    helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    out = []
    for a in np.radians(half_angles):
        for b in (np.arange(per_ring) * 2 * np.pi / per_ring if a > 0 else [0.0]):
            out.append(np.cos(a) * n + np.sin(a) * (np.cos(b) * e1 + np.sin(b) * e2))
    return np.array(out)


def test_cup_inner_wall_counts_the_rays_that_clear_the_rim():
    """A ray from the tip centre in front of the inner wall (radius ρ = R − w) meets the cylinder again at
    the positive root t of |o + t·d|_xy = ρ; it leaves the cup iff it is then above the wall's top."""
    R, H, w, b = 0.04, 0.095, 0.004, 0.004
    mesh = shapes.cup_mesh(radius=R, height=H, wall=w, bottom=b)
    shift = mesh.bounds[0, 2]  # the bottom's z after centring
    rho, top = R - w, H + shift
    compared = []
    for depth in np.arange(0.012, 0.08, 0.004):
        p = np.array([rho, 0.0, top - depth])
        n = np.array([-1.0, 0.0, 0.0])
        o = p + (TIP + 1e-3) * n
        escape = []
        for d in _cone(n):
            a = d[0] ** 2 + d[1] ** 2
            bb = 2 * (o[0] * d[0] + o[1] * d[1])
            c = o[0] ** 2 + o[1] ** 2 - rho**2
            t = (-bb + np.sqrt(bb * bb - 4 * a * c)) / (2 * a)
            z = o[2] + t * d[2]
            escape.append(np.nan if abs(z - top) <= 0.004 else z > top)  # grazing the rounded rim
        if np.all(np.isfinite(escape)):
            compared.append(np.mean(escape))
            assert open_fraction(mesh, p[None], n[None], TIP)[0] == pytest.approx(compared[-1], abs=1e-12)
    assert len(compared) >= 5 and 0.0 in compared and max(compared) > 0.3  # deep: closed; high: open
