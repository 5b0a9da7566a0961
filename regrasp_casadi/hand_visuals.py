"""The hand as the replay draws it: coloured visual shapes per link (numpy, trimesh, yourdfpy; no meshcat).

`hand_visuals(hand)` reads the hand's URDF and returns the shapes of every link, in the link's frame:

* a link with visual **meshes** (a vendor URDF, e.g. the Allegro's STL files) is drawn with those meshes,
  loaded with trimesh, scaled as the URDF says and shaded smoothly except along sharp edges;
* primitive visuals read as the robot: a **box** becomes a rounded box (edge radius `ROUND_FRACTION` of its
  smallest half-size, the look of the Allegro's links), cylinders and spheres stay as they are;
* a link without visuals (or whose meshes are missing) gets a **capsule** from its origin to each child
  joint, as thick as its collision spheres, or its collision spheres when it has no child.

Colours come from the hand's metadata file (``viewer.colors`` in hand.yaml, see `hand_model`): one per
finger (default `DEFAULT_FINGER_COLORS` in finger order) and one for the palm and every link fixed to it
(default `DEFAULT_PALM_COLOR`, a neutral grey); a finger's tip link is drawn in a light tint of its
finger's colour (the Allegro's rubber tips). Poses come from the project's FK (`hand.fk(q)`), not here.

    >>> shapes = hand_visuals(Hand.allegro_right())    # 16 rounded boxes, tip cylinders and spheres
    >>> colors = hand_colors(hand)                     # {"palm": 0x8d939c, "index": 0xd1495b, ...}
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.hand_model import PALM

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

    from regrasp_casadi.hand import Hand

__all__ = ["DEFAULT_FINGER_COLORS", "DEFAULT_PALM_COLOR", "LinkVisual", "hand_colors", "hand_visuals",
           "link_fingers", "rounded_box", "tint"]

logger = logging.getLogger(__name__)

DEFAULT_PALM_COLOR = 0x8D939C
"""Palm and links fixed to it: a neutral blue-grey."""
DEFAULT_FINGER_COLORS = (0xD1495B, 0x66A61E, 0x7570B3, 0x1B9E9E, 0xB07AA1, 0x9C755F)
"""Fingers without a colour in hand.yaml, in finger order (cycled): red, green, violet, teal, mauve, brown —
none near the contact markers' orange and blue (`viewer.CONTACT_COLOR`, `viewer.GOAL_COLOR`)."""
TIP_TINT = 0.55
"""A tip link's colour: its finger's colour mixed this much with white."""
ROUND_FRACTION = 0.7
"""Edge radius of a rounded box, as a fraction of its smallest half-size."""
_FALLBACK_RADIUS = 0.008   # m: capsule radius of a link without collision spheres


@dataclass(frozen=True)
class LinkVisual:
    """One coloured shape of a link, in the link's frame."""

    link: str
    """The link the shape is fixed to."""
    finger: str | None
    """The finger whose joints move the link (None: the palm or a link fixed to it)."""
    kind: str
    """"mesh" (params vertices (v, 3) m, faces (f, 3) int), "sphere" (radius, m) or "cylinder" (radius,
    length, m, along the shape's z axis)."""
    T_link_visual: NDArray[np.float64]
    """(4, 4) pose of the shape in the link frame (m)."""
    params: dict[str, Any]
    color: int
    """0xRRGGBB."""
    source: str
    """Where the shape comes from: "urdf-mesh", "urdf-primitive" or "generated"."""


def tint(color: int, amount: float) -> int:
    """`color` (0xRRGGBB) mixed with white: amount 0 -> the colour, 1 -> white."""
    rgb = np.array([(color >> s) & 0xFF for s in (16, 8, 0)], dtype=float)
    r, g, b = np.round(rgb + amount * (255.0 - rgb)).astype(int)
    return int(r) << 16 | int(g) << 8 | int(b)


def hand_colors(hand: Hand) -> dict[str, int]:
    """Colour 0xRRGGBB of the palm (key `hand_model.PALM`, "palm") and of every finger: hand.yaml's
    ``viewer.colors``, else the defaults (`DEFAULT_PALM_COLOR`, `DEFAULT_FINGER_COLORS` in finger order)."""
    named = {k: int(v[1:], 16) for k, v in hand.metadata.colors.items()}
    colors = {PALM: named.get(PALM, DEFAULT_PALM_COLOR)}
    for k, finger in enumerate(hand.fingers):
        colors[finger] = named.get(finger, DEFAULT_FINGER_COLORS[k % len(DEFAULT_FINGER_COLORS)])
    return colors


def link_fingers(robot, tip_links: dict[str, str]) -> dict[str, str | None]:
    """The finger of every link of a yourdfpy ``Robot``: the one finger whose root -> tip path holds the link
    or its nearest ancestor on such a path; None for links fixed to the root or shared by fingers (palm)."""
    parent = {j.child: (j.parent, j.type) for j in robot.joints}
    paths: dict[str, set[str]] = {}
    for finger, tip in tip_links.items():
        ln, path = tip, {tip}
        while ln in parent:
            ln = parent[ln][0]
            path.add(ln)
        paths[finger] = path

    def finger_of(link: str) -> str | None:
        ln, moved = link, False
        while ln in parent and not moved:
            moved = parent[ln][1] != "fixed"
            ln = parent[ln][0]
        ln = link
        while moved:
            owners = [f for f, path in paths.items() if ln in path]
            if len(owners) == 1:
                return owners[0]
            if owners or ln not in parent:
                return None
            ln = parent[ln][0]
        return None

    return {link.name: finger_of(link.name) for link in robot.links}


def rounded_box(size, radius: float) -> trimesh.Trimesh:
    """A box of `size` (3,) m, centred at the origin, whose edges and corners are rounded with `radius` m
    (the convex hull of 8 spheres; `radius` is capped at the smallest half-size)."""
    import trimesh

    half = 0.5 * np.asarray(size, dtype=float)
    radius = float(min(radius, half.min()))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=radius).vertices
    inner = np.maximum(half - radius, 0.0)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * inner
    return trimesh.convex.convex_hull(np.concatenate([ball + c for c in corners]))


def _capsule(p0: NDArray, p1: NDArray, radius: float) -> trimesh.Trimesh:
    """A capsule of `radius` m around the segment p0 -> p1 (3,), m."""
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=2, radius=radius).vertices
    return trimesh.convex.convex_hull(np.concatenate([ball + p0, ball + p1]))


def _mesh_params(mesh: trimesh.Trimesh) -> dict[str, NDArray]:
    """Vertices and faces split along sharp edges, so that the viewer's vertex normals shade curved
    surfaces smoothly and keep edges crisp."""
    shaded = mesh.smooth_shaded
    return {"vertices": np.asarray(shaded.vertices, dtype=float), "faces": np.asarray(shaded.faces)}


def _mesh_file(urdf_dir: Path, filename: str) -> Path:
    """A URDF mesh file name (relative, absolute, ``file://`` or ``package://<pkg>/...``) as a path: a
    ``package://`` name is looked up beside the URDF, with and without its package folder."""
    for prefix in ("file://", "package://"):
        if filename.startswith(prefix):
            rest = filename[len(prefix):]
            if prefix == "package://":
                pkg_rel = Path(*Path(rest).parts[1:]) if len(Path(rest).parts) > 1 else Path(rest)
                for cand in (urdf_dir / rest, urdf_dir / pkg_rel, urdf_dir.parent / pkg_rel):
                    if cand.exists():
                        return cand
            filename = rest
    path = Path(filename)
    return path if path.is_absolute() else urdf_dir / path


def _urdf_shapes(link, urdf_dir: Path) -> list[tuple[str, NDArray, dict, str]]:
    """(kind, T_link_visual, params, source) of a yourdfpy link's visuals (missing meshes skipped)."""
    import trimesh

    out = []
    for el in link.visuals:
        g = el.geometry
        T = np.eye(4) if el.origin is None else np.asarray(el.origin, dtype=float)
        if g.box is not None:
            size = np.asarray(g.box.size, dtype=float)
            mesh = rounded_box(size, ROUND_FRACTION * 0.5 * float(size.min()))
            out.append(("mesh", T, _mesh_params(mesh), "urdf-primitive"))
        elif g.cylinder is not None:
            out.append(("cylinder", T, {"radius": float(g.cylinder.radius),
                                        "length": float(g.cylinder.length)}, "urdf-primitive"))
        elif g.sphere is not None:
            out.append(("sphere", T, {"radius": float(g.sphere.radius)}, "urdf-primitive"))
        elif g.mesh is not None:
            path = _mesh_file(urdf_dir, g.mesh.filename)
            if not path.is_file():
                logger.warning("visual mesh %s of link %s not found; skipped", path, link.name)
                continue
            mesh = trimesh.load(str(path), force="mesh")
            if g.mesh.scale is not None:
                mesh.apply_scale(np.broadcast_to(np.asarray(g.mesh.scale, dtype=float), (3,)))
            out.append(("mesh", T, _mesh_params(mesh), "urdf-mesh"))
    return out


def _generated_shapes(link, child_origins: list[NDArray]) -> list[tuple[str, NDArray, dict, str]]:
    """Capsules from the link origin to each child joint origin (3,), as thick as the link's collision
    spheres; a leaf link gets its collision spheres (or nothing)."""
    spheres = [(np.eye(4) if c.origin is None else np.asarray(c.origin, float),
                float(c.geometry.sphere.radius))
               for c in link.collisions if c.geometry is not None and c.geometry.sphere is not None]
    radius = float(np.mean([r for _, r in spheres])) if spheres else _FALLBACK_RADIUS
    out = []
    for p in child_origins:
        if np.linalg.norm(p) > 1e-6:
            out.append(("mesh", np.eye(4), _mesh_params(_capsule(np.zeros(3), p, radius)), "generated"))
    if not out:
        out = [("sphere", T, {"radius": r}, "generated") for T, r in spheres]
    return out


def hand_visuals(hand: Hand) -> list[LinkVisual]:
    """The coloured shapes of every link of `hand` (see the module docstring), in URDF link order."""
    import yourdfpy

    urdf_path = Path(hand.urdf_path)
    robot = yourdfpy.URDF.load(str(urdf_path), build_scene_graph=False, load_meshes=False,
                               load_collision_meshes=False).robot
    fingers = link_fingers(robot, hand.tip_links)
    colors = hand_colors(hand)
    tips = set(hand.tip_links.values())
    child_origins: dict[str, list[NDArray]] = {link.name: [] for link in robot.links}
    for j in robot.joints:
        child_origins[j.parent].append(np.eye(4)[:3, 3] if j.origin is None else np.asarray(j.origin)[:3, 3])
    shapes: list[LinkVisual] = []
    for link in robot.links:
        items = _urdf_shapes(link, urdf_path.parent) or _generated_shapes(link, child_origins[link.name])
        finger = fingers[link.name]
        color = colors[PALM] if finger is None else colors[finger]
        if link.name in tips:
            color = tint(color, TIP_TINT)
        shapes.extend(LinkVisual(link.name, finger, kind, T, params, color, source)
                      for kind, T, params, source in items)
    return shapes
