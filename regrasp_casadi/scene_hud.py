"""The live viewer's heads-up display, drawn in the Meshcat scene: step labels and a legend on the camera.

The live viewer (`viewer.show`) is Meshcat's own page, so what the static replay shows in an HTML overlay
(`replay_overlay`) is drawn here in 3D, attached to the camera so that it stays in view: Meshcat `_text`
canvas textures on planes, and flat swatches, all without depth test (the scene never hides them). A text
plane is square (the viewer draws the text centred on a 256 px canvas and shrinks it to fit).
meshcat is imported lazily, inside the functions.

    >>> add_step_labels(vis[LABELS], labels, camera_distance, static_step=0)
    >>> animate_step_labels(anim, vis[LABELS], t_steps, fps)
    >>> add_legend(vis[LEGEND], legend_rows, camera_distance)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from regrasp_casadi.meshcat_html import mesh_in_order, text_and_plane_classes
from regrasp_casadi.replay_overlay import LegendEntry

__all__ = ["CAMERA_FOV_DEG", "LABELS", "LEGEND", "add_legend", "add_step_labels", "animate_step_labels"]

CAMERA_FOV_DEG = 75.0      # Meshcat's default perspective camera (vertical field of view)
LABELS = "/Cameras/default/rotated/<object>/labels"
LEGEND = "/Cameras/default/rotated/<object>/legend"
_HUD_ORDER = 30            # renderOrder: over the scene and its markers
_OUTLINE = 0x1A1A1A


def _hud_frame(camera_distance: float) -> tuple[float, float]:
    """(distance in front of the camera, half height of the view there), m: a quarter of the camera's
    distance from the scene centre, so that the scene never comes between."""
    dist = 0.25 * camera_distance
    return dist, dist * float(np.tan(np.radians(CAMERA_FOV_DEG) / 2.0))


def _text_plane(node, text: str, size: float, font_size: int, T_cam_plane: np.ndarray) -> None:
    import meshcat.geometry as g

    TextTexture, Plane = text_and_plane_classes()
    node.set_object(mesh_in_order(Plane(size, size), g.MeshBasicMaterial(
        map=TextTexture(text, font_size=font_size), transparent=True, depthTest=False, depthWrite=False),
        _HUD_ORDER))
    node.set_transform(T_cam_plane)


# advance widths of a sans-serif font (Helvetica / Arial metrics), em; other characters 0.56 em
_NARROW = dict.fromkeys("ijl'|", 0.23) | dict.fromkeys("ft :;.,/()[]I!", 0.28) | dict.fromkeys("r-", 0.33)
_WIDTHS = _NARROW | dict.fromkeys("cksvxyz", 0.5) | {"w": 0.72, "m": 0.83, "M": 0.83, "W": 0.94}


def _width_em(text: str) -> float:
    """The width of `text` in a sans-serif font, em (within about 10 %: to place centred canvas text)."""
    return sum(_WIDTHS.get(c, 0.56) for c in text)


def _font_size(texts: Sequence[str], largest: int = 40) -> int:
    """One font size (px of the 256 px canvas) that fits the widest text, with 5 % to spare."""
    return int(min(largest, 0.95 * 256 / max(_width_em(t) for t in texts)))


def _text_centre(x_left: float, y_mid: float, text: str, font_size: int, size: float) -> list[float]:
    """(x, y) of a text plane's centre (camera frame, m) whose text starts at `x_left` and is centred on
    `y_mid` (the viewer centres the text horizontally and puts its baseline on the canvas's middle)."""
    em = font_size / 256 * size
    return [x_left + 0.5 * _width_em(text) * em, y_mid - 0.35 * em]


def add_step_labels(labels_node, labels: Sequence[str], camera_distance: float, static_step: int) -> None:
    """One text plane per step at the top left of the view; only `static_step`'s is visible.

    `camera_distance` (m) is the camera's distance from the scene centre."""
    dist, half_h = _hud_frame(camera_distance)
    font_size = _font_size(labels, largest=48)
    size = 0.09 * half_h * 256 / font_size      # the text ~ 1/22 of the view's height
    for i, text in enumerate(labels):
        node = labels_node[f"step_{i}"]
        T_cam_label = np.eye(4)
        T_cam_label[:3, 3] = [*_text_centre(-1.17 * half_h, 0.88 * half_h, text, font_size, size), -dist]
        _text_plane(node, text, size, font_size, T_cam_label)
        node.set_property("visible", i == static_step)


def animate_step_labels(anim, labels_node, t_steps: Sequence[float], fps: float) -> None:
    """Boolean (discrete) visibility tracks: label i is on while the replay moves into step i (from time
    `t_steps[i-1]` to `t_steps[i]`, s; the last one stays on); label 0 only in the static scene (a
    one-step plan: always)."""
    import meshcat.animation as mca

    n_steps = len(t_steps)
    for i in range(n_steps):
        keys = {0.0: n_steps == 1}
        if i >= 1:
            keys[t_steps[i - 1]] = True
        if 1 <= i < n_steps - 1:
            keys[t_steps[i]] = False
        clip = anim.clips.setdefault(labels_node[f"step_{i}"].path, mca.AnimationClip(fps=fps))
        clip.tracks["visible"] = mca.AnimationTrack(
            "visible", "boolean", [t * fps for t in keys], list(keys.values()))


def add_legend(legend_node, rows: Sequence[LegendEntry], camera_distance: float) -> None:
    """The legend at the bottom left of the view: per row a swatch (an outlined disc, an outlined ring or
    a square in the row's colour) and its text (`legend_node/row_<k>/{text,swatch<j>}`)."""
    import meshcat.geometry as g

    if not rows:
        return
    _, Plane = text_and_plane_classes()
    dist, half_h = _hud_frame(camera_distance)
    row_h = 0.065 * half_h                      # a row: 1/31 of the view's height
    font_size = _font_size([r.text for r in rows], largest=48)
    size = 0.7 * row_h * 256 / font_size        # the text 0.7 row high
    x_swatch = -1.25 * half_h + 0.08 * half_h + 0.4 * row_h
    T_disc = np.eye(4)   # a flat disc facing the camera: three.js cylinders run along y, turned onto z
    T_disc[1:3, 1:3] = [[0.0, -1.0], [1.0, 0.0]]
    for k, row in enumerate(rows):
        node = legend_node[f"row_{k}"]
        y = -half_h + row_h * (len(rows) - k + 0.5)
        T = np.eye(4)
        T[:3, 3] = [*_text_centre(x_swatch + 0.8 * row_h, y, row.text, font_size, size), -dist]
        _text_plane(node["text"], row.text, size, font_size, T)
        r = 0.3 * row_h
        discs = {"dot": [(1.4 * r, _OUTLINE), (r, row.color)],
                 "ring": [(1.4 * r, _OUTLINE), (r, row.color), (0.6 * r, 0xFFFFFF)]}.get(row.swatch)
        T = T_disc.copy()
        T[:3, 3] = [x_swatch, y, -dist]
        for j, (radius, color) in enumerate(discs or [(None, row.color)]):
            geom = g.Cylinder(1e-4, radius) if radius is not None else Plane(2.2 * r, 2.2 * r)
            mat = g.MeshBasicMaterial(color=color, transparent=True, depthTest=False, depthWrite=False)
            node[f"swatch{j}"].set_object(mesh_in_order(geom, mat, _HUD_ORDER + 1 + j))
            node[f"swatch{j}"].set_transform(T if radius is not None else _translation(T[:3, 3]))


def _translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T
