"""The `regrasp` command line: plan, verify, view, generate grasps, benchmark and demo.

    regrasp plan PROBLEM.yaml --method svd --out plan.json [--html replay.html] [--view] [--max-iters N]
                              [--restarts N]
    regrasp verify plan.json [--all] [--zeta MM] [--pose-tol-position MM] [--pose-tol-rotation DEG] ...
    regrasp view plan.json [--html replay.html] [--png shot.png [--at SECONDS]] [--speed X]
    regrasp simulate plan.json [--gravity X Y Z] [--html sim.html] [--json report.json]
    regrasp export plan.json --csv traj.csv [--dt 0.01]
    regrasp grasps MESH_OR_PROBLEM [--hand MODEL] [--n N] [--seed S] [--out problems/x.yaml]
    regrasp bench [--backend process|ray|serial] [--address ADDR] [ARGS ...]
                                      (runs benchmarks/paper_objects.py)
    regrasp compile [--hand MODEL] [--jobs N]   (the planner's NLPs to C, once per hand: faster solves)
    regrasp demo [--out-dir DIR] [--method svd] [--speed X]

Exit codes:
    0  success (for `plan` / `demo`: the plan converged and `verify` accepts it; for `verify`: verified)
    1  the plan was made (or read) but did not converge or did not pass `verify`
    2  bad input: unreadable or invalid problem / plan / mesh file, bad arguments (a `RegraspError`)
    3  unexpected internal error (run again with --verbose for the traceback)
    130 interrupted (Ctrl-C)
    141 stdout was closed by its reader (`regrasp verify plan.json | head -1`): output stops quietly

Errors are printed as one line, ``regrasp: error: <message>``, on stderr; `--verbose` adds the traceback
and INFO logging. This is the only module of the package (with the examples and its `cli_*` helpers)
that prints.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
import runpy
import signal
import sys
import time
import traceback
from pathlib import Path
from typing import TYPE_CHECKING

from regrasp_casadi.cli_compile import add_compile_parser
from regrasp_casadi.cli_plan import add_planner_arguments, restart_line, run_plan
from regrasp_casadi.cli_simulate import add_simulate_parser
from regrasp_casadi.cli_tools import (
    HelpFormatter,
    Parser,
    check_host,
    check_output,
    finite_float,
    finite_positive_float,
    found_progress,
    non_negative_float,
    non_negative_int,
    plan_stability,
    positive_float,
    positive_int,
    progress_bar,
    progress_enabled,
)
from regrasp_casadi.cli_tools import UserError as _UserError
from regrasp_casadi.cli_tools import print_error as _err
from regrasp_casadi.resources import builtin_problem

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import Plan

__all__ = ["main", "EXIT_OK", "EXIT_FAILED", "EXIT_BAD_INPUT", "EXIT_INTERNAL"]

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 128 + 13   # as a process killed by SIGPIPE: the reader of stdout went away

DEMO_PROBLEM = builtin_problem("box_rotate")   # package data (regrasp_casadi.problems)
# the benchmark scripts are not package data: `regrasp bench` needs a source checkout
BENCH_SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "paper_objects.py"

_EPILOG = """exit codes:
  0    success (plan/demo: converged and verified; verify: plan verified)
  1    plan made or read, but not converged or not verified
  2    bad input (unreadable or invalid problem, plan or mesh file; bad arguments)
  3    unexpected internal error (use --verbose for the traceback)
  130  interrupted
  141  stdout closed by its reader (e.g. `regrasp verify plan.json | head -1`)
"""


# ---------------------------------------------------------------------------------------------- helpers
def _verify(plan: Plan, hand=None, obj=None, show_progress: bool = False, **tolerances: float):
    from regrasp_casadi.verify import verify

    with progress_bar(f"verifying {len(plan.steps)} steps", show_progress):
        return verify(plan, hand, obj, **tolerances)


def _finish_plan(plan: Plan, hand, obj, out: Path | None, html: Path | None, elapsed: float,
                 show_progress: bool = False, *, speed: float | None = None) -> int:
    """Verify, save, write the replay, print the summary; returns the exit code."""
    report = _verify(plan, hand, obj, show_progress)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        plan.save(out)
    if html is not None:
        from regrasp_casadi.viewer import write_html

        write_html(plan, html, hand=hand, obj=obj, **_speed(speed))
    err, (dp, dr) = plan.final_error, plan.final_pose_error
    print(f"plan: {plan.status} after {plan.iterations} iterations, {len(plan.steps)} steps "
          f"({plan.step_counts()}), method {plan.method}")
    if plan.status != "converged" and plan.status_detail:
        print(f"  ({' '.join(plan.status_detail.split())})")
    restarts = restart_line(plan)
    if restarts:
        print(f"  {restarts}")
    print(f"final average contact error: {err * 1e3:.2f} mm; object {dp * 1e3:.2f} mm / "
          f"{math.degrees(dr):.2f}° from the desired pose; planning time {elapsed:.2f} s\n"
          f"verify: {'OK' if report.ok else f'FAILED ({len(report.violations)} violations)'}")
    for v in report.violations[:3]:
        print(f"  step {v.step}: {v.check} [{v.who}]: {v.message}")
    written = [str(p) for p in (out, html) if p is not None]
    if written:
        print("wrote " + ", ".join(written))
    ok = plan.status == "converged" and report.ok
    return EXIT_OK if ok else EXIT_INTERRUPTED if plan.status == "interrupted" else EXIT_FAILED


def _load_plan(path: str) -> Plan:
    from regrasp_casadi.errors import PlanFormatError
    from regrasp_casadi.plan import Plan

    p = Path(path)
    if not p.is_file():
        raise _UserError(f"{path}: no such plan file")
    try:
        return Plan.load(p)
    except PlanFormatError as e:
        msg = str(e)
        raise PlanFormatError(msg if path in msg else f"{path}: {msg}") from None
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise PlanFormatError(f"{path}: cannot read plan file: {e}") from None


def _speed(speed: float | None) -> dict[str, float]:
    """`--speed` as a keyword of the viewer's functions (nothing: their default)."""
    return {} if speed is None else {"speed": speed}


def _view_live(plan: Plan, hand=None, obj=None, host: str = "127.0.0.1", speed: float | None = None) -> int:
    from regrasp_casadi.viewer import show

    def stop(signum, frame):  # SIGTERM ends like Ctrl-C, so that the Meshcat server is shut down
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        url = show(plan, hand=hand, obj=obj, host=host, **_speed(speed))
        print(f"viewer: {url}  (Ctrl-C to stop)", flush=True)
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        print("", file=sys.stderr)
    finally:
        signal.signal(signal.SIGTERM, previous)
        from regrasp_casadi.viewer import stop_live_viewers

        stop_live_viewers()
    return EXIT_OK


# ---------------------------------------------------------------------------------------------- commands
def cmd_plan(args: argparse.Namespace) -> int:
    from regrasp_casadi.problem import RegraspProblem

    out, html = check_output("--out", args.out), check_output("--html", args.html)
    if args.view:
        check_host(args.host)
    plan_stability(args.stability, args.gravity)  # bad flags fail before the problem loads
    problem = RegraspProblem.load(args.problem)
    stability, gravity = plan_stability(args.stability, args.gravity, problem.gravity)
    t0 = time.perf_counter()
    progress = progress_enabled(args)
    plan = run_plan(problem, args.method, args.max_iters, progress, stability, gravity, args.restarts)
    code = _finish_plan(plan, problem.hand, problem.obj, out, html, time.perf_counter() - t0, progress,
                        speed=args.speed)
    if args.view:
        _view_live(plan, problem.hand, problem.obj, args.host, args.speed)
    return code


_VERIFY_TOLERANCES_MM = ("zeta", "eta", "surface_tol", "max_slip", "min_clearance", "pose_tol_position")
"""`regrasp verify` flags (mm) passed to `verify(...)` as keyword arguments (m) when given."""


def cmd_verify(args: argparse.Namespace) -> int:
    plan = _load_plan(args.plan)
    tolerances = {k: getattr(args, k) * 1e-3 for k in _VERIFY_TOLERANCES_MM if getattr(args, k) is not None}
    if args.pose_tol_rotation is not None:
        tolerances["pose_tol_rotation"] = math.radians(args.pose_tol_rotation)
    report = _verify(plan, show_progress=progress_enabled(args), **tolerances)
    print(report.summary(max_violations=len(report.violations) if args.all else 20))
    return EXIT_OK if report.ok else EXIT_FAILED


def cmd_view(args: argparse.Namespace) -> int:
    check_output("--html", args.html)
    check_output("--png", args.png)
    if not (args.html or args.png):
        check_host(args.host)
    plan = _load_plan(args.plan)
    if args.html or args.png:
        import tempfile

        from regrasp_casadi.viewer import step_times, write_html

        with tempfile.TemporaryDirectory() as tmp:
            path = write_html(plan, args.html or Path(tmp) / "replay.html", **_speed(args.speed))
            if args.html:
                print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")
            if args.png:
                from regrasp_casadi.screenshot import screenshot

                end = float(step_times(plan, **_speed(args.speed))[-1])
                seconds = args.at if args.at is not None else end + 1.0  # the end
                png = screenshot(path, args.png, seconds=seconds)
                print(f"wrote {png} (the replay at {seconds:.1f} s)")
        return EXIT_OK
    return _view_live(plan, host=args.host, speed=args.speed)


def cmd_export(args: argparse.Namespace) -> int:
    """Write the plan's joint trajectory, sampled every --dt s, as CSV: header `t,<joint names>`, then one
    row per sample (s, rad), the motion `Plan.sample` gives (paths, else linear between the steps)."""
    from regrasp_casadi.files import atomic_write_text
    from regrasp_casadi.hand import Hand

    out = check_output("--csv", args.csv)
    plan = _load_plan(args.plan)
    if not plan.steps:
        raise _UserError(f"{args.plan}: the plan has no steps, so no motion")
    names = Hand.from_spec(plan.hand_spec).joint_names
    t, q, _ = plan.sample(args.dt)
    if q.shape[1] != len(names):
        raise _UserError(f"{args.plan}: the steps have {q.shape[1]} joints, the hand {len(names)}")
    rows = [",".join(["t", *names])]
    rows += [",".join(format(v, ".10g") for v in (ti, *qi)) for ti, qi in zip(t, q, strict=True)]
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out, "\n".join(rows) + "\n")
    print(f"wrote {out}: {len(t)} samples every {args.dt:g} s ({t[-1]:.2f} s), {len(names)} joints")
    unpathed = sum(s.path is None for s in plan.steps[1:])
    flagged = sum(s.path is not None and not s.path.ok for s in plan.steps[1:])
    if unpathed:
        print(f"note: {unpathed} steps have no path (a plan of schema version 1 or made without "
              "trajectories): they move linearly in joint space between the steps")
    if flagged:
        print(f"warning: {flagged} paths did not pass the planner's own checks (see `regrasp verify`)")
    return EXIT_OK


def cmd_grasps(args: argparse.Namespace) -> int:
    try:
        from regrasp_casadi import grasp_gen
    except ImportError as e:
        raise _UserError(f"grasp generation is not available (regrasp_casadi.grasp_gen: {e})") from None
    out = check_output("--out", args.out)
    progress = progress_enabled(args)
    src = Path(args.source)
    if src.suffix.lower() in (".yaml", ".yml"):
        from regrasp_casadi.problem import RegraspProblem

        with progress_bar(f"loading {src.name}", progress):
            problem = RegraspProblem.load(src)
        hand, obj = problem.hand, problem.obj
    else:
        from regrasp_casadi.objects import ObjectModel

        if not src.is_file():
            raise _UserError(f"{src}: no such mesh or problem file")
        with progress_bar(f"loading {src.name} (convex decomposition)", progress):
            obj = ObjectModel.from_mesh(src, scale=args.scale)
            from regrasp_casadi.hand_model import load_hand

            hand = load_hand(args.hand)
    if out is not None:
        from regrasp_casadi.problem import RegraspProblem

        with progress_bar("regrasp pair", progress, total=1, unit="pair") as bar:
            (g0, gg), = grasp_gen.generate_regrasp_pairs(hand, obj, 1, seed=args.seed,
                                                         progress=found_progress(bar))
        out.parent.mkdir(parents=True, exist_ok=True)
        problem = RegraspProblem(out.stem, f"generated by `regrasp grasps` (seed {args.seed})", None,
                                 hand, obj, g0, gg, {})
        problem.save(out)
        print(f"wrote regrasp problem {out} (object {obj.name}, seed {args.seed})")
        return EXIT_OK
    with progress_bar("grasps", progress, total=args.n, unit="grasp") as bar:
        grasps = grasp_gen.generate_grasps(hand, obj, n=args.n, seed=args.seed,
                                           progress=found_progress(bar))
    for k, g in enumerate(grasps):
        t = g.T_palm_object[:3, 3] * 1e3
        q = grasp_gen.grasp_quality(g)
        print(f"grasp {k}: object at ({t[0]:.1f}, {t[1]:.1f}, {t[2]:.1f}) mm in the palm frame, "
              f"force-closure quality {q:.4f}")
    return EXIT_OK


def cmd_bench(args: argparse.Namespace) -> int:
    if not BENCH_SCRIPT.is_file():
        raise _UserError(f"{BENCH_SCRIPT}: benchmark script not found (needs a source checkout)")
    script_args = list(args.bench_args)
    # --backend/--address reach the script with the other arguments; when they were parsed here (the
    # parser used directly), they are passed on
    for flag, value in (("--backend", getattr(args, "backend", None)),
                        ("--address", getattr(args, "address", None))):
        if value is not None and flag not in script_args:
            script_args += [flag, value]
    argv0 = sys.argv
    sys.argv = [str(BENCH_SCRIPT), *script_args]
    try:
        runpy.run_path(str(BENCH_SCRIPT), run_name="__main__")
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else EXIT_FAILED)
    finally:
        sys.argv = argv0
    return EXIT_OK


def _demo_problem():
    """The built-in problem (problems/box_rotate.yaml), or one generated in memory if it is missing."""
    from regrasp_casadi.problem import RegraspProblem

    if DEMO_PROBLEM.is_file():
        return RegraspProblem.load(DEMO_PROBLEM)
    from regrasp_casadi.grasp_gen import generate_regrasp_pairs
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel

    logging.getLogger(__name__).info("%s missing: generating a box regrasp problem", DEMO_PROBLEM)
    hand, obj = Hand.default(), ObjectModel.box((0.06, 0.06, 0.12))
    (g0, gg), = generate_regrasp_pairs(hand, obj, 1, seed=0)
    return RegraspProblem("box_generated", "generated in memory by `regrasp demo`", None, hand, obj,
                          g0, gg, {})


def cmd_demo(args: argparse.Namespace) -> int:
    out_dir = check_output("--out-dir", args.out_dir, folder=True)
    problem = _demo_problem()
    out_dir.mkdir(parents=True, exist_ok=True)
    print(f"demo: regrasp of {problem.obj.name!r} ({problem.name}) with the {args.method} method, "
          f"stability {args.stability!r}")
    t0 = time.perf_counter()
    progress = progress_enabled(args)
    plan = run_plan(problem, args.method, None, progress, args.stability)
    code = _finish_plan(plan, problem.hand, problem.obj, out_dir / "plan.json", out_dir / "replay.html",
                        time.perf_counter() - t0, progress, speed=args.speed)
    print(f"open {out_dir / 'replay.html'} in a browser to watch the regrasp")
    return code


# ---------------------------------------------------------------------------------------------- parser
def _add_host(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                        help="address the live viewer listens on; 127.0.0.1 is this machine only, "
                             "0.0.0.0 opens it to the network")


def _add_speed(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--speed", type=finite_positive_float, metavar="X",
                        help="replay speed: plan seconds of motion per replay second (default: 1, the "
                             "plan's own time; each step at least 0.3 s)")


def _add_verify_arguments(sp: argparse.ArgumentParser) -> None:
    """`regrasp verify PLAN.json [--all]` and verify's tolerances in mm (`_VERIFY_TOLERANCES_MM`)."""
    sp.add_argument("plan", metavar="PLAN.json", help="plan file (JSON)")
    sp.add_argument("--all", action="store_true", help="list every violation (default: the first 20)")
    sp.description = (f"{sp.description}.\nverify judges with its own tolerances (the flags below); the "
                      "options recorded in the plan\n(its zeta, eta, ...) are reported, never obeyed.")
    judged = "(default: verify's own)"
    sp.add_argument("--zeta", type=finite_positive_float, metavar="MM",
                    help=f"largest final contact error a 'converged' plan may have, mm {judged}")
    sp.add_argument("--pose-tol-position", type=finite_positive_float, metavar="MM",
                    help=f"largest final object position error a 'converged' plan may have, mm {judged}")
    sp.add_argument("--pose-tol-rotation", type=finite_positive_float, metavar="DEG",
                    help=f"largest final object rotation error a 'converged' plan may have, deg {judged}")
    sp.add_argument("--eta", type=finite_positive_float, metavar="MM",
                    help=f"gait step bound on a fingertip, mm {judged}")
    sp.add_argument("--surface-tol", type=finite_positive_float, metavar="MM",
                    help=f"allowed fingertip distance from the surface, mm {judged}")
    sp.add_argument("--max-slip", type=finite_positive_float, metavar="MM",
                    help=f"allowed contact slip during reposing, mm {judged}")
    sp.add_argument("--min-clearance", type=finite_float, metavar="MM",
                    help=f"required clearance of the non-tip collision spheres, mm {judged}")
    sp.set_defaults(func=cmd_verify)


def _add_view_parser(add) -> None:
    """The `view` subcommand (``add(name, help)`` makes a subparser)."""
    sp = add("view", "replay a plan: live viewer on localhost, or a self-contained HTML file")
    sp.add_argument("plan", metavar="PLAN.json", help="plan file (JSON)")
    sp.add_argument("--html", metavar="REPLAY.html", help="write the HTML replay and exit")
    sp.add_argument("--png", metavar="SHOT.png",
                    help="write a screenshot of the replay (needs chromium) and exit")
    sp.add_argument("--at", type=non_negative_float, metavar="SECONDS",
                    help="replay time of the screenshot, s (default: the end)")
    _add_host(sp)
    _add_speed(sp)
    sp.set_defaults(func=cmd_view)


def _add_export_parser(add) -> None:
    """The `export` subcommand (``add(name, help)`` makes a subparser)."""
    sp = add("export", "write a plan's joint trajectory (time stamps and joint angles) as CSV for a robot "
                       "controller")
    sp.add_argument("plan", metavar="PLAN.json", help="plan file (JSON)")
    sp.add_argument("--csv", required=True, metavar="TRAJ.csv",
                    help="CSV file to write (t, one column per joint)")
    sp.add_argument("--dt", type=positive_float, default=0.01, metavar="SECONDS",
                    help="sampling period, s (100 Hz by default)")
    sp.set_defaults(func=cmd_export)


def _add_bench_parser(add) -> None:
    """The `bench` subcommand (its flags are documented here; `main` passes everything to the script)."""
    sp = add("bench", "run the paper-objects benchmark (benchmarks/paper_objects.py); every argument "
                      "after `bench` goes to the script (`regrasp bench -- --help` for its help)")
    sp.add_argument("--backend", choices=("process", "ray", "serial"),
                    help="how the plans run (regrasp_casadi.batch.plan_many): a local process pool "
                         "(default), Ray actors (the 'ray' extra), or one after the other")
    sp.add_argument("--address", metavar="ADDR",
                    help="with --backend ray: a running Ray cluster (default: start a local one)")
    sp.add_argument("bench_args", nargs="*", metavar="ARGS", help="arguments passed to the benchmark script")
    sp.set_defaults(func=cmd_bench)


def build_parser() -> argparse.ArgumentParser:
    """The `regrasp` argument parser (one subparser per command)."""
    from regrasp_casadi import __version__
    from regrasp_casadi.hand_model import DEFAULT_MODEL

    # --verbose is accepted before and after the command; the subcommands' copy must not reset it
    common = Parser(add_help=False)
    common.add_argument("--verbose", "-v", action="store_true", default=argparse.SUPPRESS,
                        help="INFO logging and full tracebacks on errors")
    common.add_argument("--quiet", "-q", action="store_true", default=argparse.SUPPRESS,
                        help="no progress bars (they are only drawn when stderr is a terminal)")
    p = Parser(
        prog="regrasp", epilog=_EPILOG,
        formatter_class=HelpFormatter,
        description="Geometric in-hand regrasp planning (Sundaralingam & Hermans, ICRA 2018) for the "
                    "Allegro hand: plan, verify and replay regrasps.")
    p.add_argument("--verbose", "-v", action="store_true", help="INFO logging and full tracebacks on errors")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress bars (they are only drawn when stderr is a terminal)")
    p.add_argument("--version", action="version", version=f"regrasp {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add(name: str, help_: str) -> argparse.ArgumentParser:
        return sub.add_parser(name, parents=[common], help=help_, description=help_, epilog=_EPILOG,
                              formatter_class=HelpFormatter)

    sp = add("plan", "plan a regrasp for a problem file, verify it, save it (and its HTML replay)")
    sp.add_argument("problem", metavar="PROBLEM.yaml", help="regrasp problem file (YAML)")
    add_planner_arguments(sp)
    sp.add_argument("--out", default="plan.json", metavar="PLAN.json", help="plan file to write")
    sp.add_argument("--html", metavar="REPLAY.html", help="also write a self-contained HTML replay")
    sp.add_argument("--view", action="store_true", help="open the live viewer after planning")
    _add_host(sp)
    _add_speed(sp)
    sp.add_argument("--no-progress", action="store_true", help="no progress bar")
    sp.set_defaults(func=cmd_plan)

    _add_verify_arguments(add("verify", "check a plan file with exact geometry and print the report"))

    _add_view_parser(add)
    add_simulate_parser(add, load_plan=_load_plan)
    _add_export_parser(add)

    sp = add("grasps", "generate precision grasps on a mesh (or a problem's object)")
    sp.add_argument("source", metavar="MESH_OR_PROBLEM", help="mesh file (.obj, .stl, ...) or problem .yaml")
    sp.add_argument("--hand", default=DEFAULT_MODEL, metavar="MODEL",
                    help="hand for a mesh: a shipped model name, a model folder (with hand.yaml) or a URDF "
                         f"file (default: {DEFAULT_MODEL}); a problem file names its own hand")
    sp.add_argument("--n", type=positive_int, default=1, metavar="N", help="number of grasps to generate")
    sp.add_argument("--seed", type=non_negative_int, default=0, metavar="S", help="random seed")
    sp.add_argument("--scale", type=positive_float, default=1.0, help="mesh scale to metres")
    sp.add_argument("--out", metavar="PROBLEM.yaml",
                    help="write a regrasp problem (a generated initial/desired grasp pair) to this file")
    sp.set_defaults(func=cmd_grasps)

    _add_bench_parser(add)
    add_compile_parser(add, DEFAULT_MODEL)

    sp = add("demo", "plan, verify and replay a regrasp on the built-in box problem")
    sp.add_argument("--out-dir", default=".", metavar="DIR",
                    help="folder for plan.json and replay.html (default: the current directory)")
    sp.add_argument("--method", choices=("svd", "sd"), default="svd", help="in-grasp objective")
    sp.add_argument("--stability", choices=("force_closure", "gravity", "none"), default="none",
                    help="certificate every step must have; the demo runs the paper's planner (none): the "
                         "certified one (force_closure) stalls on this problem, see the README's limitations")
    _add_speed(sp)
    sp.add_argument("--no-progress", action="store_true", help="no progress bar")
    sp.set_defaults(func=cmd_demo)
    return p


def _stdout_closed() -> int:
    """The reader of stdout went away (`regrasp verify plan.json | head -1`): stop quietly, as a
    process killed by SIGPIPE would; what is left in stdout's buffer goes to /dev/null."""
    with contextlib.suppress(AttributeError, OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    return EXIT_BROKEN_PIPE


def main(argv: list[str] | None = None) -> int:
    """Run `regrasp` with `argv` (default `sys.argv[1:]`); returns the exit code (see the module doc)."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    bench_args: list[str] | None = None
    first = next((i for i, a in enumerate(argv) if not a.startswith("-")), None)
    if first is not None and argv[first] == "bench":   # pass everything after `bench` to the script
        rest = argv[first + 1:]
        if rest[:1] == ["--"]:
            bench_args, argv = rest[1:], argv[:first + 1]
        elif not {"-h", "--help"} & set(rest):
            bench_args, argv = rest, argv[:first + 1]
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:   # --help, --version, usage errors (argparse already printed)
        return e.code if isinstance(e.code, int) else EXIT_BAD_INPUT
    if bench_args is not None:
        args.bench_args = bench_args
    verbose = bool(getattr(args, "verbose", False))
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    from regrasp_casadi.errors import RegraspError

    try:
        code = int(args.func(args))
        sys.stdout.flush()   # a closed pipe shows here, not at exit
        return code
    except BrokenPipeError:
        return _stdout_closed()
    except KeyboardInterrupt:
        _err("interrupted")
        return EXIT_INTERRUPTED
    except (RegraspError, _UserError) as e:
        if verbose:
            traceback.print_exc()
        _err(" ".join(str(e).split()) or type(e).__name__)
        return EXIT_BAD_INPUT
    except Exception as e:  # noqa: BLE001 - the CLI's last line of defence, reported as exit code 3
        if verbose:
            traceback.print_exc()
        _err(f"internal error: {type(e).__name__}: {' '.join(str(e).split())} (use --verbose for details)")
        return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
