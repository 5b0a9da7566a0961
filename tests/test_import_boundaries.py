"""Import boundaries: the exact side of the geometry and `verify` load no smooth-distance, NLP, planner or
grasp-generation module.

Each check runs in a fresh interpreter (a module imported by an earlier test would otherwise be in
`sys.modules` already) and reports the forbidden modules it finds loaded.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

FORBIDDEN = (
    "regrasp_casadi.signed_distance",
    "regrasp_casadi.terms",
    "regrasp_casadi.solver",
    "regrasp_casadi.finger_gait",
    "regrasp_casadi.in_grasp",
    "regrasp_casadi.planner",
    "regrasp_casadi.grasp_gen",
)
"""Modules that exact checking must never load: the smooth distance, the NLPs and what builds them."""

EXACT_SIDE = ("objects", "convex", "exact_distance")
"""Modules that must not import CasADi or a forbidden module at module level (lazily inside a function
is allowed: that is how `ObjectModel` reaches the smooth side)."""

_REPORT = """
import json, sys
forbidden = {forbidden!r}
print(json.dumps([m for m in forbidden if m in sys.modules]))
"""


def _run(code: str, timeout: float = 600) -> str:
    """Run `code` in a fresh interpreter with this checkout first on the path; return its last line."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          cwd=REPO, env=env, timeout=timeout, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout.strip().splitlines()[-1]


def _loaded_forbidden(code: str) -> list[str]:
    return json.loads(_run(textwrap.dedent(code) + _REPORT.format(forbidden=FORBIDDEN)))


def test_exact_distances_of_a_shipped_problem_load_no_smooth_side():
    loaded = _loaded_forbidden("""
        import numpy as np
        import regrasp_casadi.verify
        from regrasp_casadi.problem import RegraspProblem

        problem = RegraspProblem.load("problems/box_rotate.yaml")
        obj = problem.obj
        p = np.array([[0.0, 0.0, 0.1], [0.03, 0.0, 0.0], [0.0, 0.0, 0.0]])
        obj.exact_signed_distance(p)
        obj.closest_points(p)
        obj.near_signed_distance(p)
        obj.surface_normals(p)
        obj.local_planes(p)
    """)
    assert loaded == []


@pytest.fixture(scope="module")
def box_shift_plan(tmp_path_factory, shipped_plan) -> Path:
    """The default plan of problems/box_shift.yaml (the session's, `conftest.shipped_plan`), saved as JSON
    for a fresh interpreter to load."""
    path = tmp_path_factory.mktemp("plan") / "box_shift.json"
    shipped_plan("box_shift", "svd")[1].save(path)
    return path


def test_verify_of_a_saved_plan_loads_no_smooth_side(box_shift_plan):
    loaded = _loaded_forbidden(f"""
        import regrasp_casadi.verify
        from regrasp_casadi.plan import Plan

        report = regrasp_casadi.verify.verify(Plan.load({str(box_shift_plan)!r}))
        assert report.ok, report.summary()
    """)
    assert loaded == []


def _module_level_imports(path: Path) -> set[str]:
    """Absolute module names imported at module level (outside functions and `if TYPE_CHECKING:`)."""
    names: set[str] = set()

    def visit(body):
        for node in body:
            if isinstance(node, ast.Import):
                names.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module:
                names.add(node.module)
                names.update(f"{node.module}.{a.name}" for a in node.names)
            elif isinstance(node, ast.If) and "TYPE_CHECKING" not in ast.unparse(node.test):
                visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                visit(node.body)

    visit(ast.parse(path.read_text()).body)
    return names


@pytest.mark.parametrize("module", EXACT_SIDE)
def test_exact_side_modules_import_no_casadi_at_module_level(module):
    imported = _module_level_imports(REPO / "regrasp_casadi" / f"{module}.py")
    bad = sorted(n for n in imported if n.split(".")[0] == "casadi" or n in FORBIDDEN)
    assert bad == []
