"""Two fingers' collision-sphere gap placed by yourdfpy's forward kinematics: an independent reference
for the planner's self-collision claims (tests of `make_way` and `reposture`)."""

from __future__ import annotations

import numpy as np
import yourdfpy


def finger_gap(hand, q, finger_a: str, finger_b: str) -> float:
    """The least surface distance of two fingers' collision spheres at q (n,) rad, m (< 0: overlap), their
    centres placed by yourdfpy's forward kinematics of the hand's URDF."""
    ref = yourdfpy.URDF.load(str(hand.urdf_path), load_meshes=False, build_collision_scene_graph=False)
    ref.update_cfg(np.asarray(q, float))

    def spheres(finger):
        chosen = [s for s in hand.spheres if s.finger == finger]
        T = [ref.get_transform(s.link, ref.base_link) for s in chosen]
        centres = np.array([t[:3, :3] @ s.center_link + t[:3, 3] for t, s in zip(T, chosen, strict=True)])
        return centres, np.array([s.radius for s in chosen])

    (a, ra), (b, rb) = spheres(finger_a), spheres(finger_b)
    return float(np.min(np.linalg.norm(a[:, None] - b[None], axis=2) - ra[:, None] - rb[None]))
