"""Generated object meshes at YCB sizes: box, cylinder, sphere, capsule, bottle, banana, and the shapes
that are hard to grasp: a thin-walled bowl and cup, a mug with a handle, a flat tool and a box with
small through-holes (a scan-like artefact of genus 3).

Every function returns a watertight `trimesh.Trimesh` in metres, winding outward (volume > 0), centred
at (or near) its centre of mass, so that examples and tests need no mesh files. `ObjectModel`'s
classmethods of the same names wrap them (see `regrasp_casadi.objects`). Closed forms of their volumes
(of the smooth shapes the meshes approximate) are in the docstrings; the Boolean shapes (mug, holed box,
tool outline) are built with manifold3d.

The thin-walled shapes also come with their convex pieces by construction (`bowl_pieces`, `cup_pieces`,
`mug_pieces`: vertex arrays in the mesh's frame whose hulls cover the mesh and reach into its cavity only
by chords within a tolerance), which `ObjectModel.bowl` / `cup` / `mug` use instead of coacd.

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
    "bowl_pieces",
    "cup_pieces",
    "mug_pieces",
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
    return _centre(_revolve(_bowl_profile(radius, wall, segments, rim_segments), sections))


def _bowl_profile(radius: float, wall: float, segments: int, rim_segments: int) -> np.ndarray:
    """`bowl_mesh`'s closed (r, z) profile: the outer quarter circle from the pole up (segments + 1
    points), the rim (rim_segments − 1), the inner quarter circle from the rim down (segments + 1)."""
    R, w = float(radius), float(wall)
    profile = np.concatenate([_arc((0.0, 0.0), R, -np.pi / 2, 0.0, segments), _rim(R, w, 0.0, rim_segments),
                              _arc((0.0, 0.0), R - w, 0.0, -np.pi / 2, segments)])
    profile[[0, -1], 0] = 0.0  # exactly on the axis
    return profile


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
    return _centre(_revolve(_cup_profile(radius, height, wall, bottom, rim_segments), sections))


def _cup_profile(radius: float, height: float, wall: float, bottom: float, rim_segments: int) -> np.ndarray:
    """`cup_mesh`'s closed (r, z) profile: (0, 0), (R, 0), (R, H), the rim (rim_segments − 1 points),
    (R − w, H), (R − w, b), (0, b)."""
    R, H, w, b = float(radius), float(height), float(wall), float(bottom)
    return np.concatenate([[[0.0, 0.0], [R, 0.0], [R, H]], _rim(R, w, H, rim_segments),
                           [[R - w, H], [R - w, b], [0.0, b]]])


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
    return _centre(_mug_solid(radius, height, wall, bottom, handle_radius, handle_thickness, sections))


def _mug_solid(radius: float, height: float, wall: float, bottom: float, handle_radius: float,
               handle_thickness: float, sections: int) -> trimesh.Trimesh:
    """`mug_mesh` before centring (the cup's axis is the z axis, its bottom at z = 0)."""
    import manifold3d

    from regrasp_casadi.mesh_repair import from_manifold, to_manifold

    R, H, w, b = float(radius), float(height), float(wall), float(bottom)
    if handle_radius + handle_thickness / 2 >= H / 2 - b:
        raise ValueError(f"handle_radius={handle_radius}: the handle must fit between the bottom and the rim")
    cup = _revolve(_cup_profile(R, H, w, b, 8), sections)
    torus = _torus_xz(handle_radius, handle_thickness / 2, (R, 0.0, H / 2), 48, 16)
    cavity = trimesh.creation.cylinder(radius=R - w / 2, height=H, sections=int(sections))
    cavity.apply_translation([0.0, 0.0, b + H / 2])
    handle = to_manifold(torus) - to_manifold(cavity)
    return from_manifold(manifold3d.Manifold.batch_boolean([to_manifold(cup), handle], manifold3d.OpType.Add))


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


# ---------------------------------------------------------------------------- convex pieces of thin walls
# A thin wall's convex pieces, by construction: coacd's pieces of a 4 mm wall over-cover it by 3.8–7.6 mm
# (benchmarks/geometry.py). A solid of revolution is cut along its profile into bands (polygons of
# consecutive profile points) and around the axis into sectors; each piece is the hull of a band's points
# at the mesh's section angles of one sector, so its vertices are mesh vertices and the union of the
# pieces is the mesh up to the chords the hulls draw across the concave (cavity) side of a piece.
def _sectors(r_max: float, sections: int, tolerance: float) -> int:
    """The fewest sectors K (a divisor of `sections`, by doubling) whose chord at radius `r_max` (m) dips
    r_max·(1 − cos(π/K)) ≤ `tolerance` (m) below the circle."""
    k = 1 if r_max <= tolerance else 2
    while k < sections and (r_max * (1.0 - np.cos(np.pi / k)) > tolerance or sections % k):
        k *= 2
    return min(k, int(sections))


def _revolved_pieces(profile: np.ndarray, bands: list[np.ndarray], sections: int,
                     tolerance: float) -> list[np.ndarray]:
    """Convex pieces (vertex arrays (v, 3), m) of the solid of revolution of `profile` (n, 2) (r, z) over
    `sections` sections: each band (profile point indices, or (k, 2) points on the surface) revolved
    over the sectors of `_sectors` (one piece, the band's full revolution, if the band touches the axis)."""
    angles = 2.0 * np.pi * np.arange(int(sections) + 1) / int(sections)
    out = []
    for band in bands:
        pts = profile[band] if np.asarray(band).dtype.kind in "iu" else np.asarray(band, float)
        on_axis = bool(np.any(pts[:, 0] <= 1e-12))
        k = 1 if on_axis else _sectors(float(np.max(pts[:, 0])), sections, tolerance)
        step = int(sections) // k
        for s in range(k):
            a = angles[s * step:(s + 1) * step + 1]
            ring = np.stack([np.outer(np.cos(a), pts[:, 0]), np.outer(np.sin(a), pts[:, 0]),
                             np.broadcast_to(pts[:, 1], (len(a), len(pts)))], axis=-1)
            out.append(ring.reshape(-1, 3))
    return out


def _polar_bands(segments: int, rim_segments: int, depth: float, step: float, tolerance: float
                 ) -> list[np.ndarray]:
    """`_bowl_profile`'s bands: a polar cap of g₀ segments, depth·(1 − cos g₀δ) ≤ tolerance, then bands
    of g segments, depth·(1 − cos(gδ/2)) ≤ tolerance (δ = `step` rad per segment, `depth` the inner
    radius, m), the last with the rim; each band holds the outer and inner points of its polar range."""
    n = int(segments)
    g0 = max(1, int(np.floor(np.arccos(1.0 - min(tolerance / depth, 1.0)) / step)))
    g = max(1, int(np.floor(2.0 * np.arccos(1.0 - min(tolerance / depth, 1.0)) / step)))
    edges = [0, min(g0, n)]
    while edges[-1] < n:
        edges.append(min(edges[-1] + g, n))
    inner0 = n + int(rim_segments)  # index of the inner circle's first point (at the rim)
    bands = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        outer = np.arange(a, b + 1)
        inner = inner0 + np.arange(n - b, n - a + 1)
        rim = np.arange(n + 1, inner0) if b == n else np.arange(0)
        bands.append(np.concatenate([outer, rim, inner]))
    return bands


def bowl_pieces(radius: float = 0.06, wall: float = 0.004, segments: int = 24, rim_segments: int = 8,
                sections: int = 64, tolerance: float = 1.5e-3) -> list[np.ndarray]:
    """Convex pieces of `bowl_mesh` (same arguments): a polar cap and bands of the wall, each band split
    into sectors, so that no hull reaches more than about `tolerance` (m) into the bowl.

    Returns:
        Vertex arrays (v_i, 3), m, in `bowl_mesh`'s frame (vertices of the mesh).
    """
    profile = _bowl_profile(radius, wall, segments, rim_segments)
    bands = _polar_bands(segments, rim_segments, float(radius) - float(wall), np.pi / 2 / int(segments),
                         tolerance)
    shift = _revolve(profile, sections).center_mass
    return [v - shift for v in _revolved_pieces(profile, bands, sections, tolerance)]


def _cup_bands(radius: float, height: float, wall: float, bottom: float, rim_segments: int
               ) -> list[np.ndarray]:
    """`_cup_profile`'s bands: the bottom disc (r ≤ R, z ≤ b) and the wall with its rim (R − w ≤ r ≤ R)."""
    R, b = float(radius), float(bottom)
    n = 3 + int(rim_segments) - 1  # points up to (R − w, H)
    profile = _cup_profile(radius, height, wall, bottom, rim_segments)
    disc = np.array([[0.0, 0.0], [R, 0.0], [R, b], [0.0, b]])
    wall_band = np.concatenate([profile[1:n + 2], [[R - float(wall), 0.0]]])
    return [disc, wall_band]


def cup_pieces(radius: float = 0.04, height: float = 0.095, wall: float = 0.004, bottom: float = 0.004,
               rim_segments: int = 8, sections: int = 64, tolerance: float = 1.5e-3) -> list[np.ndarray]:
    """Convex pieces of `cup_mesh` (same arguments): the bottom disc and the wall (with its rim) split
    into sectors whose hulls reach at most `tolerance` (m) into the cup.

    Returns:
        Vertex arrays (v_i, 3), m, in `cup_mesh`'s frame (points of the mesh's surface or inside it).
    """
    profile = _cup_profile(radius, height, wall, bottom, rim_segments)
    bands = _cup_bands(radius, height, wall, bottom, rim_segments)
    shift = _revolve(profile, sections).center_mass
    return [v - shift for v in _revolved_pieces(profile, bands, sections, tolerance)]


def _handle_pieces(radius: float, height: float, wall: float, handle_radius: float, handle_thickness: float,
                   tolerance: float) -> list[np.ndarray]:
    """Convex pieces of `_mug_solid`'s handle: the hulls of arcs of the torus's tube whose chords stay
    within `tolerance` (m) of its inner side, cut at the plane x = R − w (inside the cup's wall); arcs
    wholly inside the cup are dropped. Vertex arrays (v, 3), m, `_mug_solid`'s frame."""
    R, H, w = float(radius), float(height), float(wall)
    a, rho = float(handle_radius), 0.5 * float(handle_thickness)
    n_major = 48
    torus = _torus_xz(a, rho, (R, 0.0, H / 2), n_major, 16)
    v = np.asarray(torus.vertices)
    u = np.mod(np.arctan2(v[:, 2] - H / 2, v[:, 0] - R), 2 * np.pi)
    section = np.round(u / (2 * np.pi / n_major)).astype(int) % n_major
    step = 1
    while step < n_major // 4 and (a - rho) * (1 - np.cos((step + 1) * np.pi / n_major)) <= tolerance:
        step += 1
    out = []
    for s0 in range(0, n_major, step):
        arc = np.isin(section, np.arange(s0, s0 + step + 1) % n_major)
        hull = trimesh.convex.convex_hull(v[arc])
        if float(np.max(hull.vertices[:, 0])) <= R - w + 1e-9:
            continue
        cut = trimesh.intersections.slice_mesh_plane(hull, [1.0, 0.0, 0.0], [R - w, 0.0, 0.0], cap=True)
        if cut is not None and len(cut.vertices) >= 4:
            out.append(np.asarray(cut.vertices))
    return out


def mug_pieces(radius: float = 0.04, height: float = 0.095, wall: float = 0.004, bottom: float = 0.004,
               handle_radius: float = 0.028, handle_thickness: float = 0.01, sections: int = 64, *,
               tolerance: float = 1.5e-3) -> list[np.ndarray]:
    """Convex pieces of `mug_mesh` (same arguments): `cup_pieces` and the handle's (`_handle_pieces`),
    the pieces of the union's two operands.

    Returns:
        Vertex arrays (v_i, 3), m, in `mug_mesh`'s frame.
    """
    profile = _cup_profile(radius, height, wall, bottom, 8)
    pieces = _revolved_pieces(profile, _cup_bands(radius, height, wall, bottom, 8), sections, tolerance)
    pieces += _handle_pieces(radius, height, wall, handle_radius, handle_thickness, tolerance)
    shift = _mug_solid(radius, height, wall, bottom, handle_radius, handle_thickness, sections).center_mass
    return [p - shift for p in pieces]
