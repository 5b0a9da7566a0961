"""The compiled path of `solver.build_solver` (`regrasp_casadi.compiled`): the same solutions as the
interpreted solver, the disk cache, and the fallback when no C compiler is found.

The planner's NLPs are built on the shipped box problems (Allegro right hand, generated box 0.05 x 0.07 x
0.12 m). OPT1 without its self-collision constraints (~3 s to compile) runs in the default test run; the
planner's OPT1 (~30 s) and OPT2 (~2 min to compile with gcc -O1) are `slow`. The module gets its own
empty cache (``$REGRASP_CACHE_DIR``), as on CI.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from regrasp_casadi import compiled, nlp_cache
from regrasp_casadi.constants import SELF_CLEARANCE
from regrasp_casadi.finger_gait import FingerGaitNLP, FingerGaitOptions
from regrasp_casadi.in_grasp import InGraspNLP
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.solver import BACKEND, SolverOptions, backend_options, build_solver, lagrangian_hessian

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"


@pytest.fixture(scope="module")
def jit_cache(tmp_path_factory):
    """An empty cache folder for this module, set as ``$REGRASP_CACHE_DIR`` with compilation on."""
    mp = pytest.MonkeyPatch()
    folder = tmp_path_factory.mktemp("jit_cache")
    mp.setenv("REGRASP_CACHE_DIR", str(folder))
    yield folder
    mp.undo()


@pytest.fixture(autouse=True)
def no_kept_solvers():
    """Every build of this module reaches `compiled.solver` (no solver kept from an earlier build)."""
    nlp_cache.clear_built_solvers()


@pytest.fixture
def fresh_warnings(monkeypatch):
    """Forget which warnings were already logged, so this test sees its own."""
    monkeypatch.setattr(compiled, "_WARNED", set())


def _build(monkeypatch, switch: str, make):
    """`make()` with ``$REGRASP_COMPILE`` set to `switch` ("0", "1" or "cached")."""
    with monkeypatch.context() as mp:
        mp.setenv(compiled.ENV_VAR, switch)
        return make()


def _same(a, b):
    assert a.status == b.status
    assert a.iterations == b.iterations
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-6)
    if hasattr(a, "T_palm_object"):  # OPT2 moves the object too
        np.testing.assert_allclose(a.T_palm_object, b.T_palm_object, rtol=0, atol=1e-6)


def test_switch_and_option():
    """The option wins over the environment variable, which wins over the default ("cached")."""
    assert compiled.mode(True) == "compile" and compiled.mode(False) == "off"
    assert compiled.enabled(True) and not compiled.enabled(False)
    old = os.environ.get(compiled.ENV_VAR)
    try:
        os.environ[compiled.ENV_VAR] = "1"
        assert compiled.mode(None) == "compile" and compiled.mode(False) == "off"
        os.environ[compiled.ENV_VAR] = "0"
        assert compiled.mode(None) == "off" and compiled.mode(True) == "compile"
        os.environ[compiled.ENV_VAR] = "cached"
        assert compiled.mode(None) == "cached" and not compiled.enabled(None)
        del os.environ[compiled.ENV_VAR]
        assert compiled.mode(None) == compiled.DEFAULT == "cached"
    finally:
        if old is None:
            os.environ.pop(compiled.ENV_VAR, None)
        else:
            os.environ[compiled.ENV_VAR] = old


@pytest.mark.skipif(compiled.find_compiler() is None, reason="no C compiler")
@pytest.mark.parametrize("self_clearance", [
    None,  # no self-collision constraints: a 6x smaller Hessian, ~3 s to compile (default run)
    pytest.param(SELF_CLEARANCE, marks=pytest.mark.slow),  # the planner's OPT1, ~30 s to compile
])
def test_opt1_compiled_matches_interpreted_and_is_cached(jit_cache, monkeypatch, self_clearance):
    """OPT1: same solution and status compiled and interpreted; a second build loads the library
    from the disk cache (no compiler call, the file untouched)."""
    problem = RegraspProblem.load(PROBLEMS / "box_shift.yaml")
    hand, obj, g0 = problem.hand, problem.obj, problem.grasp0
    goal = problem.grasp_goal.tip_centers_object[hand.fingers.index("index")]
    options = FingerGaitOptions(self_clearance=self_clearance)

    def make():
        return FingerGaitNLP(hand, obj, "index", options)

    folder = jit_cache / "jit"
    before = set(folder.iterdir()) if folder.exists() else set()
    interpreted = _build(monkeypatch, "0", make)
    n0 = compiled.compile_count()
    records = len(compiled.build_records())
    _build(monkeypatch, "cached", make)  # nothing cached yet: interpreted, nothing compiled
    assert compiled.compile_count() == n0 and len(compiled.build_records()) == records
    assert not folder.exists() or set(folder.iterdir()) == before
    nlp_cache.clear_built_solvers()
    fast = _build(monkeypatch, "1", make)
    assert compiled.compile_count() == n0 + 1
    new = set(folder.iterdir()) - before
    assert len(new) == 1  # one library, no temporary file or folder left
    library = new.pop()
    assert library.suffix == ".so" and compiled.build_records()[-1].path == str(library)
    mtime = library.stat().st_mtime_ns

    a = interpreted.solve(g0.q, g0.T_palm_object, goal)
    b = fast.solve(g0.q, g0.T_palm_object, goal)
    assert a.success
    _same(a, b)

    for switch in ("1", "cached"):  # a new NLP object: same expressions, same key; loaded, not compiled
        nlp_cache.clear_built_solvers()  # as in a new process
        again = _build(monkeypatch, switch, make)
        assert compiled.compile_count() == n0 + 1
        assert library.stat().st_mtime_ns == mtime
        assert compiled.build_records()[-1].compiled is False
        assert compiled.build_records()[-1].path == str(library)
        _same(a, again.solve(g0.q, g0.T_palm_object, goal))


@pytest.mark.skipif(compiled.find_compiler() is None, reason="no C compiler")
@pytest.mark.slow  # 10 s in the default run (2026-12-03): the suite over its 10-minute budget
def test_opt2_is_one_nlp_per_hand(monkeypatch):
    """OPT2 does not depend on the object (ℓ and the local planes are parameters, an object of fewer
    convex pieces repeats its nearest): the box (one piece) and the bottle (several) give one compiled
    library key, so one library serves every object of a hand (method "sd" adds the hand's workspace
    hulls only)."""
    keys = []

    def record(name, nlp, backend, opts, compile_missing=True):  # the key `compiled.solver` would use
        keys.append(compiled.library_key(nlp, backend, opts, compiled.find_compiler()))
        return ca.nlpsol(name, backend, nlp, opts)

    monkeypatch.setattr(compiled, "solver", record)
    pieces = []
    for name in ("box_rotate", "bottle_regrasp"):
        problem = RegraspProblem.load(PROBLEMS / f"{name}.yaml")
        pieces.append(len(problem.obj.pieces))
        nlp_cache.clear_built_solvers()  # else the second build is the first's solver, kept
        _build(monkeypatch, "1", lambda: InGraspNLP(problem.hand, problem.obj, "svd"))  # noqa: B023
    assert pieces[0] == 1 and pieces[1] > 1
    assert len(keys) == 2 and keys[0] == keys[1]


@pytest.mark.slow
@pytest.mark.skipif(compiled.find_compiler() is None, reason="no C compiler")
def test_opt2_compiled_matches_interpreted(jit_cache, monkeypatch):
    """OPT2 ("svd"): the same solutions and statuses compiled and interpreted, for six 2 mm moves."""
    problem = RegraspProblem.load(PROBLEMS / "box_rotate.yaml")
    g0 = problem.grasp0

    def make():
        return InGraspNLP(problem.hand, problem.obj, "svd")

    interpreted = _build(monkeypatch, "0", make)
    n0 = compiled.compile_count()
    fast = _build(monkeypatch, "1", make)
    assert compiled.compile_count() == n0 + 1
    for d in np.vstack([np.eye(3), -np.eye(3)]) * 0.002:
        T_target = np.array(g0.T_palm_object)
        T_target[:3, 3] += d
        a, b = (nlp.solve(g0.q, g0.T_palm_object, g0.tip_centers_object, T_target=T_target)
                for nlp in (interpreted, fast))
        assert a.success, a.status
        _same(a, b)


def _toy():
    """A small NLP: min (x0 - p)² + x1² s.t. -1 ≤ x0·x1 ≤ 1."""
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    return {"x": x, "p": p, "f": (x[0] - p) ** 2 + x[1] ** 2, "g": x[0] * x[1]}


def test_missing_compiler_falls_back_with_one_warning(jit_cache, monkeypatch, tmp_path, caplog,
                                                      fresh_warnings):
    """No C compiler on the PATH: a warning (once per process) and the interpreted solver, which
    solves."""
    monkeypatch.setenv("PATH", str(tmp_path))  # an empty folder: neither cc nor gcc
    assert compiled.find_compiler() is None
    n0 = compiled.compile_count()
    with caplog.at_level(logging.WARNING, logger="regrasp_casadi.compiled"):
        solvers = []
        for _ in range(2):  # two builds (none kept), one warning
            nlp_cache.clear_built_solvers()
            solvers.append(build_solver("toy", _toy(), SolverOptions(compiled=True)))
    warnings = [r for r in caplog.records if "no C compiler" in r.getMessage()]
    assert len(warnings) == 1
    assert compiled.compile_count() == n0
    for s in solvers:
        sol = s(x0=[1.0, 1.0], p=2.0, lbx=-10, ubx=10, lbg=-1, ubg=1)
        assert s.stats()["return_status"] == "Solve_Succeeded"
        np.testing.assert_allclose(np.asarray(sol["x"]).ravel(), [2.0, 0.0], atol=1e-6)


def test_failing_compiler_falls_back(jit_cache, monkeypatch, tmp_path, caplog, fresh_warnings):
    """A compiler that fails: a warning, no library in the cache, and the interpreted solver solves."""
    fake = tmp_path / "cc"
    fake.write_text("#!/bin/sh\necho 'cc: broken' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path))
    folder = jit_cache / "jit"
    before = sorted(folder.iterdir()) if folder.exists() else []
    with caplog.at_level(logging.WARNING, logger="regrasp_casadi.compiled"):
        s = build_solver("toy", _toy(), SolverOptions(compiled=True))
    assert any("compiling NLP toy failed" in r.getMessage() for r in caplog.records)
    assert sorted(folder.iterdir()) == before  # no library, no temporary folder left
    sol = s(x0=[1.0, 1.0], p=2.0, lbx=-10, ubx=10, lbg=-1, ubg=1)
    np.testing.assert_allclose(np.asarray(sol["x"]).ravel(), [2.0, 0.0], atol=1e-6)


@pytest.mark.skipif(compiled.find_compiler() is None, reason="no C compiler")
def test_a_hessian_without_a_rows_curvature_is_compiled_under_its_own_key(jit_cache):
    """`build_solver(..., curved_rows=[])` compiled: the library's Hessian of the Lagrangian is the
    objective's alone (closed form 2·λ_f·I for min (x0 − p)² + x1², the curvature of g = x0·x1 left out),
    and its cache key differs from the exact Hessian's, so neither library is loaded for the other."""
    keys = []
    for rows in (None, []):
        opts = backend_options(SolverOptions())
        if rows is not None:
            opts["hess_lag"] = lagrangian_hessian(_toy(), rows)
        keys.append(compiled.library_key(_toy(), BACKEND, opts, compiled.find_compiler()))
    assert keys[0] != keys[1]
    s = build_solver("toy", _toy(), SolverOptions(compiled=True), curved_rows=[])
    assert compiled.build_records()[-1].path == str(compiled.library_path(keys[1]))
    hess = np.asarray(ca.DM(s.get_function("nlp_hess_l")([0.3, -0.7], 2.0, 1.5, 4.0)).full())
    np.testing.assert_allclose(hess, np.triu(3.0 * np.eye(2)), atol=1e-12)
    sol = s(x0=[1.0, 1.0], p=2.0, lbx=-10, ubx=10, lbg=-1, ubg=1)
    np.testing.assert_allclose(np.asarray(sol["x"]).ravel(), [2.0, 0.0], atol=1e-6)


def test_regrasp_compile_covers_every_nlp_a_plan_builds(monkeypatch):
    """`precompile`'s NLPs (what `regrasp compile` puts in the cache) have every compiled-library key the
    planner asks for, both methods, on an object of one convex piece (the box) and of several (the
    bottle): after `regrasp compile` no plan of the hand compiles or falls back to the interpreted
    solver. Keys only (`compiled.solver` replaced by a recorder): nothing is compiled."""
    from regrasp_casadi import precompile
    from regrasp_casadi.planner import plan_regrasp

    keys: dict[str, set[str]] = {"precompile": set(), "plans": set()}
    into = "precompile"

    def record(name, nlp, backend, opts, compile_missing=True):
        keys[into].add(compiled.library_key(nlp, backend, opts, compiled.find_compiler() or "cc"))
        return ca.nlpsol(name, backend, nlp, opts)

    monkeypatch.setattr(compiled, "solver", record)
    monkeypatch.setenv(compiled.ENV_VAR, "1")
    from regrasp_casadi.hand_model import load_hand

    for _, kind, arg in precompile.planner_nlps(load_hand("allegro_right")):
        precompile._build("allegro_right", kind, arg)
    monkeypatch.setenv(compiled.ENV_VAR, "1")  # (`_build` sets it in its worker)
    into = "plans"
    pieces = []
    for name in ("box_rotate", "bottle_regrasp"):
        problem = RegraspProblem.load(PROBLEMS / f"{name}.yaml")
        pieces.append(len(problem.obj.pieces))
        for method in ("svd", "sd"):
            nlp_cache.clear_built_solvers()
            plan_regrasp(problem.grasp0, problem.grasp_goal, method=method, stability="none", max_iters=1,
                         cache=nlp_cache.NLPCache())
    assert pieces[0] == 1 and pieces[1] > 1
    assert len(keys["precompile"]) == 10  # OPT2 x 2 methods, OPT1 x 4 fingers x (one, several pieces)
    assert keys["plans"] and keys["plans"] <= keys["precompile"], len(keys["plans"] - keys["precompile"])
