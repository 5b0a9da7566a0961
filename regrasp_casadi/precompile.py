"""Fill the compiled-NLP cache for a hand: the planner's NLPs as C libraries, once per hand and machine.

The planner solves two kinds of NLP (`finger_gait.FingerGaitNLP`, OPT1, one per finger, and
`in_grasp.InGraspNLP`, OPT2, one per method). Their object data are parameters, so one compiled library
of each serves every object: OPT1 has two variants only, for an object of one convex piece and for one of
two or more (the tip's local plane set holds that many pieces). Compiling them takes minutes (gcc on the
Hessians); afterwards every solve is 2-3x faster (`compiled`, mode "cached": a cached library is used
unless ``$REGRASP_COMPILE=0``).

    >>> records = precompile("allegro_right", jobs=2)      # or: regrasp compile --jobs 2
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

from regrasp_casadi.compiled import ENV_VAR
from regrasp_casadi.errors import RegraspError

__all__ = ["CompiledNLP", "planner_nlps", "precompile"]


@dataclass(frozen=True)
class CompiledNLP:
    """One NLP of `precompile`: its name, whether it was compiled now (else loaded from the cache, or, when
    compiling failed, interpreted: `path` empty) and the seconds it took."""

    name: str
    compiled: bool
    seconds: float
    path: str


def planner_nlps(hand) -> list[tuple[str, str, str]]:
    """The NLPs `plan_regrasp` builds for `hand` with the default options, as (name, kind, arg) tasks:
    OPT1 for every finger on a one-piece and on a two-piece object, OPT2 for both methods."""
    tasks = [(f"OPT2 {m}", "in_grasp", m) for m in ("svd", "sd")]
    for pieces in ("one", "two"):
        tasks += [(f"OPT1 {f} ({pieces}-piece objects)", f"finger_gait_{pieces}", f) for f in hand.fingers]
    return tasks


def _build(hand_name: str, kind: str, arg: str) -> CompiledNLP:
    """Build one task of `planner_nlps` in this process with compiling on (a worker's job)."""
    os.environ[ENV_VAR] = "1"
    from regrasp_casadi import compiled
    from regrasp_casadi.finger_gait import FingerGaitNLP
    from regrasp_casadi.hand_model import load_hand
    from regrasp_casadi.in_grasp import InGraspNLP
    from regrasp_casadi.nlp_cache import clear_built_solvers
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.planner import PlannerOptions

    hand = load_hand(hand_name)
    clear_built_solvers()
    options = PlannerOptions()
    before = len(compiled.build_records())
    t0 = time.perf_counter()
    if kind == "in_grasp":
        InGraspNLP(hand, ObjectModel.box(), arg, options.in_grasp)
    else:  # the box: one piece; the flat tool: two
        obj = ObjectModel.box() if kind == "finger_gait_one" else ObjectModel.flat_tool()
        FingerGaitNLP(hand, obj, arg, options.finger_gait)
    seconds = time.perf_counter() - t0
    records = compiled.build_records()[before:]
    if not records:  # compiling failed (warned): interpreted
        return CompiledNLP(arg, False, seconds, "")
    return CompiledNLP(records[-1].name, records[-1].compiled, seconds, records[-1].path)


def precompile(hand_name: str = "allegro_right", jobs: int = 1,
               report: Callable[[str], None] | None = None) -> list[CompiledNLP]:
    """Compile (or find in the cache) every NLP of `planner_nlps` for the hand `hand_name` (a shipped
    model's name, a model folder or a URDF file: `hand_model.load_hand`), `jobs` at a time in worker
    processes; `report(line)` gets a first line, then one per NLP as it finishes (default: stderr).
    Returns them in the order they finished.

    Raises:
        RegraspError: no C compiler on the PATH; `ModelError` (one) for a hand that does not load.
    """
    from regrasp_casadi.compiled import find_compiler, library_path
    from regrasp_casadi.hand_model import load_hand

    if find_compiler() is None:
        raise RegraspError("no C compiler (cc or gcc) on the PATH: install one (e.g. Debian's gcc) to "
                           "compile the NLPs; plans are solved interpreted meanwhile")
    say = report or (lambda line: print(line, file=sys.stderr, flush=True))
    tasks = planner_nlps(load_hand(hand_name))  # an unknown or broken hand fails here, before any worker
    say(f"compiling {len(tasks)} NLPs of the planner for {hand_name} into {library_path('').parent} "
        f"({jobs} at a time; minutes per NLP, once per hand and machine)")
    out: list[CompiledNLP] = []
    method = "forkserver" if sys.platform.startswith("linux") else "spawn"
    with cf.ProcessPoolExecutor(max_workers=max(1, int(jobs)),
                                mp_context=multiprocessing.get_context(method)) as pool:
        futures = {pool.submit(_build, hand_name, kind, arg): name for name, kind, arg in tasks}
        for k, future in enumerate(cf.as_completed(futures), 1):
            res = future.result()
            out.append(res)
            how = "compiled" if res.compiled else ("from the cache" if res.path else "interpreted (failed)")
            say(f"[{k}/{len(tasks)}] {futures[future]}: {how} in {res.seconds:.1f} s")
    return out
