"""Machine and software description recorded by every benchmark (CPU, cores, versions, git commit)."""

from __future__ import annotations

import datetime
import os
import pathlib
import platform
import subprocess
from importlib.metadata import PackageNotFoundError, version

REPO = pathlib.Path(__file__).resolve().parents[1]


def _cpu_model() -> str:
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, timeout=10,
                              check=False).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def machine_info(packages: tuple[str, ...] = ("casadi", "numpy", "trimesh", "coacd", "yourdfpy")) -> dict:
    """CPU model, core count, 1-minute load, Python and package versions, git commit and whether the
    work tree had uncommitted changes, and the date (UTC)."""
    versions = {}
    for name in packages:
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            versions[name] = None
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "cpu": _cpu_model(),
        "cores": os.cpu_count(),
        "load_1min": os.getloadavg()[0],
        "python": platform.python_version(),
        "platform": platform.platform(),
        "versions": versions,
        "git_commit": _git("rev-parse", "HEAD"),
        "git_dirty": bool(_git("status", "--porcelain", "--untracked-files=no")),
    }
