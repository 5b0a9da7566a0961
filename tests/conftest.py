"""Shared pytest fixtures: the session-wide Allegro hand and the reference-data folder."""

from __future__ import annotations

from pathlib import Path

import pytest

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
