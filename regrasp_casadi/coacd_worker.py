"""coacd in a child process: a time cap that can stop it, and a progress bar while it runs.

coacd's C++ call cannot be interrupted from Python, so `run_coacd` runs it in a fresh interpreter
(``python -m regrasp_casadi.coacd_worker IN.npz OUT.npz``; not a user command) and kills it when the
time cap is reached. A fresh interpreter (not `fork`) keeps the parent's threads and OpenMP state out of
the child and does not re-import the caller's main script. coacd is deterministic for a given seed, so
the child returns the same pieces as a call in the parent would.

While it runs, a tqdm bar on stderr shows the elapsed time against the cap (disabled when stderr is not
a terminal).

    >>> parts = run_coacd(mesh.vertices, mesh.faces, {"threshold": 0.05}, max_seconds=300)  # or None
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["CoacdError", "run_coacd"]

_POLL_S = 0.25


class CoacdError(RuntimeError):
    """coacd failed in the child process (the message ends with its last stderr lines)."""


def run_coacd(vertices: ArrayLike, faces: ArrayLike, kwargs: dict, max_seconds: float,
              desc: str = "coacd") -> list[NDArray[np.float64]] | None:
    """coacd's convex pieces of a mesh, or None if it did not finish within `max_seconds`.

    Args:
        vertices: (v, 3) mesh vertices, m.
        faces: (f, 3) triangle vertex indices.
        kwargs: keyword arguments of `coacd.run_coacd` (threshold, max_convex_hull, seed, ...).
        max_seconds: wall-clock cap, s; the child is killed when it is reached.
        desc: label of the progress bar.

    Returns:
        The pieces' vertex arrays (v_i, 3), m; None on timeout.

    Raises:
        CoacdError: the child exited without a result.
    """
    from tqdm import tqdm

    with tempfile.TemporaryDirectory(prefix="regrasp_coacd_") as tmp:
        src, dst = pathlib.Path(tmp) / "in.npz", pathlib.Path(tmp) / "out.npz"
        np.savez(src, vertices=np.asarray(vertices, float), faces=np.asarray(faces, np.int64),
                 kwargs=json.dumps(kwargs))
        env = dict(os.environ)
        package_root = str(pathlib.Path(__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
        err_path = pathlib.Path(tmp) / "stderr.txt"
        with open(err_path, "wb") as err:
            proc = subprocess.Popen([sys.executable, "-m", "regrasp_casadi.coacd_worker", str(src), str(dst)],
                                    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err, env=env)
            t0 = time.monotonic()
            bar = tqdm(total=max(1, round(max_seconds)), desc=desc, unit="s", file=sys.stderr, leave=False,
                       disable=not sys.stderr.isatty(),
                       bar_format="{desc}: {elapsed} of at most {total} s |{bar}|")
            try:
                while proc.poll() is None:
                    elapsed = time.monotonic() - t0
                    if elapsed > max_seconds:
                        proc.kill()
                        proc.wait()
                        return None
                    bar.n = min(int(elapsed), bar.total)
                    bar.refresh()
                    time.sleep(_POLL_S)
            finally:
                bar.close()
                if proc.poll() is None:  # interrupted (Ctrl-C): do not leave coacd running
                    proc.kill()
                    proc.wait()
        if proc.returncode != 0 or not dst.is_file():
            tail = err_path.read_text(errors="replace").strip().splitlines()[-5:]
            raise CoacdError(f"coacd exited with code {proc.returncode}: " + " | ".join(tail))
        with np.load(dst) as data:
            return [np.array(data[f"piece{i}"], dtype=float) for i in range(int(data["n"]))]


def main(argv: list[str] | None = None) -> int:
    """Child entry point: read IN.npz (vertices, faces, kwargs), write OUT.npz (n, piece0, piece1, ...)."""
    import coacd

    src, dst = (argv if argv is not None else sys.argv[1:])[:2]
    with np.load(src) as data:
        vertices, faces = np.array(data["vertices"]), np.array(data["faces"])
        kwargs = json.loads(str(data["kwargs"]))
    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(vertices, faces), **kwargs)
    pieces = [np.asarray(v, float) for v, _ in parts]
    tmp = f"{dst}.tmp.npz"
    np.savez(tmp, n=len(pieces), **{f"piece{i}": v for i, v in enumerate(pieces)})
    os.replace(tmp, dst)
    return 0


if __name__ == "__main__":
    sys.exit(main())
