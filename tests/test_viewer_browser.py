"""The one real-browser test: the static HTML replay drawn by headless Chromium (SwiftShader WebGL).

A screenshot of the replay must show the fingers in their colours (hand.yaml's, `hand_visuals.hand_colors`),
the object (`OBJECT_COLOR`, a light sand) and the contact markers — not a blank page, an error page or an
empty canvas. The plan's contacts are the fingertip centres, inside the tip spheres: the current-contact
dots and desired-contact rings are seen only because they are drawn over the scene. Pixels under the HTML
overlay's panels (whose legend repeats the colours) are not counted.
"""

from __future__ import annotations

import colorsys

import numpy as np
import pytest
from test_viewer import make_plan

from regrasp_casadi.screenshot import find_chromium, screenshot


def _color_mask(rgb: np.ndarray, color: int, tol_deg: float = 14.0, sat: tuple[float, float] = (0.35, 1.0),
                min_value: float = 0.15) -> np.ndarray:
    """Pixels whose hue is within `tol_deg` of `color`'s, with a saturation in `sat` and a value above
    `min_value` (shading changes brightness, not hue)."""
    ref = [(color >> s & 0xFF) / 255.0 for s in (16, 8, 0)]
    h_ref = colorsys.rgb_to_hsv(*ref)[0] * 360.0
    x = rgb.astype(float) / 255.0
    mx, mn = x.max(axis=-1), x.min(axis=-1)
    d = np.where(mx - mn > 1e-9, mx - mn, 1.0)
    r, g, b = x[..., 0], x[..., 1], x[..., 2]
    h = np.where(mx == r, (g - b) / d % 6.0, np.where(mx == g, (b - r) / d + 2.0, (r - g) / d + 4.0)) * 60.0
    s = (mx - mn) / np.where(mx > 0, mx, 1.0)
    dh = np.abs((h - h_ref + 180.0) % 360.0 - 180.0)
    return (dh < tol_deg) & (s > sat[0]) & (s <= sat[1]) & (mx > min_value)


def _scene_only(shape: tuple[int, int]) -> np.ndarray:
    """False under the overlay's panels at 800 × 600 px (replay_overlay's CSS, with margins): the step box
    top left, the legend bottom left, the hint bottom right."""
    h, w = shape
    keep = np.ones((h, w), dtype=bool)
    keep[:100, :340] = False
    keep[h - 200:, :200] = False
    keep[h - 60:, w - 520:] = False
    return keep


@pytest.mark.browser
def test_html_replay_draws_hand_object_and_markers(hand, tmp_path):
    if find_chromium() is None:
        pytest.skip("chromium not installed (.ci/run installs Debian's chromium)")
    from PIL import Image

    from regrasp_casadi import viewer
    from regrasp_casadi.hand_visuals import hand_colors
    from regrasp_casadi.objects import ObjectModel

    plan = make_plan(hand)
    html = viewer.write_html(plan, tmp_path / "replay.html", hand=hand,
                             obj=ObjectModel.box((0.05, 0.06, 0.12)))
    png = screenshot(html, tmp_path / "shot.png", width=800, height=600)
    rgb = np.asarray(Image.open(png).convert("RGB"))
    assert rgb.shape[:2] == (600, 800)
    assert rgb.reshape(-1, 3).std(axis=0).max() > 20.0, "uniform screenshot: nothing drawn"
    keep = _scene_only(rgb.shape[:2])
    n = int(keep.sum())

    def share(color, **kw) -> float:
        return float((_color_mask(rgb, color, **kw) & keep).sum()) / n

    colors = hand_colors(hand)
    for finger in ("index", "middle", "ring"):
        assert share(colors[finger]) > 0.01, f"{finger}: colour {colors[finger]:06x} on too few pixels"
    assert share(colors["thumb"]) > 0.002
    assert share(viewer.OBJECT_COLOR, sat=(0.12, 0.6), min_value=0.5) > 0.02
    # the markers (inside the fingertips) are seen: orange dots, blue rings, each a few hundred pixels
    assert share(viewer.CONTACT_COLOR, tol_deg=8.0, sat=(0.8, 1.0)) > 0.0005
    assert share(viewer.GOAL_COLOR, tol_deg=8.0, sat=(0.8, 1.0)) > 0.0005
