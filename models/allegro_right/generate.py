"""Generate ``allegro_right.urdf`` (the project's own Allegro hand v4 model) from public joint data.

Kinematics: the joint table of the Allegro hand v4 (origins, axes, limits; see README.md, "Provenance").
Collision: the sphere cover in ``sphere_cover.json`` (fitted by ``fit_spheres.py``) plus the fingertip contact
sphere (radius 14 mm at (0, 0, 0.002) in each tip link, collision name ``tip_contact``).
Visual: boxes, cylinders and spheres only.

    python models/allegro_right/generate.py      # rewrites allegro_right.urdf beside this file
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
TIP_RADIUS = 0.014
TIP_CENTER_Z = 0.002

# joint name, parent, child, origin xyz, origin rpy, axis, lower, upper   (metres, radians)
FINGER_BASES = {  # finger -> (first joint index, base origin xyz, base origin rpy)
    "index": (0, "0 0.0435 -0.001542", "-0.08726646255 0 0"),
    "middle": (4, "0 0 0.0007", "0 0 0"),
    "ring": (8, "0 -0.0435 -0.001542", "0.08726646255 0 0"),
}
FINGER_CHAIN = [  # (origin xyz in parent, axis, lower, upper) for joints 1..3 of each finger
    ("0 0 0.0164", "0 1 0", -0.196, 1.61),
    ("0 0 0.054", "0 1 0", -0.174, 1.709),
    ("0 0 0.0384", "0 1 0", -0.227, 1.618),
]
FINGER_J0 = ("0 0 1", -0.47, 0.47)
THUMB = [  # (origin xyz, origin rpy, axis, lower, upper) for joints 12..15
    ("-0.0182 0.019333 -0.045987", "0 -1.65806278845 -1.5707963259", "-1 0 0", 0.263, 1.396),
    ("-0.027 0.005 0.0399", "0 0 0", "0 0 1", -0.105, 1.163),
    ("0 0 0.0177", "0 0 0", "0 1 0", -0.189, 1.644),
    ("0 0 0.0514", "0 0 0", "0 1 0", -0.162, 1.719),
]
FINGER_TIP_Z = 0.0267  # tip link origin on the distal link's z axis (vendor: 0.0387 - 0.012)
THUMB_TIP_Z = 0.0423  # (vendor: 0.0543 - 0.012)

# link -> sphere-cover body of sphere_cover.json
BODY = {
    "palm_link": "palm",
    "link_12.0": "thumb_base",
    "link_13.0": "thumb_proximal",
    "link_14.0": "thumb_middle",
    "link_15.0": "thumb_distal",
}
for _i in (0, 4, 8):
    BODY.update(
        {
            f"link_{_i}.0": "proximal_base",
            f"link_{_i + 1}.0": "proximal",
            f"link_{_i + 2}.0": "middle",
            f"link_{_i + 3}.0": "distal",
        }
    )

# link -> visual primitives [(kind, size string, origin xyz)]; finger links: 19.6 x 27 mm cross-section
_W, _D = 0.0196, 0.0270


def _box_z(z0: float, z1: float) -> tuple[str, str, str]:
    return ("box", f"{_W} {_D} {z1 - z0:.4f}", f"0 0 {(z0 + z1) / 2:.5f}")


VISUAL = {
    "palm_link": [("box", "0.0408 0.1134 0.0967", "-0.0091 0 -0.04665")],
    "link_12.0": [("box", "0.0447 0.034 0.0495", "-0.01685 -0.009 -0.01675")],
    "link_13.0": [_box_z(0.0, 0.0177)],
    "link_14.0": [_box_z(0.0, 0.0514)],
    "link_15.0": [_box_z(0.0, 0.0303)],
}
for _i in (0, 4, 8):
    VISUAL.update(
        {
            f"link_{_i}.0": [_box_z(0.0, 0.0164)],
            f"link_{_i + 1}.0": [_box_z(0.0, 0.054)],
            f"link_{_i + 2}.0": [_box_z(0.0, 0.0384)],
            f"link_{_i + 3}.0": [_box_z(0.0, 0.0147)],
        }
    )
TIP_VISUAL = [
    ("cylinder", f"{TIP_RADIUS} 0.014", "0 0 -0.005"),
    ("sphere", f"{TIP_RADIUS}", f"0 0 {TIP_CENTER_Z}"),
]


def _link(name: str, spheres: list[dict], visuals, tip: bool) -> str:
    color = "white" if tip else ("black" if name == "palm_link" else "grey")
    lines = [f'  <link name="{name}">']
    for kind, size, xyz in visuals:
        if kind == "cylinder":
            radius, length = size.split()
            geom = f'<cylinder radius="{radius}" length="{length}"/>'
        else:
            geom = f'<box size="{size}"/>' if kind == "box" else f'<sphere radius="{size}"/>'
        lines += [
            "    <visual>",
            f'      <origin xyz="{xyz}" rpy="0 0 0"/>',
            f"      <geometry>{geom}</geometry>",
            f'      <material name="{color}"/>',
            "    </visual>",
        ]
    if tip:
        lines += [
            '    <collision name="tip_contact">',
            f'      <origin xyz="0 0 {TIP_CENTER_Z}" rpy="0 0 0"/>',
            f'      <geometry><sphere radius="{TIP_RADIUS}"/></geometry>',
            "    </collision>",
        ]
    for k, s in enumerate(spheres):
        xyz = " ".join(f"{c:.4f}" for c in s["center"])
        lines += [
            f'    <collision name="{name}#{k}">',
            f'      <origin xyz="{xyz}" rpy="0 0 0"/>',
            f'      <geometry><sphere radius="{s["radius"]:.4f}"/></geometry>',
            "    </collision>",
        ]
    lines.append("  </link>")
    return "\n".join(lines)


def _joint(name, jtype, parent, child, xyz, rpy, limit=None) -> str:
    """A <joint>; `limit` (axis, lower, upper) for a revolute one."""
    lines = [
        f'  <joint name="{name}" type="{jtype}">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{child}"/>',
        f'    <origin xyz="{xyz}" rpy="{rpy}"/>',
    ]
    if limit is not None:
        axis, lower, upper = limit
        lines += [
            f'    <axis xyz="{axis}"/>',
            f'    <limit lower="{lower}" upper="{upper}" effort="15" velocity="7"/>',
        ]
    lines.append("  </joint>")
    return "\n".join(lines)


def build_urdf(cover: dict) -> str:
    bodies = cover["bodies"]
    parts = [
        '<?xml version="1.0"?>',
        "<!-- Allegro hand v4, right. GENERATED by models/allegro_right/generate.py; do not edit. -->",
        "<!-- Joint data: public Allegro v4 kinematics (see README.md). Geometry: the project's own. -->",
        '<robot name="allegro_right">',
        '  <material name="black"><color rgba="0.2 0.2 0.2 1"/></material>',
        '  <material name="grey"><color rgba="0.35 0.35 0.35 1"/></material>',
        '  <material name="white"><color rgba="0.9 0.9 0.9 1"/></material>',
    ]

    def add_link(name: str, tip: bool = False) -> None:
        spheres = [] if tip else bodies[BODY[name]]
        parts.append(_link(name, spheres, TIP_VISUAL if tip else VISUAL[name], tip))

    add_link("palm_link")
    for finger, (j0, xyz0, rpy0) in FINGER_BASES.items():
        parts.append(f"  <!-- {finger} finger -->")
        parent = "palm_link"
        for k in range(4):
            i = j0 + k
            child = f"link_{i}.0"
            add_link(child)
            if k == 0:
                parts.append(_joint(f"joint_{i}.0", "revolute", parent, child, xyz0, rpy0, FINGER_J0))
            else:
                xyz, axis, lo, hi = FINGER_CHAIN[k - 1]
                parts.append(_joint(f"joint_{i}.0", "revolute", parent, child, xyz, "0 0 0", (axis, lo, hi)))
            parent = child
        add_link(f"{parent}_tip", tip=True)
        parts.append(
            _joint(
                f"{parent.replace('link', 'joint')}_tip",
                "fixed",
                parent,
                f"{parent}_tip",
                f"0 0 {FINGER_TIP_Z}",
                "0 0 0",
            )
        )
    parts.append("  <!-- thumb -->")
    parent = "palm_link"
    for k, (xyz, rpy, axis, lo, hi) in enumerate(THUMB):
        child = f"link_{12 + k}.0"
        add_link(child)
        parts.append(_joint(f"joint_{12 + k}.0", "revolute", parent, child, xyz, rpy, (axis, lo, hi)))
        parent = child
    add_link("link_15.0_tip", tip=True)
    parts.append(_joint("joint_15.0_tip", "fixed", parent, "link_15.0_tip", f"0 0 {THUMB_TIP_Z}", "0 0 0"))
    parts.append("</robot>\n")
    return "\n".join(parts)


def main() -> None:
    cover = json.loads((HERE / "sphere_cover.json").read_text())
    (HERE / "allegro_right.urdf").write_text(build_urdf(cover))


if __name__ == "__main__":
    main()
