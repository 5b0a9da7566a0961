"""Generated object meshes at YCB sizes (box, cylinder, sphere, capsule, bottle, banana).

Every function returns a watertight `trimesh.Trimesh` in metres, winding outward (volume > 0), centred
at (or near) its centre of mass, so that examples and tests need no mesh files. `ObjectModel`'s
classmethods of the same names wrap them (see `regrasp_casadi.objects`).

    >>> from regrasp_casadi.shapes import banana_mesh
    >>> m = banana_mesh()
    >>> m.is_watertight
    True
"""

from __future__ import annotations

import numpy as np
import trimesh

__all__ = [
    "box_mesh",
    "cylinder_mesh",
    "sphere_mesh",
    "capsule_mesh",
    "bottle_mesh",
    "banana_mesh",
]


def box_mesh(extents) -> trimesh.Trimesh:
    """Axis-aligned box centred at the origin; extents (3,) full side lengths, m."""
    return trimesh.creation.box(extents=np.asarray(extents, dtype=float))


def cylinder_mesh(radius: float, height: float, sections: int = 32) -> trimesh.Trimesh:
    """Cylinder about z, centred at the origin; `sections` sides (34 planes for 32), m."""
    return trimesh.creation.cylinder(radius=float(radius), height=float(height), sections=int(sections))


def sphere_mesh(radius: float, subdivisions: int = 2) -> trimesh.Trimesh:
    """Icosphere of `radius` m (vertices on the sphere; 320 faces for subdivisions=2)."""
    return trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=float(radius))


def capsule_mesh(radius: float, height: float, count: tuple[int, int] = (16, 16)) -> trimesh.Trimesh:
    """Capsule about z centred at the origin: `height` is the cylinder part between the cap centres, m."""
    return trimesh.creation.capsule(height=float(height), radius=float(radius), count=list(count))


def _centre(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    mesh.apply_translation(-mesh.center_mass)
    return mesh


def bottle_mesh(
    body_radius: float = 0.03,
    body_height: float = 0.12,
    shoulder_height: float = 0.03,
    neck_radius: float = 0.012,
    neck_height: float = 0.04,
    sections: int = 32,
) -> trimesh.Trimesh:
    """Solid of revolution about z: body, conical shoulder, neck (mustard-bottle-like, 0.19 m tall).

    The profile has a small bevel at the base and the top so that no edge is a sharp 90° rim.

    Args:
        body_radius: radius of the body, m.
        body_height: height of the cylindrical body, m.
        shoulder_height: height of the cone from body to neck, m.
        neck_radius: radius of the neck, m.
        neck_height: height of the neck, m.
        sections: segments around the axis.

    Returns:
        Watertight mesh, metres, centred at its centre of mass.
    """
    b = min(0.003, 0.25 * neck_radius)
    z1 = body_height
    z2 = z1 + shoulder_height
    z3 = z2 + neck_height
    profile = np.array(
        [
            [0.0, 0.0],
            [body_radius - b, 0.0],
            [body_radius, b],
            [body_radius, z1],
            [neck_radius, z2],
            [neck_radius, z3 - b],
            [neck_radius - b, z3],
            [0.0, z3],
        ]
    )
    mesh = trimesh.creation.revolve(profile, sections=int(sections))
    mesh.merge_vertices()
    if mesh.volume < 0:
        mesh.invert()
    return _centre(mesh)


def banana_mesh(
    length: float = 0.18,
    thickness: float = 0.036,
    bend_radius: float = 0.13,
    rings: int = 24,
    sections: int = 16,
    tip_radius: float = 0.004,
) -> trimesh.Trimesh:
    """A curved, tapered tube: circles swept along a planar arc (in the x-y plane), closed by cone tips.

    The tube radius follows r(s) = tip + (thickness/2 − tip)·sin(π s)^0.6 over the arc parameter s ∈ [0, 1].

    Args:
        length: arc length of the centre line, m (≈ the YCB banana's 0.18 m).
        thickness: largest diameter, m.
        bend_radius: radius of the centre-line arc, m.
        rings: number of circular cross-sections along the arc.
        sections: vertices per cross-section.
        tip_radius: radius of the first and last cross-section, m.

    Returns:
        Watertight mesh, metres, centred at its centre of mass.
    """
    angle = length / bend_radius
    s = np.linspace(0.0, 1.0, int(rings))
    phi = (s - 0.5) * angle
    centres = np.stack([bend_radius * np.sin(phi), bend_radius * (1.0 - np.cos(phi)), 0 * phi], axis=1)
    tangents = np.stack([np.cos(phi), np.sin(phi), 0 * phi], axis=1)
    normals = np.stack([-np.sin(phi), np.cos(phi), 0 * phi], axis=1)
    binormal = np.array([0.0, 0.0, 1.0])
    r = tip_radius + (0.5 * thickness - tip_radius) * np.sin(np.pi * s) ** 0.6
    theta = np.linspace(0.0, 2 * np.pi, int(sections), endpoint=False)
    ring_pts = (
        centres[:, None, :]
        + r[:, None, None] * np.cos(theta)[None, :, None] * normals[:, None, :]
        + r[:, None, None] * np.sin(theta)[None, :, None] * binormal[None, None, :]
    )
    n_r, n_s = ring_pts.shape[:2]
    verts = [ring_pts.reshape(-1, 3)]
    tip0 = centres[0] - tangents[0] * tip_radius
    tip1 = centres[-1] + tangents[-1] * tip_radius
    verts.append(np.stack([tip0, tip1]))
    verts = np.concatenate(verts)
    i0, i1 = n_r * n_s, n_r * n_s + 1
    faces = []
    for i in range(n_r - 1):
        for j in range(n_s):
            a, b = i * n_s + j, i * n_s + (j + 1) % n_s
            c, d = a + n_s, b + n_s
            faces += [[a, b, d], [a, d, c]]
    for j in range(n_s):
        faces.append([i0, (j + 1) % n_s, j])
        last = (n_r - 1) * n_s
        faces.append([i1, last + j, last + (j + 1) % n_s])
    mesh = trimesh.Trimesh(verts, np.asarray(faces), process=True)
    trimesh.repair.fix_normals(mesh)
    if mesh.volume < 0:
        mesh.invert()
    return _centre(mesh)
