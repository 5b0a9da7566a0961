"""The package's data: the shipped hand models and the built-in regrasp problems.

The repository keeps them in its top-level ``models/`` and ``problems/`` folders; ``pyproject.toml`` maps
these folders to the subpackages ``regrasp_casadi.models`` and ``regrasp_casadi.problems``, so that both a
normal install (``pip install .``, a wheel) and an editable one (``pip install -e .``) carry them and
`importlib.resources` finds them wherever the package is installed.

    >>> package_data_dir("models") / "allegro_right" / "hand.yaml"
    >>> builtin_problem("box_rotate")          # .../problems/box_rotate.yaml
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path
from typing import Literal

__all__ = ["package_data_dir", "builtin_problem", "builtin_problems"]


def package_data_dir(kind: Literal["models", "problems"]) -> Path:
    """The folder of the package data `kind` (``regrasp_casadi.<kind>``), as a file-system path.

    Found with `importlib.resources`. The one fallback is an uninstalled source checkout put on the path
    by hand (``PYTHONPATH=checkout``, where the subpackage cannot be imported because the folder is not
    inside ``regrasp_casadi/``): then the checkout's top-level folder of that name.
    """
    if kind not in ("models", "problems"):
        raise ValueError(f"unknown package data {kind!r} (known: models, problems)")
    try:
        root = importlib.resources.files(f"{__package__}.{kind}")
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[1] / kind
    if not isinstance(root, Path):  # e.g. a zipped install: the URDF and meshes must be real files
        raise RuntimeError(f"{__package__}.{kind} is not a folder on disk ({root!r}); install the package "
                           "unzipped")
    return root


def builtin_problems() -> list[Path]:
    """Every built-in problem file (``problems/*.yaml``), sorted by name."""
    return sorted(package_data_dir("problems").glob("*.yaml"))


def builtin_problem(name: str) -> Path:
    """The built-in problem file ``problems/<name>.yaml`` (it may not exist: check ``.is_file()``)."""
    return package_data_dir("problems") / f"{name}.yaml"
