"""Many plans at once: `plan_many` plans a list of regrasp problems in worker processes or on Ray.

    >>> results = plan_many(["problems/box_rotate.yaml", "problems/box_shift.yaml"], methods=("svd", "sd"))
    >>> [(r.problem, r.method, r.status, r.verified) for r in results]

Every job (a problem, or a problem × method with `methods`) is planned by `plan_regrasp` and judged by
`verify` in a worker; the results come back in input order and are the same as the serial run (the
planner is deterministic and resets its warm starts for every plan). A worker never raises: an exception
(an unreadable problem file, a crashed worker) is recorded in the job's `BatchResult.error`.

Backends:
    "process" (default): worker processes (one single-process `concurrent.futures.ProcessPoolExecutor`
        each) started by the "forkserver" method on Linux (a clean, single-threaded server process that
        has imported CasADi, the planner and the verifier once; each worker is forked from it, so it
        starts in milliseconds and shares no solver state or threads with the caller), "spawn"
        elsewhere. Plain "fork" is not used: the caller may hold threads (tqdm, Ray, BLAS) and live
        IPOPT/CasADi objects, which are not fork-safe. As with any spawn/forkserver pool, a script that
        calls `plan_many` must guard its top level with ``if __name__ == "__main__":``.
    "ray": one Ray actor per CPU (`ray.init(num_cpus=workers)` locally, or `ray.init(address=...)` for a
        running cluster; an already initialised Ray is used as it is). Ray is an optional extra:
        ``pip install 'regrasp-casadi[ray]'``. On a cluster, the package and the problem files (and the
        meshes they name) must be present on every node.
    "serial": the jobs one after the other in the calling process (the reference for the others).

NLP caching: each worker process keeps one NLP cache (the planner's), keyed by its hand and object. The
worker takes its models from `problem.plan_models`' per-spec cache, so every problem with the same hand and
object spec (two methods on one problem, several pairs on one mesh) reuses the worker's NLPs. Jobs are
handed to the workers (for both "process" and "ray") with that in mind: a free worker takes a job of an
object it has already built the NLPs of, else one of an object no worker has started, so that each
object's NLPs are built by as few workers as possible. Problem
paths are the cheaper input (each worker reads the file itself); an in-memory `RegraspProblem` is sent as
its hand and object specs and its grasps' arrays (a `Hand` does not pickle).
"""

from __future__ import annotations

import hashlib
import json
import logging
import multiprocessing
import os
import pathlib
import socket
import sys
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import Plan
    from regrasp_casadi.problem import RegraspProblem

__all__ = ["BatchResult", "plan_many", "process_context", "BACKENDS"]

_log = logging.getLogger(__name__)

Backend = Literal["process", "ray", "serial"]
BACKENDS: tuple[str, ...] = ("process", "ray", "serial")
"""The values of `plan_many`'s `backend`."""

RAY_EXTRA_HINT = "pip install 'regrasp-casadi[ray]'"

# modules the forkserver imports once, so that forked workers start with CasADi and the planner loaded
_PRELOAD = ("regrasp_casadi.batch", "regrasp_casadi.planner", "regrasp_casadi.problem",
            "regrasp_casadi.verify")


@dataclass(frozen=True, eq=False)
class BatchResult:
    """The outcome of one job of `plan_many` (always filled; `plan` is None when `error` is set)."""

    index: int
    """Position of the job in the input order (problem-major: problem k, method j → k·len(methods) + j)."""
    problem: str
    """The problem's name (its file stem when the file could not be read)."""
    path: str | None
    """The problem file, or None for an in-memory problem."""
    method: str
    """OPT2's objective used: "svd" or "sd"."""
    plan: Plan | None = None
    """The plan (None if an exception escaped)."""
    verified: bool = False
    """`verify(plan).ok`."""
    verify_summary: str = ""
    """`VerifyReport.summary()` of the plan ("" without a plan)."""
    verify_metrics: dict[str, Any] = field(default_factory=dict)
    """`VerifyReport.metrics` (min clearance, max slip, final errors in m, ...)."""
    violations: tuple[str, ...] = ()
    """Every violation as one line: ``step k: check [who]: message``."""
    wall_time: float = 0.0
    """Time the worker spent on the job (reading the problem, planning, verifying), s."""
    cpu_time: float = 0.0
    """CPU time of the worker process over the job (`time.process_time`), s: less than `wall_time` when
    other processes share the cores."""
    worker: str = ""
    """Where it ran: ``host:pid`` of the worker process."""
    error: str | None = None
    """``ExceptionType: message`` of an exception that escaped reading, planning or verifying, else None."""
    solve_log: Any = None
    """The plan's `solve_log.SolveLog` (every backend call and NLP move), None without a plan."""

    @property
    def status(self) -> str:
        """The plan's status ("converged", "stalled", ...) or "error"."""
        return self.plan.status if self.plan is not None else "error"

    @property
    def ok(self) -> bool:
        """Converged and verified, without error."""
        return self.error is None and self.status == "converged" and self.verified

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (without the plan's steps): problem, path, method, status, iterations,
        final average contact error (m), verified, violations count, wall time (s), worker, error."""
        plan = self.plan
        return {
            "index": self.index, "problem": self.problem, "path": self.path, "method": self.method,
            "status": self.status,
            "iterations": int(plan.iterations) if plan is not None else None,
            "final_error": float(plan.final_error) if plan is not None and plan.steps else None,
            "verified": self.verified, "n_violations": len(self.violations),
            "wall_time": self.wall_time, "cpu_time": self.cpu_time, "worker": self.worker,
            "error": self.error,
        }


@dataclass(frozen=True)
class _Job:
    """What a worker needs for one plan: a problem file, or an in-memory problem as specs and arrays."""

    index: int
    method: str
    overrides: tuple[tuple[str, Any], ...]
    path: str | None = None
    name: str | None = None
    hand_spec: dict | None = None
    object_spec: dict | None = None
    q0: np.ndarray | None = None
    """Initial joint angles (n_joints,), rad."""
    T_palm_object0: np.ndarray | None = None
    """Initial object pose in the palm frame (4, 4), m."""
    goal_contacts_object: np.ndarray | None = None
    """Desired contacts (n_fingers, 3) in the object frame, m."""
    goal_T_palm_object: np.ndarray | None = None
    """Desired object pose in the palm frame (4, 4), m."""
    goal_q: np.ndarray | None = None
    """Desired joint angles (n_joints,), rad, or None."""

    @property
    def label(self) -> str:
        return self.name or (pathlib.Path(self.path).stem if self.path else f"problem {self.index}")


# ------------------------------------------------------------------------------------------ worker side
_LOADED: dict[tuple, _Job] = {}
"""Per worker process: problem file (path, size, mtime) → its `_Job` content, so that the methods of one
problem read the file once."""


def _job_from_problem(problem: RegraspProblem, index: int, method: str, overrides: tuple) -> _Job:
    g0, gg = problem.grasp0, problem.grasp_goal
    return _Job(index, method, overrides,
                path=str(problem.path) if problem.path is not None else None, name=problem.name,
                hand_spec=dict(problem.hand.spec()), object_spec=dict(problem.obj.spec),
                q0=np.asarray(g0.q, dtype=float), T_palm_object0=np.asarray(g0.T_palm_object, dtype=float),
                goal_contacts_object=np.asarray(gg.contacts_object, dtype=float),
                goal_T_palm_object=np.asarray(gg.T_palm_object, dtype=float),
                goal_q=None if gg.q is None else np.asarray(gg.q, dtype=float))


def _read_problem(job: _Job) -> _Job:
    """`job` with the problem file read (hand/object specs, grasp arrays), cached per file version."""
    if job.hand_spec is not None:
        return job
    from regrasp_casadi.problem import RegraspProblem

    path = os.path.abspath(job.path)
    try:
        st = os.stat(path)
        key = (path, st.st_size, st.st_mtime_ns)
    except OSError:
        key = (path,)
    if key not in _LOADED:
        _LOADED.clear()  # the methods of one problem come one after the other: keep one file
        _LOADED[key] = _job_from_problem(RegraspProblem.load(job.path), -1, "", ())
    read = _LOADED[key]
    return replace(read, index=job.index, method=job.method, overrides=job.overrides, path=job.path)


def run_job(job: _Job) -> BatchResult:
    """Plan and verify one job in this process (never raises: an exception is recorded in the result)."""
    t0, cpu0 = time.perf_counter(), time.process_time()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    base = {"index": job.index, "problem": job.label, "path": job.path, "method": job.method,
            "worker": worker}
    try:
        from regrasp_casadi.grasp import Grasp
        from regrasp_casadi.planner import plan_regrasp
        from regrasp_casadi.problem import plan_models
        from regrasp_casadi.solve_log import recording
        from regrasp_casadi.verify import verify

        job = _read_problem(job)
        base["problem"] = job.label
        # this process's models for these specs: the planner's NLP cache is keyed by the models
        hand, obj = plan_models(SimpleNamespace(hand_spec=job.hand_spec, object_spec=job.object_spec))
        grasp0 = Grasp.from_joints(hand, obj, job.q0, job.T_palm_object0)
        goal = Grasp.from_contacts(hand, obj, job.goal_contacts_object, job.goal_T_palm_object, q=job.goal_q)
        with recording() as log:
            plan = plan_regrasp(grasp0, goal, **dict(job.overrides), method=job.method)
        report = verify(plan, hand, obj)
    except Exception as exc:  # noqa: BLE001 - a batch records failures, it does not stop on them
        _log.debug("job %d (%s) failed", job.index, job.label, exc_info=True)
        return BatchResult(**base, error=_error_text(exc), wall_time=time.perf_counter() - t0,
                           cpu_time=time.process_time() - cpu0)
    return BatchResult(
        **base, plan=plan, verified=bool(report.ok), verify_summary=report.summary(),
        verify_metrics=dict(report.metrics), solve_log=log,
        violations=tuple(f"step {v.step}: {v.check} [{v.who}]: {v.message}" for v in report.violations),
        wall_time=time.perf_counter() - t0, cpu_time=time.process_time() - cpu0)


def _error_text(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}"


class _RayWorker:
    """A Ray actor: one process, one NLP cache, running jobs with `run_job`."""

    def run(self, job: _Job) -> BatchResult:
        return run_job(job)


# ------------------------------------------------------------------------------------------ caller side
def process_context() -> multiprocessing.context.BaseContext:
    """The start method of the worker processes: "forkserver" (with the planner preloaded) on Linux,
    "spawn" elsewhere (see the module docstring)."""
    if sys.platform.startswith("linux"):
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(list(_PRELOAD))  # no effect once this process's forkserver runs
        return ctx
    return multiprocessing.get_context("spawn")


def _make_jobs(problems: Iterable[RegraspProblem | str | os.PathLike], methods: Sequence[str] | None,
               overrides: dict[str, Any]) -> list[_Job]:
    from regrasp_casadi.planner import PlannerOptions
    from regrasp_casadi.problem import RegraspProblem

    replace(PlannerOptions(), **overrides)  # unknown option names fail here, not in every worker
    if methods is None:
        methods = (overrides.get("method", PlannerOptions.method),)
    elif "method" in overrides:
        raise ValueError("give the method either in `methods` or as the `method` override, not both")
    rest = tuple(sorted((k, v) for k, v in overrides.items() if k != "method"))
    jobs: list[_Job] = []
    for problem in problems:
        for method in methods:
            if method not in ("svd", "sd"):
                raise ValueError(f"unknown method {method!r} (svd or sd)")
            if isinstance(problem, RegraspProblem):
                jobs.append(_job_from_problem(problem, len(jobs), method, rest))
            elif isinstance(problem, (str, os.PathLike)):
                jobs.append(_Job(len(jobs), method, rest, path=os.fspath(problem)))
            else:
                raise TypeError("expected a RegraspProblem or a problem-file path, got "
                                f"{type(problem).__name__}")
    return jobs


def _failed(job: _Job, exc: BaseException) -> BatchResult:
    """The result of a job whose worker did not return (it died, or the pool broke)."""
    return BatchResult(job.index, job.label, job.path, job.method, error=_error_text(exc))


def _affinity_key(job: _Job) -> str:
    """A key of the job's hand and object: jobs with one key share their NLPs in a worker. For a problem
    file, the file's `hand` and `object` entries (read without building anything; a relative mesh or
    URDF path taken with the file's folder); a unique key when the file cannot be read."""
    if job.hand_spec is not None:
        what: Any = [job.hand_spec, job.object_spec]
    else:
        import yaml

        try:
            raw = yaml.safe_load(pathlib.Path(job.path).read_text(encoding="utf-8"))
            what = [raw["hand"], raw["object"], str(pathlib.Path(job.path).resolve().parent)]
        except Exception:  # noqa: BLE001 - the worker reports the problem; any worker may take it
            return f"unreadable job {job.index}"
    return hashlib.sha1(json.dumps(what, sort_keys=True, default=str).encode()).hexdigest()


class _Scheduler:
    """Which job a free worker takes next: one whose hand and object it has already built the NLPs of,
    else one of an object no worker has seen, else one of the object with the most jobs left (it never
    leaves a worker idle while jobs wait). The plans do not depend on it: only NLP builds are saved."""

    def __init__(self, jobs: list[_Job], n_workers: int):
        self._queues: dict[str, deque[_Job]] = {}
        for job in jobs:
            self._queues.setdefault(_affinity_key(job), deque()).append(job)
        self._built: list[set[str]] = [set() for _ in range(n_workers)]

    def next_for(self, worker: int) -> _Job | None:
        waiting = [k for k, q in self._queues.items() if q]
        if not waiting:
            return None
        seen = set().union(*self._built)
        key = (next((k for k in waiting if k in self._built[worker]), None)
               or next((k for k in waiting if k not in seen), None)
               or max(waiting, key=lambda k: len(self._queues[k])))
        self._built[worker].add(key)
        return self._queues[key].popleft()

    def restarted(self, worker: int) -> None:
        """The worker was replaced by a new process: its NLPs are gone."""
        self._built[worker].clear()


def _run_serial(jobs: list[_Job]) -> Iterator[BatchResult]:
    for job in jobs:
        yield run_job(job)


def _run_process(jobs: list[_Job], workers: int) -> Iterator[BatchResult]:
    """One single-process executor per worker, so that the scheduler decides where each job runs."""
    ctx = process_context()
    pools = [ProcessPoolExecutor(max_workers=1, mp_context=ctx) for _ in range(workers)]
    scheduler = _Scheduler(jobs, workers)
    running: dict[Future, tuple[int, _Job]] = {}

    def feed(worker: int) -> None:
        job = scheduler.next_for(worker)
        if job is not None:
            running[pools[worker].submit(run_job, job)] = (worker, job)

    try:
        for worker in range(workers):
            feed(worker)
        while running:
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for fut in done:
                worker, job = running.pop(fut)
                try:
                    result = fut.result()
                except Exception as exc:  # noqa: BLE001 - the worker died (BrokenProcessPool): recorded
                    result = _failed(job, exc)
                    pools[worker].shutdown(wait=False, cancel_futures=True)
                    pools[worker] = ProcessPoolExecutor(max_workers=1, mp_context=ctx)
                    scheduler.restarted(worker)
                yield result
                feed(worker)
    finally:
        for pool in pools:
            pool.shutdown(wait=True, cancel_futures=True)


def _import_ray():
    try:
        import ray
    except ImportError as e:
        raise ImportError(f"plan_many(backend='ray') needs Ray, an optional extra: {RAY_EXTRA_HINT} "
                          f"({e})") from None
    return ray


def _run_ray(jobs: list[_Job], workers: int | None, address: str | None) -> Iterator[BatchResult]:
    """One Ray actor (one process, one NLP cache) per worker; the scheduler decides where each job runs."""
    ray = _import_ray()
    started = not ray.is_initialized()
    if started:
        if address is not None:
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(num_cpus=workers or _cpu_count(), include_dashboard=False, log_to_driver=False)
    try:
        n_actors = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        n_actors = max(1, min(n_actors, len(jobs)))
        actor_class = ray.remote(num_cpus=1)(_RayWorker)
        actors = [actor_class.remote() for _ in range(n_actors)]
        scheduler = _Scheduler(jobs, n_actors)
        running: dict[Any, tuple[int, _Job]] = {}

        def feed(worker: int) -> None:
            job = scheduler.next_for(worker)
            if job is not None:
                running[actors[worker].run.remote(job)] = (worker, job)

        for worker in range(n_actors):
            feed(worker)
        while running:
            (ref,), _ = ray.wait(list(running), num_returns=1)
            worker, job = running.pop(ref)
            try:
                result = ray.get(ref)
            except Exception as exc:  # noqa: BLE001 - a dead actor: recorded, replaced
                result = _failed(job, exc)
                ray.kill(actors[worker])
                actors[worker] = actor_class.remote()
                scheduler.restarted(worker)
            yield result
            feed(worker)
        for actor in actors:
            ray.kill(actor)
    finally:
        if started:
            ray.shutdown()


def _cpu_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def plan_many(
    problems: Iterable[RegraspProblem | str | os.PathLike],
    backend: Backend = "process",
    workers: int | None = None,
    address: str | None = None,
    progress: bool = True,
    *,
    methods: Sequence[str] | None = None,
    on_result: Callable[[BatchResult], None] | None = None,
    **planner_overrides: Any,
) -> list[BatchResult]:
    """Plan (and verify) many regrasp problems in parallel; the results are those of the serial run.

    Args:
        problems: `RegraspProblem`s or problem-file paths (paths are cheaper to send: each worker reads the
            file itself).
        backend: "process" (a local process pool, the default), "ray" (Ray actors) or "serial".
        workers: worker processes / Ray actors (default: the CPUs available to this process, or of the
            Ray cluster), never more than the jobs.
        address: "ray" only: the address of a running Ray cluster (``"auto"``, ``"ray://host:10001"``);
            None starts a local Ray with `workers` CPUs (and shuts it down after). An already
            initialised Ray (``ray.init`` called by the caller) is used as it is.
        progress: show a tqdm bar on stderr (only when stderr is a terminal).
        methods: plan every problem with each of these OPT2 objectives ("svd", "sd"); the jobs are
            problem-major (problem 0 with every method, then problem 1, ...). Default: one job per
            problem with `planner_overrides`' method (default "svd").
        on_result: called in the calling process with each result as it arrives (completion order).
        **planner_overrides: `PlannerOptions` fields for every plan (e.g. ``max_iters=30``).

    Returns:
        One `BatchResult` per job, in input order. A job whose problem cannot be read, whose planning or
        verification raised, or whose worker died has `error` set and `plan` None; the others still run.

    Raises:
        ValueError, TypeError: an unknown backend, method, planner option or problem type (before any
            plan starts).
        ImportError: backend "ray" without Ray installed (the message names the extra).
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r} (one of {', '.join(BACKENDS)})")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if backend == "ray":
        _import_ray()
    jobs = _make_jobs(problems, methods, planner_overrides)
    if not jobs:
        return []
    if backend == "serial":
        stream = _run_serial(jobs)
    elif backend == "process":
        stream = _run_process(jobs, max(1, min(workers or _cpu_count(), len(jobs))))
    else:
        stream = _run_ray(jobs, workers, address)
    from tqdm import tqdm

    results: list[BatchResult | None] = [None] * len(jobs)
    # disable=None: a bar only when stderr is a terminal; every result redraws it (plans take seconds)
    with tqdm(total=len(jobs), desc=f"plans ({backend})", unit="plan", file=sys.stderr, leave=False,
              dynamic_ncols=True, mininterval=0, miniters=1, disable=None if progress else True) as bar:
        for result in stream:
            results[result.index] = result
            if on_result is not None:
                on_result(result)
            bar.set_postfix_str(f"{sum(r is not None and r.ok for r in results)} ok", refresh=False)
            bar.update(1)
    return [r if r is not None else _failed(job, RuntimeError("no result returned"))
            for r, job in zip(results, jobs, strict=True)]
