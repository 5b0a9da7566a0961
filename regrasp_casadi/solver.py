"""The one home of solving: the NLP backend and its options, the parameter layout, a guarded solve with
its success test, the warm-start policy and the exact-offset correction loop.

Every NLP of the package is built by `build_solver` (kept in a `nlp_cache.NLPCache`), so swapping IPOPT
for another CasADi `nlpsol` plugin is a change of this file only (`BACKEND` and `backend_options`). A failed
solve is a status, not an exception: `solve` maps the backend's `return_status` into `SolveResult`.

    >>> layout = ParamLayout([("R_palm_object", (3, 3)), ("t_palm_object", (3,))])
    >>> p_sym, blocks = layout.symbols()                       # CasADi symbols, one per block
    >>> solver = build_solver("my_nlp", {"x": x, "p": p_sym, "f": f, "g": g}, SolverOptions())
    >>> res = solve(solver, x0=x0, p=layout.pack(R_palm_object=R, t_palm_object=t), **bounds.kwargs())
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from regrasp_casadi import compiled, nlp_cache, solve_log
from regrasp_casadi.constants import BETA, SELF_CLEARANCE

__all__ = [
    "BACKEND",
    "SUCCESS_STATUSES",
    "SolverOptions",
    "NLPOptions",
    "SolveStats",
    "backend_options",
    "build_solver",
    "lagrangian_hessian",
    "Bounds",
    "NO_WORSE_SLACK",
    "no_worse",
    "SolveResult",
    "succeeded",
    "solve",
    "WarmStart",
    "ParamLayout",
    "Correction",
    "correct_offsets",
    "clipped_if_finite",
]

_log = logging.getLogger(__name__)

BACKEND = "ipopt"
"""The CasADi `nlpsol` plugin every NLP of the package is built with."""

SUCCESS_STATUSES = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
"""Return statuses of the backend that count as a successful solve."""


# ------------------------------------------------------------------------------------ backend, options
@dataclass(frozen=True)
class SolverOptions:
    """Backend-neutral knobs of one NLP's solver; `backend_options` translates them (None: the backend's
    own default)."""

    print_level: int = 0
    """Verbosity (0 = quiet)."""
    max_iter: int = 300
    """Largest number of iterations of one solve."""
    tol: float = 1e-8
    """Convergence tolerance (scaled NLP error)."""
    acceptable_tol: float | None = 1e-6
    """Tolerance of an "acceptable" solution, reached for `acceptable_iter` iterations."""
    acceptable_iter: int | None = 10
    """Iterations at the acceptable level after which the solve stops as acceptable."""
    acceptable_obj_change_tol: float | None = None
    """The acceptable level also asks the objective's relative change per iteration to be below this."""
    acceptable_constr_viol_tol: float | None = None
    """The acceptable level's bound on the constraint violation (the constraints' own units)."""
    constr_viol_tol: float = 1e-6
    """Absolute tolerance on the constraint violation."""
    warm_start: bool = True
    """Start from the given primal and dual point (small initial barrier, no bound push)."""
    bound_relax_factor: float | None = None
    """Relaxation of the variable and constraint bounds (0: bounds hold exactly)."""
    linear_solver: str | None = "mumps"
    """Sparse linear solver of the Newton steps."""
    compiled: bool | None = None
    """Evaluate the NLP's functions from C compiled by the system compiler (`compiled`, cached on disk)
    instead of CasADi's virtual machine, compiling it when the disk cache lacks it; False: never; None:
    ``$REGRASP_COMPILE`` ("1", "cached": only libraries already cached, "0"), else `compiled.DEFAULT`
    ("cached")."""


@dataclass(frozen=True)
class NLPOptions:
    """The options the planner's NLPs (OPT1, OPT2) have in common: the clearance β, the smooth distance
    model that stands in for the mesh, the exact-offset correction (`correct_offsets`), the solver's
    verbosity and the self-clearance; SI units. Each NLP's options extend these."""

    beta: float = BETA
    """β, clearance the hand's non-contact spheres keep from the object, m (paper: 1 mm)."""
    tau: float | None = None
    """Temperature of the object's smooth signed distance (None: the object's default), m."""
    max_corrections: int = 2
    """Re-solves with exact-distance offsets after the first solve."""
    print_level: int = 0
    """Solver print level (0 = quiet)."""
    self_clearance: float | None = SELF_CLEARANCE
    """Clearance the spheres of different fingers, and of a finger and the palm, keep
    (`Hand.self_collision_pairs`; OPT1: the moving finger's against the others), m; a pair closer than
    this at the start of a solve may not get closer; None: no self-collision constraint (the paper's)."""

    clearance_curvature: bool = True
    """Whether the Hessian of the Lagrangian includes the curvature of the non-tip spheres' clearance
    constraints (True: IPOPT's exact Hessian). False: they enter IPOPT's Newton steps linearised (exact
    Jacobian; `lagrangian_hessian`), the objective's, the tips' and the self-collision pairs' curvature
    kept; a solution is a KKT point of the same NLP, reached with linear convergence where the clearance
    constraints are active. Why OPT2 has it off: the clearance spheres' curvature was the costliest part of
    its Hessian; without it an OPT2 iteration took 5.3 ms instead of 7.2 ms and the paper benchmark's plans
    14 % less time (interleaved A/B, benchmarks/README "Latest results"). On OPT1 it saved 7 % per call
    and cost an iteration per solve: on there."""
    settled_change: float | None = None
    """A solve stops (as IPOPT's "acceptable") once the objective has changed by less than this share of
    itself in each of `settled_iterations` iterations in a row with the constraints held within
    `settled_violation`; None: IPOPT's usual tolerances only. Why OPT2 has it on: with rolling tips its
    objective is nearly flat along some directions, and IPOPT zig-zagged along them against the tips'
    curved surface equalities long after the objective had settled (IPOPT's log, banana_1 svd: 58
    iterations, the objective within 0.1 % of its end value from the 27th, steps of up to 1.5 rad cut back
    by the line search). Paper benchmark (stability "none"): OPT2 iterations median 15 / 16 → 8 / 8 (svd /
    sd), per call 85 / 93 → 55 / 54 ms, 48 of 50 plans converged before and after. On OPT1 it changed no
    time per call and two plans fewer converged: off there."""
    settled_iterations: int = 3
    """Iterations in a row the objective must stay settled."""
    settled_violation: float = 1e-5
    """Largest constraint violation of a settled solve, m (the NLPs' distance constraints are in mm)."""

    def solver_options(self) -> SolverOptions:
        """The `SolverOptions` of the NLP: the defaults, with this print level and the settled stop."""
        if self.settled_change is None:
            return SolverOptions(print_level=self.print_level)
        return SolverOptions(print_level=self.print_level, acceptable_tol=1e6,
                             acceptable_iter=self.settled_iterations,
                             acceptable_obj_change_tol=self.settled_change,
                             acceptable_constr_viol_tol=1e3 * self.settled_violation)


def backend_options(options: SolverOptions) -> dict:
    """The `nlpsol` options dict of `BACKEND` (IPOPT: exact Hessian, adaptive barrier) for `options`."""
    o = options
    opts: dict = {
        "print_time": False,
        "calc_lam_p": False,  # the parameters' multipliers: unused, an extra ∂g/∂p per solve (3-5 %)
        "ipopt.print_level": o.print_level,
        "ipopt.sb": "yes",
        "ipopt.max_iter": o.max_iter,
        "ipopt.tol": o.tol,
    }
    if o.acceptable_tol is not None:
        opts["ipopt.acceptable_tol"] = o.acceptable_tol
    if o.acceptable_iter is not None:
        opts["ipopt.acceptable_iter"] = o.acceptable_iter
    if o.acceptable_obj_change_tol is not None:
        opts["ipopt.acceptable_obj_change_tol"] = o.acceptable_obj_change_tol
    if o.acceptable_constr_viol_tol is not None:
        opts["ipopt.acceptable_constr_viol_tol"] = o.acceptable_constr_viol_tol
    opts["ipopt.constr_viol_tol"] = o.constr_viol_tol
    if o.bound_relax_factor is not None:
        opts["ipopt.bound_relax_factor"] = o.bound_relax_factor
    opts["ipopt.mu_strategy"] = "adaptive"
    if o.linear_solver is not None:
        opts["ipopt.linear_solver"] = o.linear_solver
    if o.warm_start:
        opts.update({
            "ipopt.warm_start_init_point": "yes",
            "ipopt.warm_start_bound_push": 1e-9,
            "ipopt.warm_start_mult_bound_push": 1e-9,
            "ipopt.mu_init": 1e-4,
        })
    return opts


def lagrangian_hessian(nlp: dict, curved_rows: Sequence[int]) -> ca.Function:
    """The backend's Hessian of the Lagrangian of `nlp` ({"x", "p", "f", "g"}) with the curvature of the
    constraint rows `curved_rows` only: (x, p, λ_f, λ_g) -> triu ∇²ₓₓ(λ_f f + Σ_{i ∈ curved_rows} λ_g,i g_i),
    (n_x, n_x) upper triangle. The other rows enter IPOPT's Newton steps linearised (their exact Jacobian,
    no curvature): the solution is a KKT point of the same NLP, reached by inexact Newton steps. Their
    convergence is linear, and can stall when a left-out row's curvature (times its multiplier) outweighs
    the kept: min (x0 − 2)² + x0·x1² on the unit disc, the disc's curvature left out, ran IPOPT's 3000
    iterations without converging (with it: 5).

    CasADi's common-subexpression elimination (`cse`) is left off: it trims OPT2's Hessian from 271,851
    to 248,201 instructions but costs ~1.9 s per OPT2 build, for at most ~70 ms of evaluation saved per
    plan (paper benchmark, AMD EPYC, 2 workers: builds 21.4 -> 12.8 s in all with it off, OPT2's median
    solve 28.5 -> 29.2 ms)."""
    x, f = nlp["x"], nlp["f"]
    g = nlp.get("g", type(x)(0, 1))
    p = nlp.get("p", type(x)(0, 1))
    lam_f = type(x).sym("lam_f")
    lam_g = type(x).sym("lam_g", g.shape[0])
    rows = sorted(set(int(i) for i in curved_rows))
    if rows and not 0 <= rows[0] <= rows[-1] < g.shape[0]:
        raise ValueError(f"curved_rows must index the {g.shape[0]} constraints, got {rows[0]}..{rows[-1]}")
    lagrangian = lam_f * f + (ca.dot(lam_g[rows], g[rows]) if rows else 0)
    hess = ca.triu(ca.hessian(lagrangian, x)[0])
    return ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"],
                       ["triu_hess_gamma_x_x"], {"cse": False})


def build_solver(name: str, nlp: dict, options: SolverOptions | None = None,
                 curved_rows: Sequence[int] | None = None) -> ca.Function:
    """Build the solver of `nlp` ({"x", "p", "f", "g"} CasADi expressions) with `BACKEND`; `name` names
    the CasADi function (it shows in profiles and in `solver.name()`). `curved_rows`: the constraint rows
    whose curvature the Hessian of the Lagrangian includes (`lagrangian_hessian`; None: all, the exact
    Hessian). Evaluated from compiled C as `compiled.mode(options.compiled)` says (the library compiled
    when missing, or only used when cached; the interpreted solver otherwise or if that fails). A solver
    built before in this process from the same expressions and options is returned again
    (`nlp_cache.solver_key`)."""
    options = options or SolverOptions()
    opts = backend_options(options)
    mode = compiled.mode(options.compiled)
    key = nlp_cache.solver_key(name, BACKEND, nlp, opts, curved_rows, mode)
    solver = nlp_cache.built_solver(key)  # OPT2's expressions are the same for every object
    if solver is not None:
        return solver
    if curved_rows is not None:
        opts["hess_lag"] = lagrangian_hessian(nlp, curved_rows)
    if mode != "off":
        return nlp_cache.keep_solver(key, compiled.solver(name, nlp, BACKEND, opts,
                                                          compile_missing=mode == "compile"))
    return nlp_cache.keep_solver(key, ca.nlpsol(name, BACKEND, nlp, opts))



@dataclass(frozen=True)
class Bounds:
    """Bounds of an NLP: lbx ≤ x ≤ ubx, lbg ≤ g(x, p) ≤ ubg (±inf for none)."""

    lbx: NDArray[np.float64]
    """(n_x,) lower bounds of the decision variables."""
    ubx: NDArray[np.float64]
    """(n_x,) upper bounds of the decision variables."""
    lbg: NDArray[np.float64]
    """(n_g,) lower bounds of the constraints."""
    ubg: NDArray[np.float64]
    """(n_g,) upper bounds of the constraints."""

    def kwargs(self) -> dict[str, NDArray[np.float64]]:
        """The bounds as keyword arguments of `solve`."""
        return {"lbx": self.lbx, "ubx": self.ubx, "lbg": self.lbg, "ubg": self.ubg}


NO_WORSE_SLACK = 5e-6
"""How much a constraint held at its start value ("no worse") may give, m, so that the start is strictly
inside for the interior-point solver (`SelfCollisionConstraint.holds` allows 10 µm)."""


def no_worse(bound: float, start: ArrayLike) -> NDArray[np.float64]:
    """Lower bounds (m) of distance constraints that must reach `bound` but are held no worse than their
    start values `start` (m) where those are below it: min(bound, start − `NO_WORSE_SLACK`)."""
    return np.minimum(bound, np.asarray(start, dtype=float) - NO_WORSE_SLACK)


# ------------------------------------------------------------------------------------ solve, success
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
    """The backend's return_status, e.g. "Solve_Succeeded", or "exception: ..." if CasADi raised."""
    iterations: int
    """Backend iterations (-1 when unknown)."""
    time: float
    """Wall time of the call, s."""

    @property
    def success(self) -> bool:
        """The success test: the backend reports a (possibly acceptable) optimum."""
        return succeeded(self.status)


def succeeded(status: str) -> bool:
    """Whether a return status counts as a successful solve (one of `SUCCESS_STATUSES`)."""
    return status in SUCCESS_STATUSES


def solve(solver: ca.Function, *, x0, p, lbx, ubx, lbg, ubg, lam_x0=None, lam_g0=None) -> SolveResult:
    """Call a `build_solver` solver; return a `SolveResult` whatever happens (never raises on a failed
    solve)."""
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
    solve_log.record_call(solver.name(), elapsed, iterations, status)  # (only inside a recording)
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


class WarmStart:
    """The warm-start policy of a re-solved NLP: the multipliers of the last successful solve (with a
    finite solution) start the next one; a failed solve leaves them as they were.

        >>> warm = WarmStart()
        >>> res = warm.solve(solver, bounds, x0=x0, p=p)   # cold the first time, warm afterwards
        >>> warm.reset()                                     # e.g. before a new plan: reproducible plans
    """

    def __init__(self) -> None:
        self._lam: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    def reset(self) -> None:
        """Forget the multipliers: the next solve starts cold."""
        self._lam = None

    def saved(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The stored multipliers (λ_x, λ_g), or None (cold), for `restore`."""
        return self._lam

    def restore(self, saved: tuple[NDArray[np.float64], NDArray[np.float64]] | None) -> None:
        """Store the multipliers `saved` returned (the solves go on as from then)."""
        self._lam = saved

    @property
    def is_warm(self) -> bool:
        """Whether the next solve starts from stored multipliers."""
        return self._lam is not None

    def solve(self, solver: ca.Function, bounds: Bounds, *, x0, p) -> SolveResult:
        """`solve` with the stored multipliers (if any); keeps the new ones when the solve succeeded."""
        lam_x, lam_g = self._lam if self._lam is not None else (None, None)
        res = solve(solver, x0=x0, p=p, **bounds.kwargs(), lam_x0=lam_x, lam_g0=lam_g)
        if res.success and np.all(np.isfinite(res.x)):
            self._lam = (res.lam_x, res.lam_g)
        return res


# ------------------------------------------------------------------------------------ parameter layout
class ParamLayout:
    """The layout of an NLP's parameter vector p: named blocks with shapes, in order.

    Each block enters p column-major (CasADi's `vec`, numpy's ``order="F"``): `pack` is the one place
    where numeric values are put in that order, and `symbols` gives the CasADi symbols, one per block
    with the block's shape, so the NLP's expressions index blocks by name instead of by offset.

    Args:
        blocks: (name, shape) pairs in p's order; a shape is (n,) or (rows, cols).
    """

    def __init__(self, blocks: Sequence[tuple[str, tuple[int, ...]]]):
        shapes: dict[str, tuple[int, ...]] = {}
        for name, shape in blocks:
            shape = tuple(int(s) for s in shape)
            if name in shapes:
                raise ValueError(f"parameter block {name!r} appears twice")
            if len(shape) not in (1, 2) or min(shape) < 0:
                raise ValueError(f"parameter block {name!r}: shape {shape} is not (n,) or (rows, cols)")
            shapes[name] = shape
        self.shapes = shapes
        """Block name → shape, in p's order."""
        self.slices: dict[str, slice] = {}
        """Block name → its slice of p."""
        start = 0
        for name, shape in shapes.items():
            size = int(np.prod(shape))
            self.slices[name] = slice(start, start + size)
            start += size
        self.size = start
        """Length of p."""

    def symbols(self, kind: type = ca.SX) -> tuple[ca.SX, dict[str, ca.SX]]:
        """CasADi symbols of `kind` (ca.SX or ca.MX): the vector p (size,) and, per block, a symbol of
        the block's shape, named after it; p is their column-major concatenation."""
        blocks = {name: kind.sym(name, *shape) for name, shape in self.shapes.items()}
        return ca.vertcat(*[ca.vec(b) for b in blocks.values()]), blocks

    def pack(self, **values: ArrayLike) -> NDArray[np.float64]:
        """The numeric p (size,) of one value per block; each must have its block's shape exactly.

        Raises:
            ValueError: naming the block that is missing, unknown or of the wrong shape.
        """
        missing = [name for name in self.shapes if name not in values]
        unknown = [name for name in values if name not in self.shapes]
        if missing or unknown:
            raise ValueError(f"parameter blocks missing {missing}, unknown {unknown}; the layout has "
                             f"{list(self.shapes)}")
        parts = []
        for name, shape in self.shapes.items():
            value = np.asarray(values[name], dtype=float)
            if value.shape != shape:
                raise ValueError(f"parameter block {name!r}: expected shape {shape}, got {value.shape}")
            parts.append(value.ravel(order="F"))
        return np.concatenate(parts) if parts else np.zeros(0)

    def unpack(self, p: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """The blocks of a numeric p (size,), each with its shape (the inverse of `pack`)."""
        p = np.asarray(p, dtype=float).ravel()
        if p.size != self.size:
            raise ValueError(f"parameter vector has {p.size} entries, the layout {self.size}")
        return {name: p[self.slices[name]].reshape(shape, order="F") for name, shape in self.shapes.items()}


# ------------------------------------------------------------------------------ exact-offset correction
Offsets = TypeVar("Offsets")
Evaluation = TypeVar("Evaluation")


@dataclass(frozen=True)
class Correction(Generic[Evaluation]):
    """The outcome of `correct_offsets`."""

    x: NDArray[np.float64]
    """The last usable solution (the start point if no solve gave one)."""
    evaluation: Evaluation
    """`evaluate` at `x` (the start's evaluation if no solve gave a usable point)."""
    result: SolveResult | None
    """The last solve (None when no solve was made)."""
    converged: bool
    """`done` held at `x`."""
    usable: bool
    """False when the loop stopped at a solve without a usable point (`accept` returned None)."""
    solves: int
    """Number of solves."""
    iterations: int
    """Backend iterations over all solves."""
    solve_time: float
    """Wall time inside the solves, s."""

    @property
    def status(self) -> str:
        """The backend's return_status of the last solve, or "not_solved" when none was made."""
        return self.result.status if self.result is not None else "not_solved"


@dataclass(frozen=True)
class SolveStats:
    """What every NLP result reports about its solves, taken from its `Correction` (the NLPs' `*Result`s
    extend it)."""

    status: str
    """The backend's return_status of the last solve ("not_solved" when none was made)."""
    success: bool
    """True when the result satisfies the NLP's constraints with the exact geometry (whatever the
    backend's status)."""
    iterations: int
    """Backend iterations over all solves."""
    solve_time: float
    """Wall time inside the solves, s."""

    def record(self, kind: str) -> None:
        """Report this result to the active `solve_log.recording`s as one move of an NLP of `kind`."""
        solve_log.record_move(kind, self.solve_time, self.iterations, self.status, self.success)


def clipped_if_finite(bounds: Bounds) -> Callable[[SolveResult], NDArray[np.float64] | None]:
    """An `accept` for `correct_offsets`: the solution clipped to the variable bounds when it is finite,
    else None (whatever the status: the exact checks, not the solver, judge the point)."""

    def accept(res: SolveResult) -> NDArray[np.float64] | None:
        if not np.all(np.isfinite(res.x)):
            return None
        return np.clip(res.x, bounds.lbx, bounds.ubx)

    return accept


def correct_offsets(
    solve_with: Callable[[NDArray[np.float64], Offsets], SolveResult],
    evaluate: Callable[[NDArray[np.float64], Offsets], Evaluation],
    done: Callable[[Evaluation], bool],
    new_offsets: Callable[[NDArray[np.float64], Evaluation, Offsets], Offsets],
    *,
    offsets: Offsets,
    x: NDArray[np.float64],
    evaluation: Evaluation,
    max_solves: int,
    accept: Callable[[SolveResult], NDArray[np.float64] | None],
) -> Correction[Evaluation]:
    """The exact-offset correction loop shared by the NLPs.

    A smooth distance model s(x) stands in for the exact (non-smooth) mesh distance e(x) inside the NLP,
    with an offset δ (a parameter) in each distance constraint, s(x) + δ. After each solve the exact
    distances are evaluated at the solution and, unless they pass, new offsets (typically
    δ = e(x) − s(x) there) are computed and the NLP solved again, so that at a fixed point the constraint
    holds for the exact distance. One round:

    1. ``res = solve_with(x, offsets)`` (x: the last usable solution, or the start);
    2. ``x = accept(res)``: the usable point, or None to stop (e.g. a non-finite solution);
    3. ``evaluation = evaluate(x, offsets)`` (exact and smooth distances at x);
    4. stop if ``done(evaluation)``, else ``offsets = new_offsets(x, evaluation, offsets)``;

    at most `max_solves` rounds. `offsets` and `evaluation` are whatever the NLP needs (δ, local planes,
    a proximal centre, ...); `x` and `evaluation` are the start point and its evaluation.
    """
    res = None
    converged, usable = False, True
    solves, iterations, solve_time = 0, 0, 0.0
    for _ in range(max_solves):
        res = solve_with(x, offsets)
        solves += 1
        solve_time += res.time
        iterations += max(res.iterations, 0)
        x_new = accept(res)
        if x_new is None:
            usable = False
            break
        x = x_new
        evaluation = evaluate(x, offsets)
        if done(evaluation):
            converged = True
            break
        offsets = new_offsets(x, evaluation, offsets)
    return Correction(x=x, evaluation=evaluation, result=res, converged=converged, usable=usable,
                      solves=solves, iterations=iterations, solve_time=solve_time)
