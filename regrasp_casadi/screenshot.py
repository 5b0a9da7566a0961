"""Screenshots of HTML replays with headless Chromium (Debian's `chromium`), for docs and the browser test.

    >>> screenshot("replay.html", "replay.png")          # the scene after `seconds` of replay
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
    """Render `html` in headless Chromium and write a `width` × `height` PNG after `seconds` of
    (virtual) time, so that a replay has played that long.

    Args:
        html: the HTML file.
        png: the image to write (parent folders are created).
        width, height: image size, pixels.
        seconds: replay time of the image, s (>= 0; 0 is the first frame).
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
        # a budget of 0 ms never fires (Chromium waits for the page forever): 1 ms is the first frame
        budget_ms = max(1, round(seconds * 1000))
        cmd = [chromium, *_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
               f"--virtual-time-budget={budget_ms}", f"--screenshot={png}", html.as_uri()]
        try:
            proc = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise RegraspError(f"chromium wrote no screenshot of {html} within {timeout:g} s") from None
    if not png.exists():
        raise RegraspError(f"chromium wrote no screenshot of {html}: {proc.stderr.strip()[-500:]}")
    return png
