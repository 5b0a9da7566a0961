"""Grasp validation and the Plan file format (lossless JSON round trip, schema checks)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import twofinger as tf

from regrasp_casadi.errors import GraspError, PlanFormatError
from regrasp_casadi.grasp import SCHEMA_VERSION, Grasp, Plan, PlanStep
from regrasp_casadi.transforms import make_T, rpy_to_R

FINGERS = ("index", "middle", "ring", "thumb")


def _random_plan(seed: int = 0, n_steps: int = 5) -> Plan:
    """A plan full of awkward floats (random, tiny, huge, -0.0): every bit must survive JSON."""
    rng = np.random.default_rng(seed)
    kinds = ["initial"] + ["gait", "repose", "gait", "final"][: n_steps - 1]
    steps = []
    for k, kind in enumerate(kinds):
        q = rng.normal(size=16)
        q[0] = -0.0
        q[1] = 1e-300
        q[2] = 1.0 / 3.0
        T = make_T(rpy_to_R(*rng.normal(size=3)), rng.normal(size=3) * 0.1)
        steps.append(
            PlanStep(
                kind=kind,
                finger=FINGERS[k % 4] if kind == "gait" else None,
                q=q,
                T_palm_object=T,
                contacts_object=rng.normal(size=(4, 3)) * 0.05,
                contact_error=np.abs(rng.normal(size=4)) * 1e-2,
                solver_status="" if kind == "initial" else "Solve_Succeeded",
                solve_time=float(rng.uniform()) * 1e-3,
            )
        )
    return Plan(
        steps=tuple(steps),
        goal_contacts_object=rng.normal(size=(4, 3)) * 0.05,
        goal_T_palm_object=make_T(rpy_to_R(0.1, -0.2, 0.3), [0.1, 0.02, 0.05]),
        fingers=FINGERS,
        hand_spec={"model": "allegro_right"},
        object_spec={"primitive": "box", "extents": [0.05, 0.09, 0.175]},
        method="svd",
        status="converged",
        status_detail="",
        iterations=2,
        iteration_errors=np.array([0.03, 0.011, 0.004]) + rng.normal(size=3) * 1e-12,
        timing={"build": 0.5, "opt1": 0.01, "opt2": 0.02, "other": 0.003, "total": 0.533},
        options={"zeta": 0.006, "eta": 0.01, "beta": 0.001, "method": "svd", "gait": ["index", "thumb"]},
    )


def _assert_bitwise_equal(a: Plan, b: Plan) -> None:
    assert len(a.steps) == len(b.steps)
    for sa, sb in zip(a.steps, b.steps, strict=True):
        for name in ("q", "T_palm_object", "contacts_object", "contact_error"):
            x, y = getattr(sa, name), getattr(sb, name)
            assert np.array_equal(x, y), name
            # bit-for-bit, including the sign of zero
            assert x.tobytes() == y.tobytes(), name
        assert (sa.kind, sa.finger, sa.solver_status, sa.solve_time) == (
            sb.kind, sb.finger, sb.solver_status, sb.solve_time)
    for name in ("goal_contacts_object", "goal_T_palm_object", "iteration_errors"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    assert a == b


def test_plan_dict_round_trip_is_bitwise():
    plan = _random_plan()
    again = Plan.from_dict(json.loads(json.dumps(plan.to_dict(), allow_nan=False)))
    _assert_bitwise_equal(plan, again)


def test_plan_save_load_round_trip_is_bitwise(tmp_path):
    plan = _random_plan(seed=3)
    path = plan.save(tmp_path / "plan.json")
    again = Plan.load(path)
    _assert_bitwise_equal(plan, again)
    # a second save writes the same bytes
    assert again.save(tmp_path / "plan2.json").read_bytes() == path.read_bytes()


def test_plan_equality_detects_one_bit():
    plan = _random_plan()
    d = plan.to_dict()
    d["steps"][2]["q"][5] = float(np.nextafter(d["steps"][2]["q"][5], np.inf))
    assert Plan.from_dict(d) != plan


@pytest.mark.parametrize("version", [0, 2, "1", True])
def test_wrong_schema_version(version):
    d = _random_plan().to_dict()
    d["schema_version"] = version
    with pytest.raises(PlanFormatError, match=r"schema_version: expected 1, found"):
        Plan.from_dict(d)


def test_missing_schema_version_names_expected():
    d = _random_plan().to_dict()
    del d["schema_version"]
    with pytest.raises(PlanFormatError, match=rf"schema_version: missing.*expected {SCHEMA_VERSION}"):
        Plan.from_dict(d)


@pytest.mark.parametrize("field", ["steps", "fingers", "goal_T_palm_object", "method", "timing",
                                   "iteration_errors", "status"])
def test_missing_field_is_named(field):
    d = _random_plan().to_dict()
    del d[field]
    with pytest.raises(PlanFormatError, match=rf"\b{field}: missing field"):
        Plan.from_dict(d)


def test_missing_step_field_is_named():
    d = _random_plan().to_dict()
    del d["steps"][3]["contacts_object"]
    with pytest.raises(PlanFormatError, match=r"steps\[3\]\.contacts_object: missing field"):
        Plan.from_dict(d)


@pytest.mark.parametrize(
    "path, value, pattern",
    [
        (("steps", 1, "T_palm_object"), [[1.0, 0.0, 0.0]], r"steps\[1\]\.T_palm_object: expected shape"),
        (("steps", 0, "q"), "abc", r"steps\[0\]\.q: expected a 1-D array"),
        (("steps", 2, "kind"), "teleport", r"steps\[2\]\.kind: expected one of"),
        (("steps", 2, "solve_time"), "fast", r"steps\[2\]\.solve_time: expected"),
        (("iterations",), -1, r"iterations: expected a non-negative integer"),
        (("goal_contacts_object",), [[0.0, 1.0]], r"goal_contacts_object: expected shape"),
    ],
)
def test_malformed_field_is_named(path, value, pattern):
    d = _random_plan().to_dict()
    target = d
    for p in path[:-1]:
        target = target[p]
    target[path[-1]] = value
    with pytest.raises(PlanFormatError, match=pattern):
        Plan.from_dict(d)


def test_load_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(PlanFormatError, match=r"bad\.json: not valid JSON"):
        Plan.load(bad)
    nan = tmp_path / "nan.json"
    d = _random_plan().to_dict()
    text = json.dumps(d).replace("0.006", "NaN", 1)
    nan.write_text(text)
    with pytest.raises(PlanFormatError, match=r"nan\.json"):
        Plan.load(nan)
    with pytest.raises(PlanFormatError, match=r"missing\.json"):
        Plan.load(tmp_path / "missing.json")


def test_non_finite_values_refused_on_save(tmp_path):
    plan = _random_plan()
    bad = Plan(**{**{f: getattr(plan, f) for f in plan.__dataclass_fields__},
                  "timing": {"total": float("inf")}})
    with pytest.raises(PlanFormatError, match=r"timing\.total"):
        bad.save(tmp_path / "x.json")


def test_final_error_and_summary():
    plan = _random_plan()
    err = plan.steps[-1].contact_error
    assert plan.final_error == float(np.mean(err))
    text = plan.summary()
    assert "status: converged" in text
    assert "2 gait" in text and "1 repose" in text and "1 final" in text
    assert f"max {np.max(err) * 1e3:.2f} mm" in text


def test_plan_arrays_are_read_only():
    plan = _random_plan()
    with pytest.raises(ValueError):
        plan.steps[0].q[0] = 1.0


# ------------------------------------------------------------------------------------ Grasp validation
@pytest.fixture(scope="module")
def two(tmp_path_factory):
    """Two-finger test hand and the box it holds (see twofinger.py)."""
    return tf.make_hand(tmp_path_factory.mktemp("hand")), tf.make_box()


def test_from_joints_valid_grasp_contacts_in_closed_form(two):
    hand, obj = two
    q = np.zeros(hand.n_joints)
    q[hand.joint_names.index("left_slide")] = -0.007
    g = Grasp.from_joints(hand, obj, q, tf.box_pose(dy=0.003))
    # tips at (∓0.04, 0, 0.11 + slide) palm; box centre (0, 0.003, 0.11): contacts on the ±x faces
    assert np.allclose(g.contacts_object, [[-0.03, -0.003, -0.007], [0.03, -0.003, 0.0]], atol=1e-12)
    assert np.allclose(g.tip_centers_object, [[-0.04, -0.003, -0.007], [0.04, -0.003, 0.0]], atol=1e-12)
    assert g.fingers == ("left", "right")


@pytest.mark.parametrize(
    "dx, finger, text",
    [(0.01, "left", "10.0 mm off"), (-0.01, "left", "10.0 mm inside"), (0.0004, None, None),
     (0.0006, "left", "0.6 mm off")],
)
def test_from_joints_tip_off_surface_names_finger_and_distance(two, dx, finger, text):
    hand, obj = two
    q = np.zeros(hand.n_joints)
    if finger is None:  # 0.4 mm is within the 0.5 mm tolerance
        Grasp.from_joints(hand, obj, q, tf.box_pose(dx=dx))
        return
    pattern = rf"^{finger} tip is {text} the object surface \(tolerance 0.5 mm\)$"
    with pytest.raises(GraspError, match=pattern):
        Grasp.from_joints(hand, obj, q, tf.box_pose(dx=dx))


def test_wrong_joint_count(hand, two):
    _, obj = two
    with pytest.raises(GraspError, match=r"^expected 16 joint angles for allegro_right, got 15$"):
        Grasp.from_joints(hand, obj, np.zeros(15), np.eye(4))


def test_joint_out_of_limits_names_joint_value_and_limits(hand, two):
    _, obj = two
    q = 0.5 * (hand.q_lower + hand.q_upper)
    i = hand.joint_names.index("joint_3.0")
    q[i] = hand.q_upper[i] + 0.1
    with pytest.raises(GraspError) as e:
        Grasp.from_joints(hand, obj, q, np.eye(4))
    msg = str(e.value)
    assert "joint_3.0" in msg and f"{q[i]:.6g}" in msg
    assert f"[{hand.q_lower[i]:.6g}, {hand.q_upper[i]:.6g}]" in msg
    # within 1e-6 rad of the limit is accepted by the joint check (fails later, on the geometry)
    q[i] = hand.q_upper[i] + 0.5e-6
    with pytest.raises(GraspError, match="object surface"):
        Grasp.from_joints(hand, obj, q, np.eye(4))


@pytest.mark.parametrize(
    "T, pattern",
    [
        (np.diag([1.0, 1.0, 1.001, 1.0]), "not orthonormal"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), "det -1"),
        (np.vstack([np.eye(4)[:3], [0.0, 0.0, 0.1, 1.0]]), "last row"),
        (np.eye(3), r"\(4, 4\)"),
    ],
)
def test_non_rigid_transform(two, T, pattern):
    hand, obj = two
    with pytest.raises(GraspError, match=rf"T_palm_object: .*{pattern}"):
        Grasp.from_joints(hand, obj, np.zeros(hand.n_joints), T)


def test_from_contacts(two):
    hand, obj = two
    c = np.array([[-0.03, 0.01, 0.005], [0.03, -0.01, 0.0]])
    g = Grasp.from_contacts(hand, obj, c, tf.box_pose())
    assert g.q is None
    # contact + tip radius × outward normal (−x and +x faces)
    assert np.allclose(g.tip_centers_object, c + [[-0.01, 0, 0], [0.01, 0, 0]], atol=1e-12)
    with pytest.raises(GraspError, match=r"^right contact is 2.0 mm off the object surface"):
        Grasp.from_contacts(hand, obj, c + [[0, 0, 0], [0.002, 0, 0]], tf.box_pose())
    with pytest.raises(GraspError, match=r"expected shape \(2, 3\)"):
        Grasp.from_contacts(hand, obj, c[:1], tf.box_pose())
    with pytest.raises(GraspError, match="expected 6 joint angles for twofinger, got 5"):
        Grasp.from_contacts(hand, obj, c, tf.box_pose(), q=np.zeros(5))
