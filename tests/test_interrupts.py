"""Ctrl-C while planning: the plan stops at its next step with the steps so far (issue 11 item 4)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from regrasp_casadi.interrupts import deferred_interrupts
from regrasp_casadi.plan import Plan
from regrasp_casadi.planner import plan_regrasp
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.verify import verify

REPO = Path(__file__).resolve().parents[1]


def test_sigint_during_a_plan_returns_the_partial_plan_as_interrupted(tmp_path):
    problem = RegraspProblem.load(REPO / "problems" / "box_shift.yaml")
    iterations = []

    def press_ctrl_c(iteration, max_iters, error):
        iterations.append(iteration)
        if iteration == 1:
            os.kill(os.getpid(), signal.SIGINT)  # arrives while the planner runs, as a user's Ctrl-C

    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, progress=press_ctrl_c)
    assert plan.status == "interrupted" and "Ctrl-C" in plan.status_detail
    assert iterations == [1] and plan.iterations == 1
    assert len(plan.steps) > 1 and plan.steps[0].kind == "initial"
    assert verify(plan, problem.hand, problem.obj).ok  # the partial plan is a valid plan
    assert Plan.load(plan.save(tmp_path / "partial.json")).status == "interrupted"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the handler is restored


def test_a_second_sigint_raises_at_once():
    with pytest.raises(KeyboardInterrupt), deferred_interrupts() as stop:
        os.kill(os.getpid(), signal.SIGINT)
        assert stop.requested
        os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_outside_the_main_thread_nothing_is_deferred():
    seen = []

    def body():
        with deferred_interrupts() as stop:
            seen.append(stop.requested)

    t = threading.Thread(target=body)
    t.start()
    t.join()
    assert seen == [False] and signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_cli_ctrl_c_writes_the_partial_plan_and_exits_130(tmp_path):
    """`regrasp plan` under SIGINT: exit 130 and the partial plan saved (a plan of bottle_regrasp takes
    several seconds; the signal is sent once the first iteration is reported on stderr)."""
    out = tmp_path / "plan.json"
    code = (
        "import os, signal, sys\n"
        "import regrasp_casadi.planner as planner\n"
        "original = planner.plan_regrasp\n"
        "def plan_regrasp(*a, progress=None, **k):\n"
        "    def hook(i, n, e):\n"
        "        if i == 1:\n"
        "            os.kill(os.getpid(), signal.SIGINT)\n"
        "        if progress: progress(i, n, e)\n"
        "    return original(*a, progress=hook, **k)\n"
        "planner.plan_regrasp = plan_regrasp\n"
        "from regrasp_casadi.cli import main\n"
        f"problem = {str(REPO / 'problems' / 'bottle_regrasp.yaml')!r}\n"
        f"sys.exit(main(['plan', problem, '--out', {str(out)!r}]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path, check=False)
    assert proc.returncode == 130, proc.stderr[-2000:]
    plan = Plan.load(out)
    assert plan.status == "interrupted" and plan.iterations == 1 and len(plan.steps) > 1
