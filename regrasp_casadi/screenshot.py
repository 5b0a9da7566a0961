"""Screenshots of HTML replays with headless Chromium (Debian's `chromium`), for docs and the browser test.

    >>> screenshot("replay.html", "replay.png", seconds=2.5)   # the replay held at 2.5 s
"""

from __future__ import annotations

import math
import shutil
import subprocess
import tempfile
from pathlib import Path

from regrasp_casadi.errors import RegraspError

__all__ = ["find_chromium", "screenshot"]

# Flags that draw Meshcat's WebGL in headless Chromium on a machine without a GPU or network
# (SwiftShader; see DESIGN.md "Viewer notes").
LOAD_MS = 3000
"""Virtual time (ms) given to the page to load before the replay time: a replay is opened at
``#t=<seconds>`` and holds that instant (`replay_overlay`), so the picture does not depend on the load."""
_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
          "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run")


def find_chromium() -> str | None:
    """Path of a Chromium executable, or None."""
    for candidate in ("/usr/bin/chromium", shutil.which("chromium"), shutil.which("chromium-browser")):
        if candidate and Path(candidate).exists():
            return candidate
    return None


def screenshot(html: str | Path, png: str | Path, *, width: int = 800, height: int = 600,
               seconds: float = 8.0, chromium: str | None = None, timeout: float = 120.0) -> Path:
    """Render `html` in headless Chromium and write a `width` × `height` PNG of the replay at `seconds`.

    The page is opened at ``#t=<seconds>``, where a replay (`viewer.write_html`) holds that instant, and
    given `seconds` + `LOAD_MS` of virtual time (a page that ignores ``#t`` is pictured then).

    Args:
        html: the HTML file.
        png: the image to write (parent folders are created).
        width, height: image size, pixels.
        seconds: replay time of the image, s (>= 0; 0 is the first frame; past the end: the end).
        chromium: Chromium executable (default: `find_chromium()`).
        timeout: seconds to wait for Chromium.

    Raises:
        ValueError: `seconds` negative or not finite.
        RegraspError: when Chromium is not installed, writes no image (its last output is quoted) or
            does not finish within `timeout`.
    """
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds >= 0):
        raise ValueError(f"seconds: expected a non-negative number, got {seconds!r}")
    chromium = chromium or find_chromium()
    if chromium is None:
        raise RegraspError("chromium not found (Debian: apt-get install chromium)")
    html, png = Path(html).resolve(), Path(png).resolve()
    png.parent.mkdir(parents=True, exist_ok=True)
    png.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="regrasp-chromium-") as profile:
        budget_ms = round(seconds * 1000) + LOAD_MS
        cmd = [chromium, *_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
               f"--virtual-time-budget={budget_ms}", f"--screenshot={png}", f"{html.as_uri()}#t={seconds:g}"]
        try:
            proc = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise RegraspError(f"chromium wrote no screenshot of {html} within {timeout:g} s") from None
    if not png.exists():
        raise RegraspError(f"chromium wrote no screenshot of {html}: {proc.stderr.strip()[-500:]}")
    return png
