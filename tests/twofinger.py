"""A tiny two-finger test hand (URDF written to a temporary folder) and a box held between its tips.

Geometry (palm frame, metres): two fingers stand on the palm at x = ∓0.04, z = 0.02. Each finger has
a revolute base joint about y (`<f>_base`), a prismatic joint along its own z (`<f>_slide`, 0…0.03) and a
roll joint about the tip axis (`<f>_roll`) that moves no sphere centre. At q = 0 the tip contact sphere
(radius 0.01) is centred at (∓0.04, 0, 0.11). `BOX` (0.06 × 0.04 × 0.04) centred at (0, 0, 0.11)
therefore touches both tips exactly on its ±x faces, and every other sphere is at least 2.8 cm away.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

BOX_EXTENTS = (0.06, 0.04, 0.04)
BOX_CENTER = np.array([0.0, 0.0, 0.11])
TIP_RADIUS = 0.01


def _finger(name: str, x: float) -> str:
    return f"""
  <joint name="{name}_base" type="revolute">
    <parent link="palm"/><child link="{name}_1"/>
    <origin xyz="{x} 0 0.02" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-0.5" upper="0.5" effort="1" velocity="1"/>
  </joint>
  <link name="{name}_1">
    <collision><origin xyz="0 0 0.03"/><geometry><sphere radius="0.012"/></geometry></collision>
  </link>
  <joint name="{name}_slide" type="prismatic">
    <parent link="{name}_1"/><child link="{name}_2"/>
    <origin xyz="0 0 0.06"/><axis xyz="0 0 1"/>
    <limit lower="-0.03" upper="0.03" effort="1" velocity="1"/>
  </joint>
  <link name="{name}_2"/>
  <joint name="{name}_roll" type="revolute">
    <parent link="{name}_2"/><child link="{name}_tip"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1.0" upper="1.0" effort="1" velocity="1"/>
  </joint>
  <link name="{name}_tip">
    <collision name="tip_contact"><origin xyz="0 0 0.03"/><geometry><sphere radius="{TIP_RADIUS}"/></geometry>
    </collision>
  </link>"""


URDF = f"""<?xml version="1.0"?>
<robot name="twofinger">
  <link name="palm">
    <collision><origin xyz="0 0 0"/><geometry><sphere radius="0.02"/></geometry></collision>
  </link>{_finger("left", -0.04)}{_finger("right", 0.04)}
</robot>
"""


def make_hand(folder: Path):
    """Write the URDF into `folder` and build the Hand (fingers "left", "right")."""
    from regrasp_casadi.hand import Hand

    path = Path(folder) / "twofinger.urdf"
    path.write_text(URDF)
    return Hand.from_urdf(path, fingers={"left": "left_tip", "right": "right_tip"})


def make_box():
    from regrasp_casadi.objects import ObjectModel

    return ObjectModel.box(BOX_EXTENTS)


def box_pose(dx: float = 0.0, dy: float = 0.0, dz: float = 0.0) -> np.ndarray:
    """T_palm_object of the box: centred at BOX_CENTER + (dx, dy, dz), axes aligned with the palm."""
    T = np.eye(4)
    T[:3, 3] = BOX_CENTER + [dx, dy, dz]
    return T
