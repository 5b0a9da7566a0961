"""Every example runs headless and prints what its docstring promises."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("[0-9][0-9]_*.py"))


def test_examples_are_numbered_and_documented():
    assert [p.name[:2] for p in EXAMPLES] == [f"{i:02d}" for i in range(1, len(EXAMPLES) + 1)]
    for path in EXAMPLES:
        text = path.read_text()
        assert text.startswith('"""') and len(text.splitlines()) <= 120, path.name


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(path, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["--html", str(tmp_path / "replay.html")] if path.stem == "05_plan_regrasp" else []
    monkeypatch.setattr(sys, "argv", [str(path), *argv])
    runpy.run_path(str(path), run_name="__main__")
    out = capsys.readouterr().out
    assert out.strip(), "an example prints a summary"
    if path.stem == "05_plan_regrasp":
        assert "verify: ok" in out and "status: converged" in out
        assert (tmp_path / "plan.json").is_file() and (tmp_path / "replay.html").stat().st_size > 10_000
    if path.stem == "03_finger_gait":
        assert "status Solve_Succeeded" in out
