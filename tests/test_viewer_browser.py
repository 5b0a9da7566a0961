"""The one real-browser test: the static HTML replay drawn by headless Chromium (SwiftShader WebGL).

A screenshot of the replay must show the hand (HAND_COLOR, steel blue) and the object (OBJECT_COLOR,
amber) — not a blank page, an error page or an empty canvas.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_viewer import make_plan

from regrasp_casadi.screenshot import find_chromium, screenshot


def _hue_mask(rgb: np.ndarray, color: int, tol_deg: float = 14.0) -> np.ndarray:
    """Pixels whose hue is within `tol_deg` of `color`'s and that are clearly saturated (shading changes
    brightness, not hue)."""
    import colorsys

    ref = [(color >> s & 0xFF) / 255.0 for s in (16, 8, 0)]
    h_ref = colorsys.rgb_to_hsv(*ref)[0] * 360.0
    x = rgb.astype(float) / 255.0
    mx, mn = x.max(axis=-1), x.min(axis=-1)
    d = np.where(mx - mn > 1e-9, mx - mn, 1.0)
    r, g, b = x[..., 0], x[..., 1], x[..., 2]
    h = np.where(mx == r, (g - b) / d % 6.0, np.where(mx == g, (b - r) / d + 2.0, (r - g) / d + 4.0)) * 60.0
    sat = (mx - mn) / np.where(mx > 0, mx, 1.0)
    dh = np.abs((h - h_ref + 180.0) % 360.0 - 180.0)
    return (dh < tol_deg) & (sat > 0.35) & (mx > 0.15)


@pytest.mark.browser
def test_html_replay_draws_hand_and_object(hand, tmp_path):
    if find_chromium() is None:
        pytest.skip("chromium not installed (.ci/run installs Debian's chromium)")
    from PIL import Image

    from regrasp_casadi import viewer
    from regrasp_casadi.objects import ObjectModel

    plan = make_plan(hand)
    html = viewer.write_html(plan, tmp_path / "replay.html", hand=hand,
                             obj=ObjectModel.box((0.05, 0.06, 0.12)))
    png = screenshot(html, tmp_path / "shot.png", width=800, height=600)
    rgb = np.asarray(Image.open(png).convert("RGB"))
    assert rgb.shape[:2] == (600, 800)
    assert rgb.reshape(-1, 3).std(axis=0).max() > 20.0, "uniform screenshot: nothing drawn"
    n = rgb.shape[0] * rgb.shape[1]
    hand_px = int(_hue_mask(rgb, viewer.HAND_COLOR).sum())
    obj_px = int(_hue_mask(rgb, viewer.OBJECT_COLOR).sum())
    assert hand_px > 0.02 * n, f"hand colour on {hand_px} of {n} pixels"
    assert obj_px > 0.02 * n, f"object colour on {obj_px} of {n} pixels"
