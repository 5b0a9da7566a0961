"""The plan file (JSON): lossless round trip, strict schema (every unknown or malformed field is named
with the file), atomic save, and a module that loads no model code."""

from __future__ import annotations

import errno
import json
import os
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import regrasp_casadi
from regrasp_casadi import files
from regrasp_casadi.errors import PlanFormatError
from regrasp_casadi.motion import StepPath
from regrasp_casadi.plan import PLAN_METHODS, PLAN_STATUSES, SCHEMA_VERSION, STEP_KINDS, Plan, PlanStep
from regrasp_casadi.transforms import make_T, rpy_to_R

FINGERS = ("index", "middle", "ring", "thumb")
GOLDEN = Path(__file__).resolve().parent / "data" / "plan_v1_box_rotate.json"
"""A plan written by the code before plan.py existed (grasp.Plan.save, box_rotate.yaml, 1 iteration)."""


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
    k = 4
    steps[1] = replace(steps[1], path=StepPath(
        t=np.concatenate([[0.0], np.cumsum(rng.uniform(size=k - 1))]), q=rng.normal(size=(k, 16)),
        T_palm_object=np.stack([make_T(rpy_to_R(*rng.normal(size=3)), rng.normal(size=3)) for _ in range(k)]),
        phases=("lift", "transit", "touch_down"), ok=False, detail="a reason",
        metrics={"lift_height": float(rng.uniform()), "min_clearance": -1e-300}))
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
        assert (sa.path is None) == (sb.path is None)
        if sa.path is not None:
            for name in ("t", "q", "T_palm_object"):
                assert getattr(sa.path, name).tobytes() == getattr(sb.path, name).tobytes(), name
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


@pytest.mark.parametrize("version", [0, 3, "1", "2", True, 2.0])
def test_wrong_schema_version(version):
    d = _random_plan().to_dict()
    d["schema_version"] = version
    with pytest.raises(PlanFormatError, match=r"schema_version: expected 1 or 2, found"):
        Plan.from_dict(d)


def test_missing_schema_version_names_expected():
    d = _random_plan().to_dict()
    del d["schema_version"]
    assert SCHEMA_VERSION == 2
    with pytest.raises(PlanFormatError, match=r"schema_version: missing.*expected 1 or 2"):
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


_DELETE = object()


@pytest.mark.parametrize(
    "keys, value, pattern",
    [
        (("phases", 0), "teleport", r"steps\[1\]\.path\.phases\[0\]: expected one of lift, transit, "),
        (("speed",), 1.0, r"steps\[1\]\.path: unknown field 'speed'"),
        (("t",), [0.0, 2.0, 1.0, 3.0], r"steps\[1\]\.path\.t: expected time stamps from 0, non-decreasing"),
        (("q",), [[0.0] * 15] * 4, r"steps\[1\]\.path\.q: expected 16 joints per knot"),
        (("phases",), ["lift"], r"steps\[1\]\.path: a path needs k ≥ 2 knots"),
        (("interpolation",), "cubic", r"steps\[1\]\.path\.interpolation: expected one of linear, found"),
        (("metrics", "lift_height"), "high", r"steps\[1\]\.path\.metrics\.lift_height: expected a finite"),
        (("ok",), _DELETE, r"steps\[1\]\.path\.ok: missing field"),
    ],
)
def test_malformed_path_is_named(keys, value, pattern):
    d = _random_plan().to_dict()
    target = d["steps"][1]["path"]
    for k in keys[:-1]:
        target = target[k]
    if value is _DELETE:
        del target[keys[-1]]
    else:
        target[keys[-1]] = value
    with pytest.raises(PlanFormatError, match=pattern):
        Plan.from_dict(d)


def test_a_version_2_step_needs_its_path_field():
    d = _random_plan().to_dict()
    del d["steps"][2]["path"]
    with pytest.raises(PlanFormatError, match=r"steps\[2\]\.path: missing field"):
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


def test_step_certificates_round_trip_and_are_optional(tmp_path):
    plan = _random_plan()
    cert = {"kind": "gravity", "ok": True, "margin": 1.75, "forces": [[0.1, -0.0, 2.0]] * 4,
            "detail": "holds"}
    steps = (plan.steps[0], replace(plan.steps[1], certificate=cert), *plan.steps[2:])
    certified = replace(plan, steps=steps)
    assert certified != plan
    loaded = Plan.load(certified.save(tmp_path / "c.json"))
    assert loaded == certified and loaded.steps[1].certificate == cert and loaded.steps[2].certificate is None
    # a step without one writes no field (the paper's plans keep their files)
    assert "certificate" not in plan.to_dict()["steps"][1]
    for bad, pattern in (({**cert, "kind": "wobbly"}, r"steps\[1\]\.certificate\.kind: expected one of"),
                         ({**cert, "ok": 1}, r"steps\[1\]\.certificate\.ok: expected bool"),
                         ({**cert, "eps": 0.1}, r"steps\[1\]\.certificate: unknown field 'eps'")):
        d = certified.to_dict()
        d["steps"][1]["certificate"] = bad
        with pytest.raises(PlanFormatError, match=pattern):
            Plan.from_dict(d)


def test_plan_arrays_are_read_only():
    plan = _random_plan()
    with pytest.raises(ValueError):
        plan.steps[0].q[0] = 1.0




def test_final_error_and_summary_from_hand_set_errors():
    steps = list(_random_plan().steps)
    steps[-1] = replace(steps[-1], contact_error=np.array([0.001, 0.002, 0.003, 0.006]))
    plan = replace(_random_plan(), steps=tuple(steps), status="stalled", status_detail="no progress")
    assert plan.final_error == pytest.approx(0.003, abs=1e-15)  # (1 + 2 + 3 + 6) / 4 mm
    text = plan.summary()
    assert text.splitlines()[0] == "status: stalled (no progress)"
    assert "steps: 5 (1 initial, 2 gait, 1 repose, 1 final)" in text
    assert "final contact error: avg 3.00 mm, max 6.00 mm" in text
    assert np.isnan(replace(plan, steps=()).final_error)


# ------------------------------------------------------------------------------ the vocabularies
def test_vocabularies_are_the_literal_types():
    # every status plan_regrasp returns, plus "interrupted" (Ctrl-C), in a fixed order
    assert PLAN_STATUSES == ("converged", "iteration_limit", "stalled", "solver_failure", "invalid_input",
                             "interrupted", "pose_not_reached")
    assert STEP_KINDS == ("initial", "gait", "repose", "final", "slide")
    assert PLAN_METHODS == ("svd", "sd")


@pytest.mark.parametrize("status", PLAN_STATUSES)
@pytest.mark.parametrize("method", PLAN_METHODS)
def test_every_status_and_method_round_trips(status, method, tmp_path):
    plan = replace(_random_plan(), status=status, method=method)
    again = Plan.load(plan.save(tmp_path / "p.json"))
    assert (again.status, again.method) == (status, method)
    assert again == plan


def test_plan_written_before_the_split_loads_and_saves_as_version_2_losing_nothing(tmp_path):
    plan = Plan.load(GOLDEN)
    assert (plan.status, plan.method, plan.iterations) == ("iteration_limit", "svd", 1)
    assert [s.kind for s in plan.steps] == ["initial", "gait", "gait", "gait", "gait", "repose"]
    assert [s.finger for s in plan.steps[1:5]] == ["index", "middle", "ring", "thumb"]
    assert all(s.path is None for s in plan.steps)
    saved = json.loads(plan.save(tmp_path / "again.json").read_text(encoding="utf-8"))
    # version 2 = version 1 plus a null path per step; every other value is the golden file's
    assert saved["schema_version"] == 2 and [s.pop("path") for s in saved["steps"]] == [None] * 6
    golden = _golden_doc()
    del saved["schema_version"], golden["schema_version"]
    assert saved == golden
    assert Plan.load(tmp_path / "again.json") == plan


# ------------------------------------------------------------------------------ strict reading
def _golden_doc() -> dict:
    return json.loads(GOLDEN.read_text(encoding="utf-8"))


def _load_doc(tmp_path: Path, doc: dict, name: str = "plan.json") -> Plan:
    path = tmp_path / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    return Plan.load(path)


def _edit(doc: dict, keys: tuple, value) -> dict:
    target = doc
    for k in keys[:-1]:
        target = target[k]
    target[keys[-1]] = value
    return doc


@pytest.mark.parametrize(
    "keys, value, pattern",
    [
        (("plan_version",), 2, r"plan: unknown field 'plan_version' \(known: steps, "),
        (("steps", 3, "velocity"), [0.0], r"steps\[3\]: unknown field 'velocity' \(known: kind, finger, "),
        (("status",), "done", r"plan\.status: expected one of converged, iteration_limit, stalled, "
                              r"solver_failure, invalid_input, interrupted, pose_not_reached, found 'done'"),
        (("status",), 3, r"plan\.status: expected str, found int 3"),
        (("method",), "pose", r"plan\.method: expected one of svd, sd, found 'pose'"),
        (("steps", 2, "kind"), "roll", r"steps\[2\]\.kind: expected one of initial, gait, repose, final, "
                                       r"slide, found 'roll'"),
    ],
)
def test_unknown_fields_and_values_are_named_with_the_file(tmp_path, keys, value, pattern):
    doc = _edit(_golden_doc(), keys, value)
    with pytest.raises(PlanFormatError, match=rf"^{re.escape(str(tmp_path / 'plan.json'))}: {pattern}"):
        _load_doc(tmp_path, doc)


def test_two_unknown_fields_are_both_named(tmp_path):
    doc = {**_golden_doc(), "a": 1, "b": 2}
    with pytest.raises(PlanFormatError, match=r"plan: unknown fields 'a', 'b' \(known: "):
        _load_doc(tmp_path, doc)


@pytest.mark.parametrize(
    "old, new, key",
    [
        ('"status": "iteration_limit",', '"status": "iteration_limit", "status": "converged",', "status"),
        ('"kind": "repose",', '"kind": "repose", "kind": "gait",', "kind"),
        ('"opt2": 1', '"opt2": 1, "opt2": 2', "opt2"),  # inside options.solves
    ],
)
def test_duplicate_keys_are_refused(tmp_path, old, new, key):
    text = GOLDEN.read_text(encoding="utf-8")
    assert text.count(old) == 1
    path = tmp_path / "dup.json"
    path.write_text(text.replace(old, new), encoding="utf-8")
    with pytest.raises(PlanFormatError, match=rf"^{re.escape(str(path))}: duplicate key '{key}'"):
        Plan.load(path)
    path.write_text(text, encoding="utf-8")  # the same file without the duplicate loads
    assert Plan.load(path) == Plan.load(GOLDEN)


@pytest.mark.parametrize("data", [b"\xff\xfe{}", "{\"status\": \"\u00e9\"}".encode("latin-1"),
                                  '{"a": 1}'.encode("utf-16")])
def test_non_utf8_file_is_a_one_line_error_naming_the_file(tmp_path, data):
    path = tmp_path / "latin.json"
    path.write_bytes(data)
    with pytest.raises(PlanFormatError) as e:
        Plan.load(path)
    assert str(e.value).startswith(f"{path}: not a UTF-8 text file (byte ")
    assert "\n" not in str(e.value)


def test_unknown_values_are_refused_on_save_and_nothing_is_written(tmp_path):
    plan = _random_plan()
    steps = (*plan.steps[:-1], replace(plan.steps[-1], kind="roll"))
    cases = [(replace(plan, status="done"), r"^plan\.status: expected one of converged, "),
             (replace(plan, method="pose"), r"^plan\.method: expected one of svd, sd, found 'pose'"),
             (replace(plan, steps=steps), r"^steps\[4\]\.kind: expected one of initial, ")]
    for bad, pattern in cases:
        with pytest.raises(PlanFormatError, match=pattern):
            bad.save(tmp_path / "x.json")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------ nothing lost
def test_a_save_that_fails_midway_keeps_the_previous_file(tmp_path, monkeypatch):
    path = _random_plan(seed=1).save(tmp_path / "plan.json")
    before = path.read_bytes()

    def disk_full(fd, data):
        os.write(fd, bytes(data[: len(data) // 2]))
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(files, "_write_all", disk_full)
    with pytest.raises(OSError) as e:
        _random_plan(seed=2).save(path)
    assert e.value.errno == errno.ENOSPC
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["plan.json"]
    assert Plan.load(path) == _random_plan(seed=1)


# ------------------------------------------------------------------------------ plain data
def test_importing_and_using_plan_loads_no_model_code():
    code = (
        "import sys\n"
        "from regrasp_casadi.plan import Plan\n"
        f"plan = Plan.load({str(GOLDEN)!r})\n"
        "plan.to_dict(); plan.summary()\n"
        "print('\\n'.join(sorted(sys.modules)))\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(regrasp_casadi.__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    loaded = set(out.stdout.split())
    assert "regrasp_casadi.plan" in loaded
    model_code = {"casadi", "trimesh", "scipy", "yaml", "regrasp_casadi.hand", "regrasp_casadi.geometry",
                  "regrasp_casadi.objects", "regrasp_casadi.convex", "regrasp_casadi.signed_distance",
                  "regrasp_casadi.exact_distance", "regrasp_casadi.transforms", "regrasp_casadi.grasp",
                  "regrasp_casadi.problem", "regrasp_casadi.verify"}
    assert loaded & model_code == set()
    assert {m for m in loaded if m.startswith("regrasp_casadi.")} == {
        "regrasp_casadi.errors", "regrasp_casadi.files", "regrasp_casadi.grasp_metrics",
        "regrasp_casadi.motion", "regrasp_casadi.plan", "regrasp_casadi.plan_codec"}
