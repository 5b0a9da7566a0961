"""Per-solve statistics: every backend call and every NLP move, recorded while a `recording` is active.

`solver.solve` reports each backend (IPOPT) call — NLP name, wall time, iterations, status — and the NLPs
report each move they return (`record_move`: its total time and iterations over the corrections and
retries, and whether the exact checks accepted it). The benchmarks use `summary` for per-solve medians,
iteration percentiles and the share of time spent on rejected moves. Nothing is recorded (and nothing
costs) unless a `recording` is active. No CasADi here.

    >>> with recording() as log:
    ...     plan = plan_regrasp(grasp0, grasp_goal)
    >>> log.summary()["opt2"]["call_median_ms"]
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

__all__ = ["SolveRecord", "SolveLog", "recording", "record_call", "record_move", "nlp_kind", "summarise"]


@dataclass(frozen=True)
class SolveRecord:
    """One backend call, or one move of an NLP (all its calls)."""

    kind: str
    """"opt1" (finger gait), "opt2" (in-grasp) or the NLP's name (`nlp_kind`)."""
    time: float
    """Wall time, s."""
    iterations: int
    """Backend iterations (−1: unknown)."""
    status: str
    """The backend's return status (of the last call, for a move)."""
    accepted: bool | None = None
    """Moves: the NLP's exact checks accepted the result; calls: None."""


@dataclass
class SolveLog:
    """The records of one `recording`."""

    calls: list[SolveRecord] = field(default_factory=list)
    """Every backend call, in order."""
    moves: list[SolveRecord] = field(default_factory=list)
    """Every move an NLP returned (`record_move`), in order."""

    def summary(self) -> dict[str, dict[str, float]]:
        """`summarise` of these records."""
        return summarise(self.calls, self.moves)


_ACTIVE: list[SolveLog] = []


@contextmanager
def recording() -> Iterator[SolveLog]:
    """Record the solves made inside the block into a new `SolveLog` (nested recordings all record)."""
    log = SolveLog()
    _ACTIVE.append(log)
    try:
        yield log
    finally:
        _ACTIVE.remove(log)


def nlp_kind(name: str) -> str:
    """"opt1" for a finger-gait NLP's name, "opt2" for an in-grasp one, else the name itself."""
    if name.startswith("finger_gait"):
        return "opt1"
    if name.startswith("in_grasp"):
        return "opt2"
    return name


def record_call(name: str, time: float, iterations: int, status: str) -> None:
    """Record one backend call of the NLP named `name` (called by `solver.solve`)."""
    if _ACTIVE:
        rec = SolveRecord(nlp_kind(name), float(time), int(iterations), str(status))
        for log in _ACTIVE:
            log.calls.append(rec)


def record_move(kind: str, time: float, iterations: int, status: str, accepted: bool) -> None:
    """Record one move an NLP returns (`kind` "opt1" / "opt2"; time s over all its calls)."""
    if _ACTIVE:
        rec = SolveRecord(kind, float(time), int(iterations), str(status), bool(accepted))
        for log in _ACTIVE:
            log.moves.append(rec)


def _pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def summarise(calls: list[SolveRecord], moves: list[SolveRecord]) -> dict[str, dict[str, float]]:
    """Per kind ("opt1", "opt2", ...): calls, call time median / p95 / total (ms, ms, s), iterations per
    call median / p95 / max, moves, rejected moves, their time (s) and its share of the moves' time."""
    out: dict[str, dict[str, float]] = {}
    for kind in sorted({r.kind for r in calls} | {r.kind for r in moves}):
        t = [r.time for r in calls if r.kind == kind]
        it = [r.iterations for r in calls if r.kind == kind and r.iterations >= 0]
        mv = [r for r in moves if r.kind == kind]
        rejected = [r.time for r in mv if not r.accepted]
        move_time = float(sum(r.time for r in mv))
        out[kind] = {
            "calls": len(t), "call_median_ms": _pct(t, 50) * 1e3, "call_p95_ms": _pct(t, 95) * 1e3,
            "call_time_s": float(sum(t)), "iterations_median": _pct(it, 50),
            "iterations_p95": _pct(it, 95), "iterations_max": float(max(it)) if it else float("nan"),
            "moves": len(mv), "move_median_ms": _pct([r.time for r in mv], 50) * 1e3,
            "rejected": len(rejected), "rejected_time_s": float(sum(rejected)),
            "rejected_share": float(sum(rejected)) / move_time if move_time > 0 else float("nan"),
        }
    return out
