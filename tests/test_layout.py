"""The package's size rules: no module in `regrasp_casadi/` over 600 lines, no function over 80.

Ruff's PLR limits (pyproject.toml) bound arguments, branches, returns and statements; these two bounds
are the project's own (a module holds one concept; a function does one named step).
"""

from __future__ import annotations

import ast
from pathlib import Path

import regrasp_casadi

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80

PACKAGE = Path(regrasp_casadi.__file__).resolve().parent
REPO = Path(__file__).resolve().parents[1]


def _modules() -> list[Path]:
    return sorted(PACKAGE.glob("*.py"))


def _long_functions(source: str, limit: int) -> list[tuple[str, int]]:
    """(qualified name, lines) of every function or method of `source` longer than `limit` lines, from
    its `def` line to its last line (docstring and nested functions included, decorators not)."""
    found: list[tuple[str, int]] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    lines = child.end_lineno - child.lineno + 1
                    if lines > limit:
                        found.append((name, lines))
                visit(child, name + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(source), "")
    return found


def _body(n: int, indent: int) -> str:
    return "\n".join(" " * indent + f"x{i} = {i}" for i in range(n))


def test_the_function_measure_counts_from_def_to_last_line():
    source = "\n".join([
        "@decorator", "def at_limit():", _body(79, 4),  # def + 79 lines = 80
        "class A:", "    def long(self):", _body(80, 8),  # 81
        "    def outer(self):", "        def inner():", _body(79, 12),  # inner 80, outer 81
    ]) + "\n"
    assert _long_functions(source, MAX_FUNCTION_LINES) == [("A.long", 81), ("A.outer", 81)]


def test_no_module_over_600_lines():
    assert len(_modules()) > 20  # the package itself, not an empty folder
    lines = {p.name: len(p.read_text(encoding="utf-8").splitlines()) for p in _modules()}
    long = {name: n for name, n in lines.items() if n > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_no_function_over_80_lines():
    long = {f"{p.name}:{name}": n for p in _modules()
            for name, n in _long_functions(p.read_text(encoding="utf-8"), MAX_FUNCTION_LINES)}
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {long}"


def test_ci_runs_the_readme_command_with_the_lint():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    block = readme.split("Run the lint and the tests", 1)[1].split("```bash\n", 1)[1].split("\n```", 1)[0]
    ci = [line for line in (REPO / ".ci" / "run").read_text(encoding="utf-8").splitlines()
          if line and not line.startswith("#")]
    assert ci[-1] == block.strip()
    assert "ruff check . && python -m pytest" in block
