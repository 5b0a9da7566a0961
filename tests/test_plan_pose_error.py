"""`Plan.final_pose_error` (the reached object pose against the desired one) and the "pose_not_reached"
status in the plan file: old files load with it, new ones round trip."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from regrasp_casadi.plan import Plan
from regrasp_casadi.transforms import make_T, rot_axis_angle

GOLDEN_V1 = Path(__file__).resolve().parent / "data" / "plan_v1_box_rotate.json"


def test_an_old_plan_file_loads_with_its_final_pose_error():
    plan = Plan.load(GOLDEN_V1)
    raw = json.loads(GOLDEN_V1.read_text())  # the file's numbers, independent of the loader
    T_last, T_goal = np.array(raw["steps"][-1]["T_palm_object"]), np.array(raw["goal_T_palm_object"])
    dR = T_last[:3, :3].T @ T_goal[:3, :3]
    angle = np.arctan2(np.linalg.norm([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]),
                       np.trace(dR) - 1.0)  # atan2(2 sin θ, 2 cos θ)
    assert plan.final_pose_error == pytest.approx((np.linalg.norm(T_last[:3, 3] - T_goal[:3, 3]), angle),
                                                  abs=1e-9)


def test_pose_not_reached_round_trips_with_its_pose_error(tmp_path):
    plan = Plan.load(GOLDEN_V1)
    last = plan.steps[-1]
    T_goal = make_T(last.T_palm_object[:3, :3] @ rot_axis_angle([0.0, 1.0, 0.0], np.radians(3.0)),
                    last.T_palm_object[:3, 3] + [0.0, 0.0, 0.004])
    planted = replace(plan, status="pose_not_reached", goal_T_palm_object=T_goal,
                      status_detail="contacts within ζ but the object 4.00 mm / 3.00° from the desired pose")
    loaded = Plan.load(planted.save(tmp_path / "plan.json"))
    assert loaded == planted and loaded.status == "pose_not_reached"
    assert loaded.final_pose_error == pytest.approx((0.004, np.radians(3.0)), abs=1e-9)
    assert "object 4.00 mm / 3.00° from the desired pose" in loaded.summary().splitlines()[2]


def test_a_plan_without_steps_has_no_pose_error():
    assert np.all(np.isnan(replace(Plan.load(GOLDEN_V1), steps=()).final_pose_error))
