"""regrasp_casadi — geometric in-hand regrasp planning with CasADi and IPOPT.

Implements Sundaralingam & Hermans, "Geometric In-Hand Regrasp Planning: Alternating Optimization of
Finger Gaits and In-Grasp Manipulation" (ICRA 2018) for the Allegro hand.

    >>> from regrasp_casadi import RegraspProblem, plan_regrasp, verify
    >>> problem = RegraspProblem.load("problems/box_rotate.yaml")
    >>> plan = plan_regrasp(problem.grasp0, problem.grasp_goal)
    >>> verify(plan).ok

Public names are imported lazily so that `import regrasp_casadi` stays cheap (no solver, no meshcat).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

_LAZY = {
    "Hand": "regrasp_casadi.hand",
    "ObjectModel": "regrasp_casadi.objects",
    "Grasp": "regrasp_casadi.grasp",
    "Plan": "regrasp_casadi.plan",
    "PlanStep": "regrasp_casadi.plan",
    "RegraspProblem": "regrasp_casadi.problem",
    "plan_regrasp": "regrasp_casadi.planner",
    "PlannerOptions": "regrasp_casadi.planner",
    "FingerGaitNLP": "regrasp_casadi.finger_gait",
    "InGraspNLP": "regrasp_casadi.in_grasp",
    "VerifyReport": "regrasp_casadi.verify",
    "generate_grasps": "regrasp_casadi.grasp_gen",
    "generate_regrasp_pairs": "regrasp_casadi.grasp_gen",
    "plan_many": "regrasp_casadi.batch",
    "BatchResult": "regrasp_casadi.batch",
    "Certificate": "regrasp_casadi.certificates",
    "SimOptions": "regrasp_casadi.mujoco_model",
    "SimReport": "regrasp_casadi.simulate",
    "RegraspError": "regrasp_casadi.errors",
    "ModelError": "regrasp_casadi.errors",
    "MeshError": "regrasp_casadi.errors",
    "GraspError": "regrasp_casadi.errors",
    "ProblemFileError": "regrasp_casadi.errors",
    "PlanFormatError": "regrasp_casadi.errors",
}

__all__ = ["__version__", "verify", *_LAZY]  # noqa: PLE0604

# `verify` is the submodule regrasp_casadi.verify, which is callable (it calls verify.verify): Python
# binds a package's submodule to the package attribute of the same name, so a function could not stay.
# It is imported on first use (`__getattr__` below), like every other name here, so that importing a
# light module such as regrasp_casadi.plan does not load the verifier and its numerical dependencies.

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi import verify  # noqa: F401
    from regrasp_casadi.batch import BatchResult, plan_many  # noqa: F401
    from regrasp_casadi.certificates import Certificate  # noqa: F401
    from regrasp_casadi.errors import (  # noqa: F401
        GraspError,
        MeshError,
        ModelError,
        PlanFormatError,
        ProblemFileError,
        RegraspError,
    )
    from regrasp_casadi.finger_gait import FingerGaitNLP  # noqa: F401
    from regrasp_casadi.grasp import Grasp  # noqa: F401
    from regrasp_casadi.grasp_gen import generate_grasps, generate_regrasp_pairs  # noqa: F401
    from regrasp_casadi.hand import Hand  # noqa: F401
    from regrasp_casadi.in_grasp import InGraspNLP  # noqa: F401
    from regrasp_casadi.mujoco_model import SimOptions  # noqa: F401
    from regrasp_casadi.objects import ObjectModel  # noqa: F401
    from regrasp_casadi.plan import Plan, PlanStep  # noqa: F401
    from regrasp_casadi.planner import PlannerOptions, plan_regrasp  # noqa: F401
    from regrasp_casadi.problem import RegraspProblem  # noqa: F401
    from regrasp_casadi.simulate import SimReport  # noqa: F401
    from regrasp_casadi.verify import VerifyReport  # noqa: F401


def __getattr__(name: str):
    if name == "verify":
        return importlib.import_module("regrasp_casadi.verify")
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'regrasp_casadi' has no attribute {name!r}")
