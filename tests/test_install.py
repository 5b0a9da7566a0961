"""A normal (non-editable) install works: build the wheel, install it into a fresh venv, run `regrasp demo`.

How the test avoids the editable install of the checkout (the usual development setup): the fresh venv
has no access to the development environment's site-packages except through a ``.pth`` file that lists
those folders. A ``.pth`` line only appends its folder to ``sys.path``; the ``.pth`` files inside that
folder are not processed, so the editable install's finder (``__editable__*.pth``) is never installed.
``PYTHONPATH`` is removed and the commands run from a temporary folder, so neither the checkout nor the
current directory is on the path: `regrasp_casadi` (and its models and problems) can only come from the
wheel, which the test asserts. The dependencies are the development environment's (``--no-deps``).
"""

from __future__ import annotations

import json
import os
import shutil
import site
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
_SOURCES = ("pyproject.toml", "README.md", "LICENSE", "regrasp_casadi", "models", "problems")


def _run(cmd: list, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}
    return subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, check=False)


def _build_wheel(tmp: Path) -> Path:
    """The wheel of a copy of the checkout (the checkout gets no build/ or egg-info, and no stale build
    folder can leak files into the wheel). Without build isolation first (the installed setuptools); if
    that fails (e.g. no `wheel` package for an old setuptools) with isolation, as `pip install .` does;
    skips when neither works (no network for the build requirements)."""
    src = tmp / "src"
    src.mkdir()
    for name in _SOURCES:
        p = REPO / name
        if p.is_dir():
            shutil.copytree(p, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copy2(p, src / name)
    out = tmp / "wheel"
    errors = []
    for isolation in (["--no-build-isolation"], []):
        r = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", *isolation, "-w", out, src], cwd=tmp)
        wheels = sorted(out.glob("regrasp_casadi-*.whl"))
        if r.returncode == 0 and wheels:
            return wheels[0]
        errors.append(r.stderr.strip().splitlines()[-3:])
    pytest.skip(f"cannot build the wheel: {errors}")


def _fresh_venv(tmp: Path, wheel: Path) -> Path:
    """A venv with only the wheel installed; the dependencies come through a .pth file (see module doc)."""
    venv = tmp / "venv"
    r = _run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=tmp)
    assert r.returncode == 0, r.stderr
    python = venv / "bin" / "python"
    r = _run([sys.executable, "-m", "pip", "--python", python, "install", "--no-deps", "--no-index", wheel],
             cwd=tmp)
    assert r.returncode == 0, r.stderr
    (site_dir,) = (venv / "lib").glob("python*/site-packages")
    deps = [p for p in site.getsitepackages() if Path(p).is_dir()]
    (site_dir / "_regrasp_test_deps.pth").write_text("".join(f"{p}\n" for p in deps))
    return venv


def test_wheel_installs_and_runs_the_demo(tmp_path):
    wheel = _build_wheel(tmp_path)
    venv = _fresh_venv(tmp_path, wheel)
    work = tmp_path / "work"
    work.mkdir()
    probe = (
        "import json, regrasp_casadi\n"
        "from regrasp_casadi.resources import package_data_dir, builtin_problem\n"
        "from regrasp_casadi.hand import Hand\n"
        "h = Hand.allegro_right()\n"
        "print(json.dumps({'package': regrasp_casadi.__file__, 'models': str(package_data_dir('models')),\n"
        "    'problem': str(builtin_problem('box_rotate')), 'urdf': str(h.urdf_path), 'spec': h.spec(),\n"
        "    'thumb': h.thumb, 'gait': list(h.gait_forward)}))\n"
    )
    r = _run([venv / "bin" / "python", "-c", probe], cwd=work)
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    for key in ("package", "models", "problem", "urdf"):
        assert Path(info[key]).resolve().is_relative_to(venv.resolve()), (key, info[key])
    assert Path(info["problem"]).is_file() and Path(info["urdf"]).is_file()
    assert info["spec"] == {"model": "allegro_right"} and info["thumb"] == "thumb"
    assert info["gait"] == ["index", "middle", "ring", "thumb"]

    r = _run([venv / "bin" / "regrasp", "demo", "--out-dir", "out", "--no-progress"], cwd=work)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "(box_rotate)" in r.stdout  # the shipped problem, not the in-memory fallback
    plan = json.loads((work / "out" / "plan.json").read_text())
    assert plan["hand_spec"] == {"model": "allegro_right"}
    r = _run([venv / "bin" / "regrasp", "verify", "out/plan.json"], cwd=work)
    assert r.returncode == 0, r.stdout + r.stderr
