"""plan_many: the process and Ray backends give the serial plans bit for bit; failures are recorded per job.

The references: the serial run, and for it `plan_regrasp` called directly on the loaded problem (its own,
freshly built models and NLPs). The planner is deterministic, so every backend must give the same
statuses, iterations and joint angles (compared with ==, not a tolerance).
"""

from __future__ import annotations

import io
import sys

import casadi as ca
import numpy as np
import pytest

from regrasp_casadi.batch import BatchResult, plan_many
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.resources import builtin_problem

PROBLEMS = [str(builtin_problem("box_rotate")), str(builtin_problem("box_shift"))]
METHODS = ("svd", "sd")
SHORT = {"max_iters": 6}
"""Planner overrides of the backend comparisons: six iterations of each plan (gaits, slides, reposings,
every NLP of the box built) compare the backends as well as whole plans, in a fraction of the time."""


@pytest.fixture(scope="module")
def serial() -> list[BatchResult]:
    return plan_many(PROBLEMS, backend="serial", methods=METHODS, progress=False, **SHORT)


def _assert_same_plans(results: list[BatchResult], reference: list[BatchResult]) -> None:
    assert [(r.problem, r.method) for r in results] == [(r.problem, r.method) for r in reference]
    for got, ref in zip(results, reference, strict=True):
        assert got.error is None, got.error
        assert got.plan.status == ref.plan.status
        assert got.plan.iterations == ref.plan.iterations
        assert [s.kind for s in got.plan.steps] == [s.kind for s in ref.plan.steps]
        for a, b in zip(got.plan.steps, ref.plan.steps, strict=True):
            assert np.array_equal(a.q, b.q), f"{got.problem}/{got.method}: q differs"
            assert np.array_equal(a.T_palm_object, b.T_palm_object)
        assert got.verified == ref.verified


def test_serial_is_plan_regrasp(serial):
    """The serial job = `plan_regrasp` on the problem as loaded (fresh models, fresh NLPs), then `verify`."""
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.verify import verify

    assert [(r.problem, r.method) for r in serial] == [
        ("box_rotate", "svd"), ("box_rotate", "sd"), ("box_shift", "svd"), ("box_shift", "sd")]
    problem = RegraspProblem.load(PROBLEMS[1])
    direct = plan_regrasp(problem.grasp0, problem.grasp_goal, method="svd", **SHORT)
    got = serial[2]
    assert got.plan.status == direct.status
    assert got.plan.iterations == direct.iterations
    assert np.array_equal(got.plan.steps[-1].q, direct.steps[-1].q)
    assert got.verified is verify(direct, problem.hand, problem.obj).ok is True
    assert got.verify_summary.startswith("verify: OK")
    assert all(r.verified for r in serial)  # converged or not, every plan verifies


@pytest.mark.slow  # 15 s in the default run (2026-12-03): the suite over its 10-minute budget
def test_process_backend_is_serial(serial):
    """Two worker processes, the problems given once as a loaded object and once as a path."""
    problems = [RegraspProblem.load(PROBLEMS[0]), PROBLEMS[1]]
    results = plan_many(problems, backend="process", workers=2, methods=METHODS, progress=False, **SHORT)
    _assert_same_plans(results, serial)
    assert results[0].path == PROBLEMS[0] and results[2].path == PROBLEMS[1]


def test_ray_backend_is_serial(serial):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        results = plan_many(PROBLEMS, backend="ray", methods=METHODS, progress=False, **SHORT)
        assert ray.is_initialized()  # a Ray started by the caller is left running
    finally:
        ray.shutdown()
    _assert_same_plans(results, serial)
    workers = {r.worker for r in results}
    assert 1 <= len(workers) <= 2, workers  # one actor per CPU, each with its own NLP cache


def test_an_exception_is_recorded_and_the_others_plan(tmp_path):
    missing = tmp_path / "missing.yaml"
    results = plan_many([missing, PROBLEMS[1]], backend="process", workers=2, progress=False, **SHORT)
    bad, good = results
    assert bad.plan is None and bad.status == "error" and not bad.ok
    assert bad.error.startswith("ProblemFileError:") and "missing.yaml" in bad.error
    assert bad.problem == "missing" and bad.index == 0
    assert good.error is None and good.plan is not None and good.verified and good.method == "svd"


@pytest.mark.slow  # 13 s in the default run (2026-12-03): the suite over its 10-minute budget
def test_nlps_are_reused_across_problems_of_one_object(monkeypatch):
    """box_rotate and box_shift hold the same box: the second problem builds no NLP in the worker."""
    from regrasp_casadi.planner import clear_nlp_cache
    from regrasp_casadi.problem import clear_model_cache

    clear_nlp_cache()
    clear_model_cache()
    built: list[str] = []
    real = ca.nlpsol

    def counting(name, *args, **kwargs):
        built.append(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(ca, "nlpsol", counting)
    seen = []
    results = plan_many(PROBLEMS, backend="serial", progress=False,
                        on_result=lambda r: seen.append(len(built)), **SHORT)
    assert [r.error for r in results] == [None, None]
    first, second = seen
    assert first > 0 and second == first, built


def test_progress_bar_on_a_terminal(monkeypatch, tmp_path):
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    files = [tmp_path / "a.yaml", tmp_path / "b.yaml"]  # missing: two quick error results
    for progress, shown in ((True, True), (False, False)):
        err = Terminal()
        monkeypatch.setattr(sys, "stderr", err)
        results = plan_many(files, backend="serial", progress=progress)
        monkeypatch.undo()
        assert [r.status for r in results] == ["error", "error"]
        assert ("2/2" in err.getvalue()) is shown, err.getvalue()
    not_a_terminal = io.StringIO()
    monkeypatch.setattr(sys, "stderr", not_a_terminal)
    plan_many(files, backend="serial", progress=True)
    assert not_a_terminal.getvalue() == ""


def test_bad_arguments_fail_before_planning():
    with pytest.raises(ValueError, match="backend"):
        plan_many(PROBLEMS, backend="threads")
    with pytest.raises(ValueError, match="method"):
        plan_many(PROBLEMS, methods=("svd", "kabsch"))
    with pytest.raises(ValueError, match="not both"):
        plan_many(PROBLEMS, methods=("svd",), method="sd")
    with pytest.raises(TypeError, match="no_such_option"):
        plan_many(PROBLEMS, no_such_option=1)
    with pytest.raises(TypeError, match="RegraspProblem"):
        plan_many([42])
    assert plan_many([], backend="process") == []


def test_ray_missing_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    with pytest.raises(ImportError, match=r"regrasp-casadi\[ray\]"):
        plan_many(PROBLEMS, backend="ray")


def test_cli_bench_passes_the_backend_to_the_script(monkeypatch):
    import runpy

    from regrasp_casadi import cli

    seen = {}

    def fake_run_path(path, run_name):
        seen["argv"] = list(sys.argv)
        raise SystemExit(0)

    monkeypatch.setattr(runpy, "run_path", fake_run_path)
    assert cli.main(["bench", "--backend", "ray", "--address", "auto", "--pairs", "1"]) == 0
    assert seen["argv"][1:] == ["--backend", "ray", "--address", "auto", "--pairs", "1"]


def _paper_objects():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "paper_objects.py"
    spec = importlib.util.spec_from_file_location("paper_objects_under_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_bench_script_backend_flags_and_throughput():
    bench = _paper_objects()
    default = bench.parse_args([])
    assert (default.backend, default.workers, default.address) == ("process", 1, None)
    ray_cluster = bench.parse_args(["--backend", "ray", "--address", "auto"])
    assert (ray_cluster.backend, ray_cluster.workers, ray_cluster.address) == ("ray", None, "auto")
    with pytest.raises(SystemExit):
        bench.parse_args(["--address", "auto"])  # an address without the Ray backend
    tp = bench.throughput(8, 120.0, 2)  # 8 plans in 2 minutes on 2 cores
    assert tp["plans_per_minute"] == pytest.approx(4.0)
    assert tp["plans_per_minute_per_core"] == pytest.approx(2.0)


def test_scheduler_keeps_an_object_on_the_worker_that_built_its_nlps():
    """Jobs of objects A A A B B C: a free worker takes its own object's jobs, then an object nobody has
    started, and only then another worker's object (the one with the most jobs left)."""
    from regrasp_casadi.batch import _Job, _Scheduler

    objects = "AAABBC"
    jobs = [_Job(i, "svd", (), hand_spec={"model": "h"}, object_spec={"primitive": o})
            for i, o in enumerate(objects)]
    scheduler = _Scheduler(jobs, 2)
    taken = [(w, objects[scheduler.next_for(w).index]) for w in (0, 1, 1, 1, 0, 0)]
    assert taken == [(0, "A"), (1, "B"), (1, "B"), (1, "C"), (0, "A"), (0, "A")]
    assert scheduler.next_for(0) is None and scheduler.next_for(1) is None
    jobs = [_Job(i, "svd", (), hand_spec={"model": "h"}, object_spec={"primitive": o})
            for i, o in enumerate("AAAAB")]
    scheduler = _Scheduler(jobs, 3)
    taken = ["AAAAB"[scheduler.next_for(w).index] for w in (0, 1, 2)]
    assert taken == ["A", "B", "A"]  # the third worker, with no new object left, shares A
