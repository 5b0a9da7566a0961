"""Where an OPT1 / OPT2 solve's time goes: the NLP's functions against IPOPT's own work, and the floor
of IPOPT itself on a trivial NLP of the same size (issue 10's per-solve targets).

Plans one problem (default mustard_0, the paper's planner, both methods), records every solve the
planner makes (start, parameters, bounds, multipliers), then replays each one `--rounds` times on the
planner's own solver and reads CasADi's statistics: the time in the NLP's functions (objective,
constraints, their derivatives, the Hessian of the Lagrangian: ``t_wall_nlp_*``) and the rest (IPOPT's
linear algebra, its line search and barrier updates, CasADi's interface). A least-squares line
rest = a + b · iterations over the solves gives IPOPT's fixed cost per call (a) and per iteration (b).

The floor: for each NLP the same number of variables and constraints (f = ‖x − p‖², g = A x with a
dense A, the same bounds' shape), the same IPOPT options (`solver.backend_options`), solved from the
same kind of start (it takes more iterations than the planner's warm-started solves); its time per
iteration is what IPOPT costs when the functions cost next to nothing. "IPOPT alone at the median
iterations" (a + b · median iterations) is the time a solve would take with functions that cost nothing.

    python benchmarks/ipopt_floor.py [--problem mustard_0] [--rounds 3] [--out FILE]

Records the machine (`machine.machine_info`) and asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import casadi as ca
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def record_solves(problem: str) -> tuple[dict[str, ca.Function], list[tuple[str, dict]]]:
    """Plan `problem` with both methods; return the planner's solvers by name and every solve's
    arguments (name, kwargs) in order."""
    from regrasp_casadi import solver as solver_module
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem

    solvers: dict[str, ca.Function] = {}
    calls: list[tuple[str, dict]] = []
    solve = solver_module.solve

    def wrapped(solver, **kwargs):
        solvers[solver.name()] = solver
        calls.append((solver.name(), {k: np.array(v, dtype=float) for k, v in kwargs.items() if v is not None}))
        return solve(solver, **kwargs)

    solver_module.solve = wrapped
    try:
        p = RegraspProblem.load(HERE / "problems" / f"{problem}.yaml")
        for method in ("svd", "sd"):
            plan_regrasp(p.grasp0, p.grasp_goal, method=method, stability="none")
    finally:
        solver_module.solve = solve
    return solvers, calls


def replay(solver: ca.Function, kwargs: dict, rounds: int) -> tuple[float, float, int]:
    """(median wall s, its function time s, iterations) of `rounds` solves with `kwargs`."""
    rows = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        solver(**kwargs)
        wall = time.perf_counter() - t0
        stats = solver.stats()
        rows.append((wall, sum(v for k, v in stats.items() if k.startswith("t_wall_nlp")),
                     int(stats["iter_count"])))
    return sorted(rows)[len(rows) // 2]


def trivial_solver(n_x: int, n_g: int) -> ca.Function:
    """f = ‖x − p‖², g = A x (A dense, fixed seed) with the planner's IPOPT options."""
    from regrasp_casadi.solver import SolverOptions, backend_options

    x, p = ca.SX.sym("x", n_x), ca.SX.sym("p", n_x)
    A = np.random.default_rng(0).normal(size=(n_g, n_x))
    return ca.nlpsol("trivial", "ipopt", {"x": x, "p": p, "f": ca.sumsqr(x - p), "g": ca.mtimes(A, x)},
                     backend_options(SolverOptions()))


def summarise(name: str, rows: list[tuple[float, float, int]], floor: list[tuple[float, float, int]]) -> dict:
    wall, fun, it = (np.array(c, dtype=float) for c in zip(*rows, strict=True))
    rest = wall - fun
    a, b = np.linalg.lstsq(np.c_[np.ones_like(it), it], rest, rcond=None)[0]
    f_wall, _, f_it = (np.array(c, dtype=float) for c in zip(*floor, strict=True))
    return {"nlp": name, "solves": len(rows), "call_median_ms": 1e3 * float(np.median(wall)),
            "functions_share": float(fun.sum() / wall.sum()), "iterations_median": float(np.median(it)),
            "ipopt_fixed_ms": 1e3 * float(a), "ipopt_per_iteration_ms": 1e3 * float(b),
            "floor_call_median_ms": 1e3 * float(np.median(f_wall)),
            "floor_iterations_median": float(np.median(f_it)),
            "floor_per_iteration_ms": 1e3 * float(f_wall.sum() / f_it.sum()),
            "ipopt_at_median_iterations_ms": 1e3 * float(a + b * np.median(it))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default="mustard_0")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=pathlib.Path, default=HERE / "results" / "ipopt_floor.json")
    args = ap.parse_args(argv)
    from machine import machine_info

    solvers, calls = record_solves(args.problem)
    out = {"problem": args.problem, "rounds": args.rounds, "nlps": []}
    for name, solver in sorted(solvers.items()):
        mine = [kw for n, kw in calls if n == name]
        rows = [replay(solver, kw, args.rounds) for kw in mine]
        n_x, n_g = solver.size1_in("x0"), solver.size1_in("lbg")
        trivial, rng = trivial_solver(n_x, n_g), np.random.default_rng(1)
        floor = [replay(trivial, {"x0": np.zeros(n_x), "p": rng.normal(size=n_x), "lbx": -2.0, "ubx": 2.0,
                                  "lbg": -1.0, "ubg": 1.0}, args.rounds) for _ in mine]
        out["nlps"].append(summarise(name, rows, floor) | {"n_x": n_x, "n_g": n_g})
        s = out["nlps"][-1]
        print(f"{name}: {s['solves']} solves, {s['call_median_ms']:.2f} ms median ({s['iterations_median']:.0f} "
              f"iterations), functions {100 * s['functions_share']:.0f} %, IPOPT {s['ipopt_fixed_ms']:.2f} ms "
              f"+ {s['ipopt_per_iteration_ms']:.2f} ms/iteration; trivial NLP of {n_x} x {n_g}: "
              f"{s['floor_call_median_ms']:.2f} ms ({s['floor_iterations_median']:.0f} iterations, "
              f"{s['floor_per_iteration_ms']:.2f} ms/iteration); IPOPT alone at the median iterations: "
              f"{s['ipopt_at_median_iterations_ms']:.2f} ms", flush=True)
    out["machine"] = machine_info()
    args.out.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
