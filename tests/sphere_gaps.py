"""Two fingers' collision-sphere gap placed by yourdfpy's forward kinematics: an independent reference
for the planner's self-collision claims (tests of `make_way` and `reposture`) and its clearance claims."""

from __future__ import annotations

import functools

import numpy as np
import yourdfpy


@functools.lru_cache(maxsize=4)
def _urdf(path: str) -> yourdfpy.URDF:
    """The hand's URDF, loaded once per path (its configuration is set before every use)."""
    return yourdfpy.URDF.load(path, load_meshes=False, build_collision_scene_graph=False)


def finger_spheres(hand, q, finger: str, tip: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A finger's collision spheres at q (n,) rad (without its tip sphere when `tip` is False): centres
    (k, 3), palm frame, m, placed by yourdfpy's forward kinematics of the hand's URDF, and radii (k,), m."""
    ref = _urdf(str(hand.urdf_path))
    ref.update_cfg(np.asarray(q, float))
    chosen = [s for s in hand.spheres if s.finger == finger and (tip or not s.is_tip)]
    T = [ref.get_transform(s.link, ref.base_link) for s in chosen]
    centres = np.array([t[:3, :3] @ s.center_link + t[:3, 3] for t, s in zip(T, chosen, strict=True)])
    return centres, np.array([s.radius for s in chosen])


def finger_gap(hand, q, finger_a: str, finger_b: str) -> float:
    """The least surface distance of two fingers' collision spheres at q (n,) rad, m (< 0: overlap), their
    centres placed by yourdfpy's forward kinematics of the hand's URDF."""
    (a, ra), (b, rb) = finger_spheres(hand, q, finger_a), finger_spheres(hand, q, finger_b)
    return float(np.min(np.linalg.norm(a[:, None] - b[None], axis=2) - ra[:, None] - rb[None]))
