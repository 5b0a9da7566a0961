"""Exact self-collision of a hand's link meshes, independent of the planner's sphere model (python-fcl).

A URDF whose links carry mesh geometry (collision meshes, else visual meshes; for the Allegro the vendor
URDF in ``../shared/reference/allegro_right``, whose link and joint names are the shipped model's) is
posed with its own forward kinematics (yourdfpy) at a joint vector of the hand, and the meshes of links
on different fingers are tested for intersection with python-fcl (triangle-exact BVH test). The depth
of an intersection is the deepest vertex of either mesh inside the other (exact distance to the other
mesh's surface, trimesh; the vendor meshes are watertight); 0 when only edges cross.

python-fcl is optional (``pip install "regrasp-casadi[fcl]"``): `available` says whether it is there.

    >>> meshes, note = LinkMeshes.from_urdf("allegro_hand_right.urdf", hand)   # None, why: no check
    >>> meshes.intersections(q)   # [(link_a, link_b, depth_m), ...], links of different fingers
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    import trimesh

    from regrasp_casadi.hand import Hand

__all__ = ["LinkMeshes", "available", "finger_links", "has_link_meshes"]


def available() -> bool:
    """True when python-fcl can be imported."""
    try:
        import fcl  # noqa: F401
    except ImportError:
        return False
    return True


def finger_links(hand: Hand) -> dict[str, str]:
    """link -> finger, for every link on exactly one finger's path from the palm to its tip that a joint
    of that finger moves (the palm and shared links are left out)."""
    paths: dict[str, list[str]] = {}
    for f, tip in hand.tip_links.items():
        link = tip
        while link is not None and link != hand.root_link:
            paths.setdefault(link, []).append(f)
            link = hand.parent_link(link)
    return {link: fs[0] for link, fs in paths.items() if len(fs) == 1}


def _link_geometry(urdf_robot, base: Path) -> dict[str, list[tuple[str, NDArray, NDArray | None]]]:
    """link -> [(mesh file, T_link_mesh (4, 4), scale (3,) or None)]: collision meshes, else visual."""
    out = {}
    for link in urdf_robot.links:
        for items in (link.collisions, link.visuals):
            meshes = [(base / g.geometry.mesh.filename,
                       np.eye(4) if g.origin is None else np.asarray(g.origin), g.geometry.mesh.scale)
                      for g in items if g.geometry is not None and g.geometry.mesh is not None]
            if meshes:
                out[link.name] = meshes
                break
    return out


def has_link_meshes(urdf_path: str | Path) -> bool:
    """True when some link of the URDF has mesh geometry (collision or visual)."""
    import yourdfpy

    path = Path(urdf_path)
    robot = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False).robot
    return bool(_link_geometry(robot, path.parent))


@dataclass
class _Body:
    mesh: trimesh.Trimesh
    """The link's meshes in the link frame, m."""
    center: NDArray[np.float64]
    """(3,) centre of its bounding sphere, link frame."""
    radius: float
    """Bounding-sphere radius, m."""
    obj: object
    """Its fcl.CollisionObject (pose set per query)."""


class LinkMeshes:
    """The link meshes of one URDF as fcl objects, and the link pairs of different fingers to test."""

    def __init__(self, urdf_path: str | Path, hand: Hand):
        """Read `urdf_path` (its link meshes, its kinematics) for `hand` (whose joint names and fingers
        name the URDF's joints and links).

        Raises:
            ImportError: python-fcl is missing.
            ValueError: the URDF lacks a joint of the hand, or has no link meshes.
        """
        import fcl
        import trimesh
        import yourdfpy

        self.urdf_path = Path(urdf_path).resolve()
        """The URDF whose meshes are checked."""
        self._urdf = yourdfpy.URDF.load(str(self.urdf_path), build_scene_graph=True, load_meshes=False,
                                        build_collision_scene_graph=False, load_collision_meshes=False)
        missing = [j for j in hand.joint_names if j not in self._urdf.actuated_joint_names]
        if missing:
            raise ValueError(f"{self.urdf_path}: no joint {missing[0]!r} of the hand")
        self._joint_names = tuple(hand.joint_names)
        geometry = _link_geometry(self._urdf.robot, self.urdf_path.parent)
        if not geometry:
            raise ValueError(f"{self.urdf_path}: no link has mesh geometry")
        self.bodies: dict[str, _Body] = {}
        for link, items in geometry.items():
            parts = []
            for filename, T_link_mesh, scale in items:
                m = trimesh.load(filename, force="mesh")
                if scale is not None:
                    m.apply_scale(np.broadcast_to(np.asarray(scale, float), 3)[0])
                parts.append(m.apply_transform(T_link_mesh))
            mesh = trimesh.util.concatenate(parts) if len(parts) > 1 else parts[0]
            center = 0.5 * (mesh.bounds[0] + mesh.bounds[1])
            model = fcl.BVHModel()
            model.beginModel(len(mesh.vertices), len(mesh.faces))
            model.addSubModel(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32))
            model.endModel()
            radius = float(np.max(np.linalg.norm(mesh.vertices - center, axis=1)))
            self.bodies[link] = _Body(mesh, center, radius, fcl.CollisionObject(model, fcl.Transform()))
        fingers = finger_links(hand)
        self.finger_of = {link: fingers[link] for link in self.bodies if link in fingers}
        """link -> finger, for the links with meshes that a finger moves."""
        self.pairs: tuple[tuple[str, str], ...] = tuple(
            (a, b) for a, b in itertools.combinations(self.finger_of, 2)
            if self.finger_of[a] != self.finger_of[b])
        """The link pairs tested: links with meshes on different fingers."""

    @classmethod
    def from_urdf(cls, urdf_path: str | Path, hand: Hand) -> tuple[LinkMeshes | None, str]:
        """(the link meshes of `urdf_path`, a note saying what is checked) or (None, why not: no
        python-fcl, or no link meshes in the URDF)."""
        urdf_path = Path(urdf_path)
        if not available():
            return None, "skipped: python-fcl is not installed (pip install regrasp-casadi[fcl])"
        if not has_link_meshes(urdf_path):
            return None, f"skipped: {urdf_path.name} has no link meshes (verify(..., link_meshes=URDF))"
        return cls(urdf_path, hand), f"link meshes of {urdf_path} (python-fcl)"

    def poses(self, q: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """link -> (4, 4) T_base_link by the URDF's own forward kinematics at the hand's joints `q` (n,)."""
        self._urdf.update_cfg(dict(zip(self._joint_names, np.asarray(q, float).tolist(), strict=True)))
        base = self._urdf.base_link
        return {link: np.asarray(self._urdf.get_transform(link, base)) for link in self.bodies}

    def intersections(self, q: ArrayLike) -> list[tuple[str, str, float]]:
        """Intersecting link-mesh pairs of different fingers at `q`: (link_a, link_b, depth m), depth =
        the deepest vertex of either mesh inside the other (0 when only edges cross)."""
        import fcl

        T = self.poses(q)
        centers = {ln: T[ln][:3, :3] @ b.center + T[ln][:3, 3] for ln, b in self.bodies.items()}
        out = []
        for a, b in self.pairs:
            A, B = self.bodies[a], self.bodies[b]
            if np.linalg.norm(centers[a] - centers[b]) > A.radius + B.radius:
                continue
            for ln, body in ((a, A), (b, B)):
                body.obj.setTransform(fcl.Transform(T[ln][:3, :3], T[ln][:3, 3]))
            if fcl.collide(A.obj, B.obj, fcl.CollisionRequest(), fcl.CollisionResult()):
                depth = max(_depth(A.mesh, T[a], B.mesh, T[b]), _depth(B.mesh, T[b], A.mesh, T[a]))
                out.append((a, b, depth))
        return out


def _depth(mesh_in: trimesh.Trimesh, T_in: NDArray, mesh_of: trimesh.Trimesh, T_of: NDArray) -> float:
    """Deepest vertex of `mesh_in` (posed by T_in) inside `mesh_of` (posed by T_of), m (0: none inside)."""
    import trimesh

    T_rel = np.linalg.inv(T_of) @ T_in
    v = trimesh.transform_points(mesh_in.vertices, T_rel)
    near = np.all((v >= mesh_of.bounds[0]) & (v <= mesh_of.bounds[1]), axis=1)
    if not near.any():
        return 0.0
    sd = trimesh.proximity.signed_distance(mesh_of, v[near])  # > 0 inside (trimesh's sign)
    return float(max(0.0, np.max(sd)))
