"""Generated object meshes at YCB sizes: box, cylinder, sphere, capsule, bottle, banana, and the shapes
that are hard to grasp: a thin-walled bowl and cup, a mug with a handle, a flat tool and a box with
small through-holes (a scan-like artefact of genus 3).

Every function returns a watertight `trimesh.Trimesh` in metres, winding outward (volume > 0), centred
at (or near) its centre of mass, so that examples and tests need no mesh files. `ObjectModel`'s
classmethods of the same names wrap them (see `regrasp_casadi.objects`). Closed forms of their volumes
(of the smooth shapes the meshes approximate) are in the docstrings; the Boolean shapes (mug, holed box,
tool outline) are built with manifold3d.

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
    "bowl_mesh",
    "cup_mesh",
    "mug_mesh",
    "flat_tool_mesh",
    "holed_box_mesh",
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


# ---------------------------------------------------------------------------- thin-walled, holed, flat
def _arc(centre, radius: float, a0: float, a1: float, n: int) -> np.ndarray:
    """n + 1 points (r, z) of a circular arc from angle a0 to a1 (rad) about `centre` (r, z)."""
    a = np.linspace(a0, a1, int(n) + 1)
    return np.stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)], axis=1)


def _revolve(profile: np.ndarray, sections: int) -> trimesh.Trimesh:
    """Solid of revolution about z of a closed (r, z) profile that starts and ends on the axis."""
    mesh = trimesh.creation.revolve(profile, sections=int(sections))
    mesh.merge_vertices()
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _rim(r_outer: float, wall: float, z: float, n: int) -> np.ndarray:
    """The rounded rim of a wall (r_outer − wall ≤ r ≤ r_outer) at height z: a semicircle of diameter
    `wall` from the outer to the inner face, over the top (its end points excluded)."""
    a = 0.5 * wall
    return _arc((r_outer - a, z), a, 0.0, np.pi, n)[1:-1]


def bowl_mesh(radius: float = 0.06, wall: float = 0.004, segments: int = 24, rim_segments: int = 8,
              sections: int = 64) -> trimesh.Trimesh:
    """A hemispherical bowl, open at the top: the difference of two concentric solid hemispheres
    (outer `radius`, inner `radius − wall`) with a rounded rim (a half torus of tube diameter `wall`).

    Volume of the smooth shape: 2/3·π·(R³ − (R − w)³) + π²·(w/2)²·(R − w/2).

    Args:
        radius: outer radius, m (0.12 m across).
        wall: wall thickness, m.
        segments: segments of each quarter circle of the profile.
        rim_segments: segments of the rim's semicircle.
        sections: segments around the axis.

    Returns:
        Watertight mesh, metres, genus 0, centred at its centre of mass (opening towards +z).
    """
    R, w = float(radius), float(wall)
    profile = np.concatenate([_arc((0.0, 0.0), R, -np.pi / 2, 0.0, segments), _rim(R, w, 0.0, rim_segments),
                              _arc((0.0, 0.0), R - w, 0.0, -np.pi / 2, segments)])
    profile[[0, -1], 0] = 0.0  # exactly on the axis
    return _centre(_revolve(profile, sections))


def cup_mesh(radius: float = 0.04, height: float = 0.095, wall: float = 0.004, bottom: float = 0.004,
             rim_segments: int = 8, sections: int = 64) -> trimesh.Trimesh:
    """A cylindrical cup, open at the top: an outer cylinder minus the inner cylinder (radius
    `radius − wall`, from `bottom` up), with a rounded rim (a half torus of tube diameter `wall`) on top.

    Volume of the smooth shape: π·R²·H − π·(R − w)²·(H − b) + π²·(w/2)²·(R − w/2).

    Args:
        radius: outer radius, m.
        height: height of the walls (without the rim), m.
        wall: wall thickness, m.
        bottom: bottom thickness, m.
        rim_segments: segments of the rim's semicircle.
        sections: segments around the axis.

    Returns:
        Watertight mesh, metres, genus 0, centred at its centre of mass (opening towards +z).
    """
    R, H, w, b = float(radius), float(height), float(wall), float(bottom)
    profile = np.concatenate([[[0.0, 0.0], [R, 0.0], [R, H]], _rim(R, w, H, rim_segments),
                              [[R - w, H], [R - w, b], [0.0, b]]])
    return _centre(_revolve(profile, sections))


def _torus_xz(major: float, minor: float, centre, n_major: int, n_minor: int) -> trimesh.Trimesh:
    """Torus whose ring lies in the x-z plane (axis along y), centred at `centre` (3,), m."""
    torus = trimesh.creation.torus(major_radius=float(major), minor_radius=float(minor),
                                   major_sections=int(n_major), minor_sections=int(n_minor))
    torus.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1.0, 0.0, 0.0]))
    return torus.apply_translation(np.asarray(centre, dtype=float))


def mug_mesh(radius: float = 0.04, height: float = 0.095, wall: float = 0.004, bottom: float = 0.004,
             handle_radius: float = 0.028, handle_thickness: float = 0.01, sections: int = 64
             ) -> trimesh.Trimesh:
    """A mug: `cup_mesh` with a handle, the part outside the cup's cavity of a torus whose ring (radius
    `handle_radius`, tube diameter `handle_thickness`) lies in the x-z plane, centred on the outer
    wall at x = `radius`, half-way up (manifold3d union; the handle's loop makes the genus 1).

    Args:
        radius, height, wall, bottom: the cup's (see `cup_mesh`), m.
        handle_radius: radius of the handle's centre line, m (the handle reaches to x ≈ R + 0.033 m).
        handle_thickness: diameter of the handle's tube, m.
        sections: segments around the cup's axis.

    Returns:
        Watertight mesh, metres, genus 1, centred at its centre of mass.
    """
    import manifold3d

    from regrasp_casadi.mesh_repair import from_manifold, to_manifold

    R, H, w, b = float(radius), float(height), float(wall), float(bottom)
    if handle_radius + handle_thickness / 2 >= H / 2 - b:
        raise ValueError(f"handle_radius={handle_radius}: the handle must fit between the bottom and the rim")
    cup = _revolve(np.concatenate([[[0.0, 0.0], [R, 0.0], [R, H]], _rim(R, w, H, 8),
                                   [[R - w, H], [R - w, b], [0.0, b]]]), sections)
    torus = _torus_xz(handle_radius, handle_thickness / 2, (R, 0.0, H / 2), 48, 16)
    cavity = trimesh.creation.cylinder(radius=R - w / 2, height=H, sections=int(sections))
    cavity.apply_translation([0.0, 0.0, b + H / 2])
    handle = to_manifold(torus) - to_manifold(cavity)
    mesh = from_manifold(manifold3d.Manifold.batch_boolean([to_manifold(cup), handle], manifold3d.OpType.Add))
    return _centre(mesh)


def flat_tool_mesh(length: float = 0.20, thickness: float = 0.015, handle_width: float = 0.025,
                   head_length: float = 0.08, head_width: float = 0.045, corner_radius: float = 0.01,
                   segments: int = 16) -> trimesh.Trimesh:
    """A flat tool (a spatula-like plate): a handle with a round end and a wider head with rounded far
    corners, extruded to `thickness`, lying in the x-y plane with its length along x.

    Outline area of the smooth shape: w_h·(L − L_head − w_h/2) + π·w_h²/8 + L_head·w_head − (2 − π/2)·r_c²;
    volume = area × thickness.

    Args:
        length: overall length, m.
        thickness: plate thickness (z), m.
        handle_width: width of the handle, m.
        head_length: length of the head, m.
        head_width: width of the head, m.
        corner_radius: radius of the head's two far corners, m.
        segments: segments of each quarter circle of the outline.

    Returns:
        Watertight mesh, metres, genus 0, centred at its centre of mass.
    """
    import manifold3d

    from regrasp_casadi.mesh_repair import from_manifold

    L, wh, lh, wb, rc = map(float, (length, handle_width, head_length, head_width, corner_radius))
    x0 = L - lh  # where the head starts
    outline = np.concatenate([
        _arc((wh / 2, 0.0), wh / 2, np.pi / 2, 3 * np.pi / 2, 2 * segments),  # round end of the handle
        [[x0, -wh / 2], [x0, -wb / 2]],
        _arc((L - rc, -wb / 2 + rc), rc, -np.pi / 2, 0.0, segments),
        _arc((L - rc, wb / 2 - rc), rc, 0.0, np.pi / 2, segments),
        [[x0, wb / 2], [x0, wh / 2]],
    ])
    solid = manifold3d.Manifold.extrude(manifold3d.CrossSection([outline]), float(thickness))
    return _centre(from_manifold(solid))


def holed_box_mesh(extents=(0.05, 0.07, 0.09), hole_radius: float = 0.002, sections: int = 12
                   ) -> trimesh.Trimesh:
    """A box with three small straight tunnels through it, one along each axis, that do not meet (the
    thin tunnels of a scanned object; genus 3). The tunnels are prisms of `sections` sides whose
    vertices lie on a circle of `hole_radius`: along z at (x, y) = (e_x/4, e_y/4), along x at
    (y, z) = (−e_y/4, e_z/4), along y at (x, z) = (−e_x/4, −e_z/4).

    Volume: e_x·e_y·e_z − A·(e_x + e_y + e_z), A = (n/2)·r²·sin(2π/n) the tunnels' cross-section.

    Args:
        extents: (3,) full side lengths of the box, m.
        hole_radius: radius of the tunnels, m.
        sections: sides of each tunnel.

    Returns:
        Watertight mesh, metres, genus 3, centred at its centre of mass.
    """
    import manifold3d

    from regrasp_casadi.mesh_repair import from_manifold, to_manifold

    ex, ey, ez = (float(e) for e in extents)
    tunnels = []
    placements = ((2, (ex / 4, ey / 4, 0.0)), (0, (0.0, -ey / 4, ez / 4)), (1, (-ex / 4, 0.0, -ez / 4)))
    for axis, offset in placements:
        c = trimesh.creation.cylinder(radius=float(hole_radius), height=2 * max(ex, ey, ez),
                                      sections=int(sections))
        if axis != 2:
            c.apply_transform(trimesh.geometry.align_vectors([0.0, 0.0, 1.0], np.eye(3)[axis]))
        tunnels.append(to_manifold(c.apply_translation(offset)))
    box = to_manifold(trimesh.creation.box(extents=(ex, ey, ez)))
    solid = box - manifold3d.Manifold.batch_boolean(tunnels, manifold3d.OpType.Add)
    return _centre(from_manifold(solid))
