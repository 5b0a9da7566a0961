"""nlp_cache.py: the NLPs kept across plans (`NLPCache`) and the solvers kept by the hash of their
expressions (`build_solver` builds OPT2 once per process, not once per object)."""

from __future__ import annotations

import gc
import weakref
from pathlib import Path

import casadi as ca
import numpy as np

from regrasp_casadi import nlp_cache
from regrasp_casadi.in_grasp import InGraspNLP
from regrasp_casadi.nlp_cache import NLPCache
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.solver import SolverOptions, build_solver

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"


# ------------------------------------------------------------------------------------------- NLP cache
class _Model:
    """Stands for a Hand or ObjectModel (compared by identity, like them)."""


def test_cache_builds_once_per_kind_models_and_key():
    cache = NLPCache()
    hand, obj = _Model(), _Model()
    built = []

    def build(tag):
        return lambda: built.append(tag) or tag

    assert cache.get("gait", hand, obj, "index", build("a")) == "a"
    assert cache.get("gait", hand, obj, "index", build("b")) == "a"  # a hit: build not called
    assert cache.get("gait", hand, _Model(), "index", build("c")) == "c"  # another object
    assert cache.get("in_grasp", hand, obj, "index", build("d")) == "d"  # another kind
    assert built == ["a", "c", "d"] and cache.builds == 3 and len(cache) == 3
    cache.clear()
    assert len(cache) == 0 and cache.get("gait", hand, obj, "index", build("e")) == "e"


def test_cache_holds_its_models_until_cleared():
    """A cached model cannot be collected, so its id cannot be reused by a new model while cached."""
    cache = NLPCache()
    obj = _Model()
    alive = weakref.ref(obj)
    cache.get("gait", _Model(), obj, None, lambda: "nlp")
    del obj
    gc.collect()
    assert alive() is not None
    cache.clear()
    gc.collect()
    assert alive() is None


def test_cache_drops_the_least_recently_used():
    cache = NLPCache(max_size=2)
    hand, obj = _Model(), _Model()
    for key in ("a", "b"):
        cache.get("k", hand, obj, key, lambda key=key: key)
    cache.get("k", hand, obj, "a", lambda: "rebuilt a")  # a hit: "a" is now the most recent
    cache.get("k", hand, obj, "c", lambda: "c")  # drops "b"
    assert cache.get("k", hand, obj, "a", lambda: "rebuilt a") == "a"
    assert cache.get("k", hand, obj, "b", lambda: "rebuilt b") == "rebuilt b"


# ----------------------------------------------------------------------------------------- kept solvers
def _toy(power: int = 2):
    """min (x0 − p)^power + x1² s.t. x0 + x1 ≤ 1, built from new symbols on every call."""
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    return {"x": x, "p": p, "f": (x[0] - p) ** power + x[1] ** 2, "g": x[0] + x[1]}


def test_a_solver_built_again_from_the_same_expressions_is_the_kept_one():
    nlp_cache.clear_built_solvers()
    first = build_solver("toy", _toy(), SolverOptions(compiled=False))
    assert build_solver("toy", _toy(), SolverOptions(compiled=False)) is first  # new symbols, same NLP
    others = [build_solver("toy", _toy(4), SolverOptions(compiled=False)),  # another objective
              build_solver("toy", _toy(), SolverOptions(compiled=False, warm_start=False)),  # other options
              build_solver("toy", _toy(), SolverOptions(compiled=False), curved_rows=[]),  # another Hessian
              build_solver("other", _toy(), SolverOptions(compiled=False))]  # another name
    assert all(o is not first for o in others) and len({id(o) for o in others}) == 4
    nlp_cache.clear_built_solvers()
    again = build_solver("toy", _toy(), SolverOptions(compiled=False))
    assert again is not first
    for s in (first, again):  # the kept solver solves as a new one: x0 + x1 = 1 active, x = (1.5, −0.5)
        sol = s(x0=[0.0, 0.0], p=2.0, lbx=-10, ubx=10, lbg=-10, ubg=1)
        np.testing.assert_allclose(np.asarray(sol["x"]).ravel(), [1.5, -0.5], atol=1e-6)


def test_opt2_is_built_once_for_two_objects_and_solves_as_built_alone():
    """OPT2's object data are parameters: the box (one convex piece) and the bottle (several) share one
    solver, and the bottle's reposing with it is the one its own, newly built solver gives."""
    box, bottle = (RegraspProblem.load(PROBLEMS / f"{n}.yaml") for n in ("box_rotate", "bottle_regrasp"))
    nlp_cache.clear_built_solvers()
    on_box = InGraspNLP(box.hand, box.obj, "svd")
    shared = InGraspNLP(bottle.hand, bottle.obj, "svd")
    assert shared._solver is on_box._solver
    nlp_cache.clear_built_solvers()
    alone = InGraspNLP(bottle.hand, bottle.obj, "svd")
    assert alone._solver is not on_box._solver
    g0 = bottle.grasp0
    T_target = np.array(g0.T_palm_object)
    T_target[:3, 3] += [0.0, 0.0, 0.003]
    a, b = (nlp.solve(g0.q, g0.T_palm_object, g0.tip_centers_object, T_target=T_target)
            for nlp in (shared, alone))
    assert a.success and a.status == b.status and a.iterations == b.iterations
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.T_palm_object, b.T_palm_object)
