"""solver.py: the parameter layout, the exact-offset correction loop, the warm-start policy and the
Hessian of the Lagrangian."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import brentq

from regrasp_casadi import solver
from regrasp_casadi.solver import (
    Bounds,
    ParamLayout,
    SolverOptions,
    WarmStart,
    build_solver,
    correct_offsets,
)

LAYOUT = ParamLayout([("q", (4,)), ("R_palm_object", (3, 3)), ("p_object_tips", (3, 2)), ("delta", (0,))])


def _values(rng):
    return {"q": rng.normal(size=4), "R_palm_object": rng.normal(size=(3, 3)),
            "p_object_tips": rng.normal(size=(3, 2)), "delta": np.zeros(0)}


def test_pack_puts_blocks_where_the_casadi_symbols_read_them():
    """The numeric p of `pack`, fed to a CasADi function of the layout's symbols, gives back each block
    (CasADi's own column-major `vec` is the independent reference)."""
    p, blocks = LAYOUT.symbols()
    assert p.shape == (LAYOUT.size, 1) and LAYOUT.size == 4 + 9 + 6
    read = ca.Function("read", [p], list(blocks.values()))
    values = _values(np.random.default_rng(0))
    for got, want in zip(read(LAYOUT.pack(**values)), values.values(), strict=True):
        assert np.array_equal(np.asarray(got).reshape(want.shape), want)


def test_pack_is_column_major_and_unpack_inverts_it():
    values = _values(np.random.default_rng(1))
    p = LAYOUT.pack(**values)
    # column-major = the rows of the transpose, concatenated
    assert np.array_equal(p[4:13], values["R_palm_object"].T.reshape(-1))
    assert np.array_equal(p[13:19], np.concatenate([values["p_object_tips"][:, 0],
                                                    values["p_object_tips"][:, 1]]))
    back = LAYOUT.unpack(p)
    assert all(np.array_equal(back[k], v) for k, v in values.items())


def test_pack_errors_name_the_block():
    values = _values(np.random.default_rng(2))
    with pytest.raises(ValueError, match=r"'p_object_tips': expected shape \(3, 2\), got \(2, 3\)"):
        LAYOUT.pack(**{**values, "p_object_tips": values["p_object_tips"].T})
    with pytest.raises(ValueError, match=r"missing \['q'\]"):
        LAYOUT.pack(**{k: v for k, v in values.items() if k != "q"})
    with pytest.raises(ValueError, match=r"unknown \['w'\]"):
        LAYOUT.pack(**values, w=np.zeros(3))
    with pytest.raises(ValueError, match="'q' appears twice"):
        ParamLayout([("q", (2,)), ("q", (3,))])


# ----------------------------------------------------------------------- the correction loop on a toy NLP
# min (x − 2)²  s.t.  s(x) + δ = 1, with the smooth model s(x) = x, so the solution is x = 1 − δ.
# The "exact" distance e(x) differs from the model; the loop must find the x where e(x) = 1.

@pytest.fixture(scope="module")
def toy():
    x = ca.SX.sym("x")
    delta = ca.SX.sym("delta")
    nlp_solver = build_solver("toy", {"x": x, "p": delta, "f": (x - 2) ** 2, "g": x + delta},
                              SolverOptions(warm_start=False))
    bounds = Bounds(np.array([-10.0]), np.array([10.0]), np.array([1.0]), np.array([1.0]))
    return nlp_solver, bounds


def _run(toy, exact, max_solves=10, accept=None):
    nlp_solver, bounds = toy

    def solve_with(x, delta):
        return solver.solve(nlp_solver, x0=x, p=delta, **bounds.kwargs())

    def evaluate(x, delta):
        return float(exact(x[0])), float(x[0])  # exact and smooth distance at x

    return correct_offsets(solve_with, evaluate, lambda ev: abs(ev[0] - 1.0) <= 1e-10,
                           lambda x, ev, delta: ev[0] - ev[1], offsets=0.0, x=np.array([0.0]),
                           evaluation=evaluate(np.array([0.0]), 0.0), max_solves=max_solves,
                           accept=accept or solver.clipped_if_finite(bounds))


def test_correction_with_a_constant_bias_takes_two_solves(toy):
    corr = _run(toy, lambda x: x + 0.3)  # the exact offset is 0.3 everywhere
    assert corr.converged and corr.usable and corr.solves == 2
    assert corr.x[0] == pytest.approx(0.7, abs=1e-9)
    assert corr.result.success and corr.iterations >= 2


def test_correction_reaches_the_exact_root(toy):
    def exact(x):
        return x + 0.3 + 0.2 * np.sin(3.0 * x)  # offset varies, |d offset/dx| ≤ 0.6 < 1: a contraction

    corr = _run(toy, exact, max_solves=60)
    assert corr.converged
    assert corr.x[0] == pytest.approx(brentq(lambda x: exact(x) - 1.0, 0.0, 1.0), abs=1e-9)


def test_correction_stops_after_max_solves_and_at_an_unusable_point(toy):
    corr = _run(toy, lambda x: x + 0.3, max_solves=1)
    assert not corr.converged and corr.usable and corr.solves == 1
    assert corr.x[0] == pytest.approx(1.0, abs=1e-9)  # the first solve, with δ = 0
    corr = _run(toy, lambda x: x + 0.3, accept=lambda res: None)
    assert not corr.usable and corr.solves == 1 and corr.x[0] == 0.0 and corr.evaluation == (0.3, 0.0)


def test_warm_start_keeps_the_multipliers_of_successful_solves_only(toy):
    nlp_solver, bounds = toy
    warm = WarmStart()
    infeasible = Bounds(bounds.lbx, np.array([-5.0]), bounds.lbg, bounds.ubg)  # x ≤ −5 and x = 1
    res = warm.solve(nlp_solver, infeasible, x0=np.array([0.0]), p=np.array([0.0]))
    assert not res.success and not warm.is_warm
    res = warm.solve(nlp_solver, bounds, x0=np.array([0.0]), p=np.array([0.0]))
    assert res.success and warm.is_warm
    warm.reset()
    assert not warm.is_warm


# ------------------------------------------------------------------ a Hessian without some rows' curvature
# f = (x0 − p)² + x0·x1², g = [x0 + 0.2·x1², sin(x0)·x1]: closed-form Hessians.
def _curved_toy():
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    return {"x": x, "p": p, "f": (x[0] - p) ** 2 + x[0] * x[1] ** 2,
            "g": ca.vertcat(x[0] + 0.2 * x[1] ** 2, ca.sin(x[0]) * x[1])}


def _closed_form_hessian(x, lam_f, lam_g, rows):
    x0, x1 = x
    h_f = np.array([[2.0, 2 * x1], [2 * x1, 2 * x0]])
    h_g = [np.diag([0.0, 0.4]), np.array([[-np.sin(x0) * x1, np.cos(x0)], [np.cos(x0), 0.0]])]
    return lam_f * h_f + sum(lam_g[i] * h_g[i] for i in rows)


@pytest.mark.parametrize("rows", [None, [1], []])
def test_the_solver_uses_the_hessian_of_the_curved_rows_only(rows):
    """`build_solver(..., curved_rows)`: the backend's Hessian of the Lagrangian (the function IPOPT
    calls) is the closed form λ_f ∇²f + Σ_{i ∈ rows} λ_i ∇²g_i, upper triangle; None: all rows."""
    s = build_solver("curved_toy", _curved_toy(), SolverOptions(compiled=False), curved_rows=rows)
    hess = s.get_function("nlp_hess_l")
    rng = np.random.default_rng(1)
    for _ in range(3):
        x, lam_f, lam_g = rng.normal(size=2), rng.uniform(0.5, 2), rng.normal(size=2)
        got = np.asarray(ca.DM(hess(x, 0.3, lam_f, lam_g)).full())
        want = _closed_form_hessian(x, lam_f, lam_g, range(2) if rows is None else rows)
        np.testing.assert_allclose(got, np.triu(want), atol=1e-12)


def test_a_linearised_row_leaves_the_solution_of_the_nlp_unchanged():
    """A constraint entering the Newton steps without its curvature changes the path, not the KKT point:
    min (x0 − 2)² + x0·x1² s.t. x0 + 0.2·x1² ≤ 1 (active at x = (1, 0), its multiplier 2 in closed form)
    is solved to that point with and without the constraint's curvature; a wrong row index is an error."""
    nlp = _curved_toy()
    for rows in (None, [1]):
        s = build_solver("curved_toy", nlp, SolverOptions(compiled=False, warm_start=False), curved_rows=rows)
        sol = s(x0=[0.5, 0.2], p=2.0, lbx=-5, ubx=5, lbg=[-np.inf, -5], ubg=[1, 5])
        assert s.stats()["return_status"] == "Solve_Succeeded"
        np.testing.assert_allclose(np.asarray(sol["x"]).ravel(), [1.0, 0.0], atol=1e-6)
        np.testing.assert_allclose(np.asarray(sol["lam_g"]).ravel(), [2.0, 0.0], atol=1e-6)
    with pytest.raises(ValueError, match="must index the 2 constraints"):
        build_solver("curved_toy", nlp, curved_rows=[2])
