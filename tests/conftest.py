"""Shared pytest fixtures: the session-wide Allegro hand and the reference-data folder."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ["REGRASP_COMPILE"] = "0"  # NLPs interpreted (no compiler runs) unless a test asks otherwise

REFERENCE_DIR = Path(__file__).resolve().parents[2] / "shared" / "reference"


@pytest.fixture(scope="session")
def hand():
    """The shipped Allegro right hand (symbolic functions built once per session)."""
    from regrasp_casadi.hand import Hand

    return Hand.allegro_right()


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    """``../shared/reference`` beside the repository; skips the test when it is absent."""
    if not REFERENCE_DIR.is_dir():
        pytest.skip(f"reference data not present: {REFERENCE_DIR}")
    return REFERENCE_DIR


@pytest.fixture(scope="session")
def box_object():
    """Generated box, 0.05 × 0.09 × 0.175 m (YCB sugar-box size), one convex piece of 6 planes."""
    from regrasp_casadi.objects import ObjectModel

    return ObjectModel.box((0.05, 0.09, 0.175))


@pytest.fixture(scope="session")
def cylinder_object():
    """Generated cylinder about z, radius 0.035 m, height 0.2 m, 32 sides (34 planes)."""
    from regrasp_casadi.objects import ObjectModel

    return ObjectModel.cylinder(0.035, 0.2)


@pytest.fixture(scope="session")
def banana_small(tmp_path_factory):
    """A low-resolution banana (coacd, a few convex pieces) decomposed into a private cache."""
    from regrasp_casadi.objects import ObjectModel

    mp = pytest.MonkeyPatch()
    mp.setenv("REGRASP_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    obj = ObjectModel.banana(rings=10, sections=8)
    mp.undo()
    return obj
