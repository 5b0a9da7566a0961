"""Tests of regrasp_casadi.shapes: the generated objects are solids in metres with the stated volume
(closed forms, or a Monte-Carlo estimate of the mug's handle from its implicit definition), outward
normals, one shell, no self-intersection, and the stated genus (Euler characteristic)."""

from __future__ import annotations

import numpy as np
import pytest

from regrasp_casadi import shapes
from regrasp_casadi.mesh_repair import genus, self_intersections, shells


def _rim_volume(R, w):
    """Half torus of tube radius w/2 whose tube centre circle has radius R − w/2 (Pappus)."""
    a = w / 2
    return np.pi**2 * a * a * (R - a)


def _bowl_volume(R=0.06, w=0.004):
    return 2 / 3 * np.pi * (R**3 - (R - w) ** 3) + _rim_volume(R, w)


def _cup_volume(R=0.04, H=0.095, w=0.004, b=0.004):
    return np.pi * R * R * H - np.pi * (R - w) ** 2 * (H - b) + _rim_volume(R, w)


def _tool_volume(L=0.20, t=0.015, wh=0.025, lh=0.08, wb=0.045, rc=0.01):
    return (wh * (L - lh - wh / 2) + np.pi * wh**2 / 8 + lh * wb - (2 - np.pi / 2) * rc * rc) * t


def _holed_box_volume(e=(0.05, 0.07, 0.09), r=0.002, n=12):
    return np.prod(e) - n / 2 * r * r * np.sin(2 * np.pi / n) * sum(e)


def _handle_volume_mc(R=0.04, H=0.095, rm=0.028, rh=0.005, n=400_000):
    """Volume of the mug handle outside the cup, x² + y² > R², from the torus's implicit definition."""
    rng = np.random.default_rng(0)
    lo = np.array([R - 0.001, -rh, H / 2 - rm - rh])
    hi = np.array([R + rm + rh, rh, H / 2 + rm + rh])
    p = rng.uniform(lo, hi, (n, 3))
    ring = np.hypot(p[:, 0] - R, p[:, 2] - H / 2) - rm
    inside = (ring**2 + p[:, 1] ** 2 < rh**2) & (p[:, 0] ** 2 + p[:, 1] ** 2 > R * R)
    return float(inside.mean() * np.prod(hi - lo))


CASES = {
    # name: (mesh, reference volume m³, relative tolerance (polygonal approximation), genus, extents m)
    "bowl": (shapes.bowl_mesh, _bowl_volume(), 5e-3, 0, (0.12, 0.12, 0.062)),
    "cup": (shapes.cup_mesh, _cup_volume(), 5e-3, 0, (0.08, 0.08, 0.097)),
    "mug": (shapes.mug_mesh, _cup_volume() + _handle_volume_mc(), 1e-2, 1, (0.113, 0.08, 0.097)),
    "flat_tool": (shapes.flat_tool_mesh, _tool_volume(), 1e-3, 0, (0.20, 0.045, 0.015)),
    "holed_box": (shapes.holed_box_mesh, _holed_box_volume(), 1e-9, 3, (0.05, 0.07, 0.09)),
}


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    make, volume, rtol, g, extents = CASES[request.param]
    return request.param, make(), volume, rtol, g, extents


def test_volume_matches_the_closed_form(case):
    name, mesh, volume, rtol, _, _ = case
    assert mesh.volume == pytest.approx(volume, rel=rtol), name


def test_solid_in_metres_centred(case):
    name, mesh, _, _, g, extents = case
    assert mesh.is_watertight and mesh.is_winding_consistent, name
    assert len(shells(mesh)) == 1 and len(self_intersections(mesh)) == 0, name
    assert genus(mesh) == g and mesh.euler_number == 2 - 2 * g, name
    np.testing.assert_allclose(mesh.extents, extents, atol=1.5e-3, err_msg=name)
    assert np.linalg.norm(mesh.center_mass) < 1e-12, name


def test_normals_point_outward(case):
    """A point just off each face along its normal is outside; just behind it, inside."""
    name, mesh, _, _, _, _ = case
    rng = np.random.default_rng(1)
    faces = rng.choice(len(mesh.faces), size=min(300, len(mesh.faces)), replace=False)
    c, n = mesh.triangles_center[faces], mesh.face_normals[faces]
    eps = 2e-4  # smaller than half the thinnest wall (3 mm tunnels' and walls' scale: 2–4 mm)
    assert not mesh.contains(c + eps * n).any(), name
    assert mesh.contains(c - eps * n).all(), name


def _wall_thickness(mesh, origins, directions):
    """Distance between the first two surface hits of each ray (the wall it enters first), m."""
    loc, ray, _ = mesh.ray.intersects_location(origins, directions, multiple_hits=True)
    out = []
    for k in range(len(origins)):
        d = np.sort(np.linalg.norm(loc[ray == k] - origins[k], axis=1))
        out.append(d[1] - d[0])
    return np.array(out)


def test_thin_walls_are_4_mm():
    """Rays towards the axis through the cup's side wall and towards the bowl's centre through its shell."""
    a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    radial = np.stack([np.cos(a), np.sin(a), 0 * a], axis=1)
    cup = shapes.cup_mesh()
    z_mid = 0.5 * (cup.bounds[0, 2] + cup.bounds[1, 2])
    t_cup = _wall_thickness(cup, 0.2 * radial + [0, 0, z_mid], -radial)
    bowl = shapes.bowl_mesh()
    centre = np.array([0.0, 0.0, bowl.bounds[1, 2] - 0.002])  # the hemispheres' centre: rim top − w/2
    down = np.stack([0.5 * np.cos(a), 0.5 * np.sin(a), -np.ones_like(a)], axis=1)
    down /= np.linalg.norm(down, axis=1, keepdims=True)
    t_bowl = _wall_thickness(bowl, centre + 0.2 * down, -down)
    for t in (t_cup, t_bowl):
        np.testing.assert_allclose(t, 0.004, atol=2e-5)


def test_default_sphere_is_7_cm_across():
    m = shapes.sphere_mesh(0.035)
    np.testing.assert_allclose(np.linalg.norm(m.vertices, axis=1), 0.035, atol=1e-15)
    assert m.extents.max() == pytest.approx(0.07, abs=1e-3)
