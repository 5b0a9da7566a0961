"""Shared pytest fixtures: the session-wide Allegro hand and the reference-data folder."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ["REGRASP_COMPILE"] = "0"  # NLPs interpreted (no compiler runs) unless a test asks otherwise

REFERENCE_DIR = Path(__file__).resolve().parents[2] / "shared" / "reference"
SHIPPED_PROBLEMS = Path(__file__).resolve().parents[1] / "problems"


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


@pytest.fixture(scope="session")
def shipped_plan():
    """plan_of(stem, method="svd", **options) -> (problem, plan): the shipped problem
    ``problems/<stem>.yaml`` (a `RegraspProblem`) and its `plan_regrasp` plan, planned once per session for
    every test that asks for the same stem, method and options. Sharing is sound: one process gives the
    same plan for the same input (tests/test_planner.py::test_same_input_same_plan) and a `Plan` is
    frozen. Saves the default run a plan of 15-25 s per repeat."""
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem

    cache: dict = {}

    def plan_of(stem: str, method: str = "svd", **options):
        key = (stem, method, tuple(sorted(options.items())))
        if key not in cache:
            problem = RegraspProblem.load(SHIPPED_PROBLEMS / f"{stem}.yaml")
            cache[key] = (problem, plan_regrasp(problem.grasp0, problem.grasp_goal, method=method, **options))
        return cache[key]

    return plan_of
