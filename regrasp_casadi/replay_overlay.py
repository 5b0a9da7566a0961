"""The HTML overlay of the static replay: the step being played, a progress bar and the legend (pure strings).

The overlay is plain HTML/CSS over the Meshcat canvas, with a small script that reads the replay time
from Meshcat's animator (`viewer.animator.time`, s) on every frame and shows the label of the step being
moved into (the label of step i from time t_{i-1} on, as the 3D scene's labels of the live viewer do).
Nothing is loaded from elsewhere: the file plays offline.

Opened with ``#t=S`` after its address (``replay.html#t=2.5``), the page holds the replay at S seconds
instead of playing it (pressing play in the controls lets it run): screenshots of a given instant
(`regrasp_casadi.screenshot`) do not depend on how long the page took to load.

    >>> rows = [LegendEntry("dot", 0xE69F00, "current contact")]
    >>> html = overlay_html("box · method svd · converged", labels, times, rows)
"""

from __future__ import annotations

import html as _html
import json
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["LegendEntry", "overlay_html"]


@dataclass(frozen=True)
class LegendEntry:
    """One row of the legend: a swatch and what it means."""

    swatch: str
    """"dot" (a filled, outlined disc), "ring" (an outlined ring) or "block" (a rounded square)."""
    color: int
    """0xRRGGBB."""
    text: str


def _css_color(color: int) -> str:
    return f"#{color & 0xFFFFFF:06x}"


def _swatch(entry: LegendEntry) -> str:
    c = _css_color(entry.color)
    if entry.swatch == "dot":
        style = f"background:{c};border:2px solid #1a1a1a;border-radius:50%;width:8px;height:8px"
    elif entry.swatch == "ring":
        style = (f"background:#fff;border:2px solid #1a1a1a;box-shadow:inset 0 0 0 3px {c};"
                 "border-radius:50%;width:12px;height:12px")
    else:
        style = f"background:{c};border-radius:3px;width:14px;height:14px"
    return f'<span class="rg-sw" style="{style}"></span>'


_CSS = """
#rg-hud { position: fixed; inset: 0; pointer-events: none; font: 14px/1.35 system-ui, -apple-system,
  "Segoe UI", "DejaVu Sans", Helvetica, Arial, sans-serif; color: #1f2328; }
#rg-hud .rg-panel { position: absolute; background: rgba(255,255,255,0.86); border: 1px solid #d8dde3;
  border-radius: 8px; padding: 8px 12px; box-shadow: 0 1px 4px rgba(0,0,0,0.08); }
#rg-step-box { left: 14px; top: 14px; min-width: 250px; }
#rg-step { font-size: 19px; font-weight: 600; white-space: nowrap; }
#rg-title { font-size: 12px; color: #57606a; margin-top: 2px; }
#rg-bar { height: 4px; background: #e6e9ed; border-radius: 2px; margin-top: 7px; overflow: hidden; }
#rg-fill { height: 100%; width: 0; background: #57606a; }
#rg-legend { left: 14px; bottom: 14px; font-size: 13px; }
#rg-legend div { display: flex; align-items: center; gap: 8px; margin: 2px 0; white-space: nowrap; }
#rg-legend .rg-sw { display: inline-block; flex: none; box-sizing: content-box; }
#rg-legend .rg-slot { width: 16px; display: flex; justify-content: center; }
#rg-hint { right: 14px; bottom: 14px; font-size: 12px; color: #57606a; }
@media (max-width: 720px), (max-height: 480px) {
  #rg-hud { font-size: 11px; } #rg-step { font-size: 14px; } #rg-step-box { min-width: 0; }
  #rg-legend { font-size: 10px; } #rg-hint { display: none; }
}
"""

_JS = """
(function () {
  var hud = JSON.parse(document.getElementById("rg-data").textContent);
  var label = document.getElementById("rg-step"), fill = document.getElementById("rg-fill");
  var m = /[#&]t=([0-9.eE+-]+)/.exec(location.hash), hold = m ? parseFloat(m[1]) : null, shown = -1;
  function tick() {
    var a = viewer.animator;
    if (hold !== null && a && a.duration > 0) {
      if (a.playing && a.holding) { hold = null; }   // the user pressed play: let it run
      else {                    // #t=S: hold the replay at S s (re-applied while late commands arrive)
        if (a.playing) { a.pause(); }
        a.holding = true;
        a.seek(Math.min(hold, a.duration));
        a.display_progress(Math.min(hold, a.duration));
      }
    }
    var t = (a && a.time) || 0, i = 0;
    while (i + 1 < hud.times.length && hud.times[i] < t - 1e-6) { i++; }
    if (i !== shown) { label.textContent = hud.labels[i]; shown = i; }
    fill.style.width = (hud.duration > 0 ? Math.min(100, 100 * t / hud.duration) : 100) + "%";
    requestAnimationFrame(tick);
  }
  tick();
})();
"""


def overlay_html(title: str, labels: Sequence[str], step_times: Sequence[float],
                 legend: Sequence[LegendEntry], hint: str = "") -> str:
    """The overlay's HTML (a ``<style>``, the panels and a ``<script>``), to go before ``</body>``.

    Args:
        title: one line under the step label (e.g. the object, method and status).
        labels: the text of each step, e.g. "gait 3/26: index finger".
        step_times: replay time of each step, s (increasing; the label of step i shows from
            `step_times[i-1]` on, i.e. while the replay moves into step i).
        legend: the legend rows, top to bottom.
        hint: how to use the viewer, bottom right (empty: no hint).
    """
    if len(labels) != len(step_times) or not labels:
        raise ValueError(f"labels and step_times: expected the same non-zero length, got {len(labels)} "
                         f"and {len(step_times)}")
    data = {"labels": list(labels), "times": [float(t) for t in step_times],
            "duration": float(step_times[-1])}
    # JSON inside <script type="application/json">: only "</" could end the element early
    data_json = json.dumps(data).replace("</", "<\\/")
    rows = "".join(f'<div><span class="rg-slot">{_swatch(e)}</span>{_html.escape(e.text)}</div>'
                   for e in legend)
    hint_html = f'<div id="rg-hint" class="rg-panel">{_html.escape(hint)}</div>' if hint else ""
    return (f"<style>{_CSS}</style>\n"
            '<div id="rg-hud">'
            f'<div id="rg-step-box" class="rg-panel"><div id="rg-step">{_html.escape(labels[-1])}</div>'
            f'<div id="rg-title">{_html.escape(title)}</div>'
            '<div id="rg-bar"><div id="rg-fill"></div></div></div>'
            f'<div id="rg-legend" class="rg-panel">{rows}</div>{hint_html}</div>\n'
            f'<script type="application/json" id="rg-data">{data_json}</script>\n'
            f"<script>{_JS}</script>\n")
