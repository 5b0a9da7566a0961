"""IPOPT through CasADi: the options the NLPs share and a guarded solve that never raises.

A failed solve is a status, not an exception: `solve` maps IPOPT's `return_status` into `SolveResult`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

__all__ = ["SolveResult", "ipopt_options", "solve", "SUCCESS_STATUSES"]

_log = logging.getLogger(__name__)

SUCCESS_STATUSES = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


@dataclass(frozen=True)
class SolveResult:
    """The outcome of one NLP solve."""

    x: NDArray[np.float64]
    """Primal solution (n_x,)."""
    lam_x: NDArray[np.float64]
    """Bound multipliers (n_x,), for warm starts."""
    lam_g: NDArray[np.float64]
    """Constraint multipliers (n_g,), for warm starts."""
    f: float
    """Objective value (the NLP's own scaling)."""
    g: NDArray[np.float64]
    """Constraint values (n_g,)."""
    status: str
    """IPOPT's return_status, e.g. "Solve_Succeeded", or "exception: ..." if CasADi raised."""
    iterations: int
    """IPOPT iterations."""
    time: float
    """Wall time of the call, s."""

    @property
    def success(self) -> bool:
        return self.status in SUCCESS_STATUSES


def ipopt_options(print_level: int = 0, max_iter: int = 300, warm: bool = True, tol: float = 1e-8) -> dict:
    """IPOPT options for the small, dense NLPs of the planner (exact Hessian, MUMPS)."""
    opts = {
        "print_time": False,
        "ipopt.print_level": print_level,
        "ipopt.sb": "yes",
        "ipopt.max_iter": max_iter,
        "ipopt.tol": tol,
        "ipopt.acceptable_tol": 1e-6,
        "ipopt.acceptable_iter": 10,
        "ipopt.constr_viol_tol": 1e-6,
        "ipopt.mu_strategy": "adaptive",
        "ipopt.linear_solver": "mumps",
    }
    if warm:
        opts.update({
            "ipopt.warm_start_init_point": "yes",
            "ipopt.warm_start_bound_push": 1e-9,
            "ipopt.warm_start_mult_bound_push": 1e-9,
            "ipopt.mu_init": 1e-4,
        })
    return opts


def solve(solver: ca.Function, *, x0, p, lbx, ubx, lbg, ubg, lam_x0=None, lam_g0=None) -> SolveResult:
    """Call an `nlpsol` solver; return a `SolveResult` whatever happens (never raises on a failed solve)."""
    args = {"x0": x0, "p": p, "lbx": lbx, "ubx": ubx, "lbg": lbg, "ubg": ubg}
    if lam_x0 is not None:
        args["lam_x0"] = lam_x0
    if lam_g0 is not None:
        args["lam_g0"] = lam_g0
    t0 = time.perf_counter()
    try:
        sol = solver(**args)
    except RuntimeError as exc:  # CasADi raises on evaluation errors (NaN in a function, ...)
        _log.warning("solver %s raised: %s", solver.name(), exc)
        n_x = int(np.size(x0))
        return SolveResult(np.asarray(x0, float).ravel(), np.zeros(n_x), np.zeros(int(np.size(lbg))),
                           float("nan"), np.full(int(np.size(lbg)), np.nan), f"exception: {exc}", 0,
                           time.perf_counter() - t0)
    elapsed = time.perf_counter() - t0
    try:
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        iterations = int(stats.get("iter_count", -1))
    except RuntimeError:  # CasADi 3.8 can raise from stats() after some failed solves
        status, iterations = "unknown", -1
    return SolveResult(
        x=np.asarray(sol["x"], float).ravel(),
        lam_x=np.asarray(sol["lam_x"], float).ravel(),
        lam_g=np.asarray(sol["lam_g"], float).ravel(),
        f=float(sol["f"]),
        g=np.asarray(sol["g"], float).ravel(),
        status=status,
        iterations=iterations,
        time=elapsed,
    )
