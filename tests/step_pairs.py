"""Two-step plans from problem files: a problem's grasp0 and grasp_goal (with joints) as the steps before
and after one plan step, for tests of one step's path (tests/data/*.yaml fixtures cut from real plans)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from regrasp_casadi.plan import PlanStep
from regrasp_casadi.problem import RegraspProblem


def step_pair(path: Path, kind: str, finger: str | None = None):
    """(hand, obj, [initial step, `kind` step of `finger`]) of the problem file `path`."""
    problem = RegraspProblem.load(path)
    steps = [PlanStep(kind=k, finger=f, q=g.q, T_palm_object=g.T_palm_object,
                      contacts_object=g.contacts_object, contact_error=np.zeros(len(g.contacts_object)),
                      solver_status="", solve_time=0.0)
             for k, f, g in (("initial", None, problem.grasp0), (kind, finger, problem.grasp_goal))]
    return problem.hand, problem.obj, steps
