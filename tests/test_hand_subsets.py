"""Hand subsets in problem files (``hand: {model: allegro_right, fingers: [index, middle, thumb]}``): the
named fingers hold, the others are collision bodies kept clear; such a plan verifies."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from regrasp_casadi.errors import ProblemFileError
from regrasp_casadi.planner import plan_regrasp
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.verify import verify

BOX_SHIFT = Path(__file__).resolve().parents[1] / "problems" / "box_shift.yaml"
HOLD = ["index", "middle", "thumb"]


def _three_finger_doc() -> dict:
    doc = yaml.safe_load(BOX_SHIFT.read_text())
    doc["hand"] = {"model": "allegro_right", "fingers": HOLD}
    doc["grasp_goal"]["contacts"] = {f: doc["grasp_goal"]["contacts"][f] for f in HOLD}
    doc["grasp0"]["joints"][8:12] = [0.0, 0.0, 0.0, 0.0]  # the ring finger straight: 13.6 mm off the box
    return doc


def _write(tmp_path, doc) -> Path:
    path = tmp_path / "three.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_a_problem_file_names_the_fingers_that_hold(tmp_path):
    problem = RegraspProblem.load(_write(tmp_path, _three_finger_doc()))
    assert problem.hand.fingers == tuple(HOLD) and problem.hand.n_joints == 16
    assert problem.grasp0.contacts_object.shape == (3, 3)
    # the ring finger's spheres, its tip included, are collision bodies (checked for clearance)
    assert any("11.0_tip" in label for label in problem.hand.sphere_labels())
    again = RegraspProblem.load(problem.save(tmp_path / "saved.yaml"))  # written as a URDF + fingers
    assert again.hand.fingers == tuple(HOLD)
    assert np.array_equal(again.grasp0.q, problem.grasp0.q)


@pytest.mark.parametrize("fingers", [["index", "pinky"], ["index", "index"], [], "index"])
def test_fingers_that_the_model_does_not_have_are_an_error(tmp_path, fingers):
    doc = _three_finger_doc()
    doc["hand"]["fingers"] = fingers
    with pytest.raises(ProblemFileError, match=r"hand\.fingers: expected a list of distinct fingers"):
        RegraspProblem.load(_write(tmp_path, doc))


@pytest.mark.slow
def test_a_three_finger_regrasp_plans_and_verifies(tmp_path):
    problem = RegraspProblem.load(_write(tmp_path, _three_finger_doc()))
    # with the steps' paths: verify samples the motion, and straight joint lines would slip (its rows)
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, max_iters=3)
    assert len(plan.steps) > 1 and plan.fingers == tuple(HOLD)
    report = verify(plan, problem.hand, problem.obj)
    assert report.ok, report.summary()
