"""Problem files (YAML): a valid file loads into validated grasps; every error names the file and key."""

from __future__ import annotations

import copy
import errno
import os
from pathlib import Path

import numpy as np
import pytest
import twofinger as tf
import yaml

from regrasp_casadi import files
from regrasp_casadi.errors import ModelError, ProblemFileError
from regrasp_casadi.plan import Plan
from regrasp_casadi.problem import RegraspProblem, clear_model_cache, plan_models
from regrasp_casadi.transforms import make_T, rpy_to_R

RPY = [0.0, 0.0, 0.3]


def _valid_doc() -> dict:
    """Two-finger hand (URDF next to the file) holding the box; goal: box turned 0.3 rad about z."""
    return {
        "schema_version": 1,
        "description": "two-finger box test",
        "hand": {"urdf": "hand/twofinger.urdf", "fingers": {"left": "left_tip", "right": "right_tip"}},
        "object": {"primitive": "box", "extents": list(tf.BOX_EXTENTS)},
        "grasp0": {
            "joints": [0.0, -0.005, 0.0, 0.0, 0.0, 0.0],
            "T_palm_object": tf.box_pose().tolist(),
        },
        "grasp_goal": {
            "contacts": {"left": [-0.03, 0.01, 0.0], "right": [0.03, -0.01, 0.002]},
            "T_palm_object": {"xyz": [0.0, 0.0, 0.11], "rpy": RPY},
        },
    }


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("problems")
    (d / "hand").mkdir()
    tf.make_hand(d / "hand")
    return d


def _write(folder, doc, name="p.yaml"):
    path = folder / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_load_valid_file(folder):
    problem = RegraspProblem.load(_write(folder, _valid_doc(), "box_turn.yaml"))
    assert problem.name == "box_turn"  # default: the file stem
    assert problem.description == "two-finger box test"
    assert problem.hand.fingers == ("left", "right")
    assert problem.obj.spec["extents"] == list(tf.BOX_EXTENTS)
    # tips at (∓0.04, 0, 0.11 + slide), box centred at (0, 0, 0.11): contacts on the ±x faces
    assert np.allclose(problem.grasp0.contacts_object, [[-0.03, 0, -0.005], [0.03, 0, 0]], atol=1e-12)
    assert np.array_equal(problem.grasp_goal.contacts_object, [[-0.03, 0.01, 0.0], [0.03, -0.01, 0.002]])
    assert np.allclose(problem.grasp_goal.T_palm_object, make_T(rpy_to_R(*RPY), [0, 0, 0.11]), atol=1e-15)
    assert problem.grasp_goal.q is None
    assert problem.grasp0.hand is problem.hand and problem.grasp_goal.obj is problem.obj


def test_joints_as_mapping_equal_list(folder):
    doc = _valid_doc()
    names = ["left_base", "left_slide", "left_roll", "right_base", "right_slide", "right_roll"]
    doc["grasp0"]["joints"] = dict(zip(reversed(names), reversed(doc["grasp0"]["joints"]), strict=True))
    problem = RegraspProblem.load(_write(folder, doc))
    assert np.array_equal(problem.grasp0.q, [0.0, -0.005, 0.0, 0.0, 0.0, 0.0])


def test_save_load_round_trip(folder, tmp_path):
    problem = RegraspProblem.load(_write(folder, _valid_doc(), "rt.yaml"))
    out = tmp_path / "elsewhere" / "copy.yaml"
    out.parent.mkdir()
    problem.save(out)
    assert not yaml.safe_load(out.read_text())["hand"]["urdf"].startswith("/")  # written relative
    again = RegraspProblem.load(out)
    assert again.name == "rt"
    for a, b in [(problem.grasp0, again.grasp0), (problem.grasp_goal, again.grasp_goal)]:
        assert np.array_equal(a.T_palm_object, b.T_palm_object)
        assert np.array_equal(a.contacts_object, b.contacts_object)
        assert (a.q is None and b.q is None) or np.array_equal(a.q, b.q)
    assert again.obj.spec == problem.obj.spec
    assert again.hand.spec() == problem.hand.spec()


def test_the_object_mass_is_read_and_written_and_kept_out_of_the_spec(folder, tmp_path):
    doc = copy.deepcopy(_valid_doc())
    assert RegraspProblem.load(_write(folder, doc, "nomass.yaml")).object_mass is None
    doc["object"]["mass"] = 0.25
    problem = RegraspProblem.load(_write(folder, doc, "mass.yaml"))
    assert problem.object_mass == 0.25
    assert "mass" not in problem.obj.spec  # the geometry's spec: the mass is the problem's
    again = RegraspProblem.load(problem.save(tmp_path / "mass_copy.yaml"))
    assert again.object_mass == 0.25 and again.obj.spec == problem.obj.spec


def test_the_gravity_is_read_resolved_and_written(folder, tmp_path):
    """`gravity`: absent (None), a palm-frame vector (kept as given), or "support" (kept as the word in
    the file, resolved by `gravity_palm` to `hand_orientation.supporting_gravity` of grasp0); both
    survive a save and load."""
    from regrasp_casadi.hand_orientation import supporting_gravity

    doc = copy.deepcopy(_valid_doc())
    plain = RegraspProblem.load(_write(folder, doc, "nogravity.yaml"))
    assert plain.gravity is None and plain.gravity_palm is None
    doc["gravity"] = [0.0, -9.81, 0.0]
    vector = RegraspProblem.load(_write(folder, doc, "gravity.yaml"))
    assert vector.gravity == vector.gravity_palm == (0.0, -9.81, 0.0)
    assert RegraspProblem.load(vector.save(tmp_path / "gravity_copy.yaml")).gravity == (0.0, -9.81, 0.0)
    doc["gravity"] = "support"
    support = RegraspProblem.load(_write(folder, doc, "support.yaml"))
    assert support.gravity == "support"
    np.testing.assert_allclose(support.gravity_palm, supporting_gravity(support.grasp0), atol=1e-12)
    assert np.isclose(np.linalg.norm(support.gravity_palm), 9.81)
    assert RegraspProblem.load(support.save(tmp_path / "support_copy.yaml")).gravity == "support"


def _set(doc, keys, value):
    target = doc
    for k in keys[:-1]:
        target = target[k]
    if value is KeyError:
        del target[keys[-1]]
    else:
        target[keys[-1]] = value


@pytest.mark.parametrize(
    "keys, value, message",
    [
        (("grasp_goal", "contacts", "right"), [0.03, 0.0],
         "grasp_goal.contacts.right: expected 3 numbers, got 2"),
        (("grasp_goal", "contacts", "left", 1), "x",
         r"grasp_goal.contacts.left\[1\]: expected a finite number"),
        (("grasp_goal", "contacts", "thumb"), [0, 0, 0], r"grasp_goal.contacts: unknown key\(s\) thumb"),
        (("grasp_goal", "contacts", "left"), KeyError, "grasp_goal.contacts: missing key 'left'"),
        (("grasp_gaol",), {}, r"unknown key\(s\) grasp_gaol"),
        (("grasp0",), KeyError, "missing key 'grasp0'"),
        (("schema_version",), 2, "schema_version: expected 1, found 2"),
        (("object", "extent"), [0.1, 0.1, 0.1], r"object: unknown key\(s\) extent"),
        (("object", "primitive"), "pyramid", "object.primitive: unknown primitive 'pyramid'"),
        (("object", "extents"), [0.05, -0.09, 0.1], "object.extents: expected positive sizes"),
        (("object", "mesh"), "x.obj", "object: give exactly one of 'primitive' or 'mesh'"),
        (("hand",), "shadow_hand", "hand: unknown hand model 'shadow_hand'"),
        (("hand", "urdf"), "nope.urdf", "hand.urdf: file not found"),
        (("grasp0", "joints"), [0.0] * 5, "grasp0.joints: expected 6 joint angles for twofinger, got 5"),
        (("grasp0", "joints"), {"left_base": 0.0}, r"grasp0.joints: missing joint\(s\) left_slide"),
        (("grasp0", "T_palm_object"), {"xyz": [0, 0, 0.11], "rpy": [0, 0]},
         "grasp0.T_palm_object.rpy: expected 3 numbers, got 2"),
        (("grasp0", "T_palm_object"), {"xyz": [0.01, 0, 0.11], "rpy": [0, 0, 0]},
         r"grasp0: left tip is 10.0 mm off the object surface \(tolerance 0.5 mm\)"),
        (("grasp0", "T_palm_object", 0, 0), 2.0, "grasp0: T_palm_object: rotation is not orthonormal"),
        (("grasp0", "joints", 2), 1.5, "grasp0: joint left_roll = 1.5 rad is outside its limits"),
        (("grasp_goal", "contacts", "right"), [0.032, 0.0, 0.0],
         "grasp_goal: right contact is 2.0 mm off the object surface"),
        (("grasp_goal", "joints"), [0.0], "grasp_goal.joints: expected 6 joint angles"),
        (("description",), 5, "description: expected a string"),
        (("object", "mass"), -0.2, r"object.mass: expected a positive number \(kg\), got -0.2"),
        (("object", "mass"), "heavy", r"object.mass: expected a positive number \(kg\), got 'heavy'"),
        (("gravity",), [0.0, -9.81], "gravity: expected 3 numbers, got 2"),
        (("gravity",), "down", r"gravity: expected \[x, y, z\] \(m/s\^2, palm frame\) or 'support'"),
    ],
)
def test_errors_name_file_and_key(folder, keys, value, message):
    doc = copy.deepcopy(_valid_doc())
    _set(doc, keys, value)
    path = _write(folder, doc, "bad.yaml")
    with pytest.raises(ProblemFileError, match=rf"^{path}: {message}"):
        RegraspProblem.load(path)


def test_unreadable_files(folder):
    bad = folder / "broken.yaml"
    bad.write_text("grasp0: [unclosed\n")
    with pytest.raises(ProblemFileError, match=rf"^{bad}: invalid YAML"):
        RegraspProblem.load(bad)
    with pytest.raises(ProblemFileError, match=r"missing\.yaml: cannot read problem file"):
        RegraspProblem.load(folder / "missing.yaml")
    lst = _write(folder, [1, 2], "list.yaml")
    with pytest.raises(ProblemFileError, match="expected a mapping at the top level"):
        RegraspProblem.load(lst)


def test_a_save_that_fails_midway_keeps_the_previous_problem_file(folder, tmp_path, monkeypatch):
    problem = RegraspProblem.load(_write(folder, _valid_doc(), "keep.yaml"))
    out = problem.save(tmp_path / "copy.yaml")
    before = out.read_bytes()

    def disk_full(fd, data):
        os.write(fd, bytes(data[: len(data) // 2]))
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(files, "_write_all", disk_full)
    with pytest.raises(OSError) as e:
        problem.save(out)
    assert e.value.errno == errno.ENOSPC
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["copy.yaml"]


# ------------------------------------------------------------------------------ plan_models
def _plan(hand_spec: dict, object_spec: dict) -> Plan:
    """A plan with no steps: plan_models reads only its specs."""
    return Plan(steps=(), goal_contacts_object=np.zeros((2, 3)), goal_T_palm_object=np.eye(4),
                fingers=("left", "right"), hand_spec=hand_spec, object_spec=object_spec, method="svd",
                status="invalid_input", status_detail="", iterations=0, iteration_errors=np.zeros(1),
                timing={}, options={})


def test_plan_models_rebuild_from_the_specs_once_per_spec(folder, tmp_path):
    problem = RegraspProblem.load(_write(folder, _valid_doc(), "models.yaml"))
    clear_model_cache()
    plan = _plan(problem.hand.spec(), dict(problem.obj.spec))
    hand, obj = plan_models(plan)
    assert hand is not problem.hand and obj is not problem.obj  # rebuilt, not borrowed
    assert hand.spec() == problem.hand.spec() and obj.spec == problem.obj.spec
    assert np.array_equal(hand.tip_positions(problem.grasp0.q), problem.hand.tip_positions(problem.grasp0.q))
    # a second plan with equal specs (here: read back from its file) gets the same models
    again = Plan.load(plan.save(tmp_path / "p.json"))
    assert plan_models(again)[0] is hand and plan_models(again)[1] is obj
    # a changed URDF file is read again; the object spec did not change
    urdf = Path(problem.hand.spec()["urdf"])
    st = urdf.stat()
    os.utime(urdf, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    hand2, obj2 = plan_models(plan)
    assert hand2 is not hand and obj2 is obj
    clear_model_cache()
    assert plan_models(plan)[1] is not obj


def test_plan_models_use_the_models_given_without_building(folder):
    problem = RegraspProblem.load(_write(folder, _valid_doc(), "given.yaml"))
    plan = _plan({"model": "no_such_hand"}, {"primitive": "no_such_primitive"})
    assert plan_models(plan, problem.hand, problem.obj) == (problem.hand, problem.obj)
    with pytest.raises(ModelError, match="no_such_hand"):
        plan_models(plan, None, problem.obj)


@pytest.mark.parametrize(
    "key, value, message",
    [
        ("scale", 0, "object.scale: expected a positive number, got 0"),
        ("scale", -0.001, "object.scale: expected a positive number, got -0.001"),
        ("scale", float("nan"), "object.scale: expected a positive number, got nan"),
        ("scale", "mm", "object.scale: expected a positive number, got 'mm'"),
        ("scale", True, "object.scale: expected a positive number, got True"),
        ("threshold", 0.0, "object.threshold: expected a positive number"),
        ("max_planes_per_piece", 2.5, "object.max_planes_per_piece: expected an integer ≥ 4"),
        ("hull_tolerance", -1e-3, "object.hull_tolerance: expected a number ≥ 0"),
        ("sha256", 123, "object.sha256: expected a hex string"),
    ],
)
def test_mesh_object_options_name_the_key(folder, key, value, message):
    import trimesh

    trimesh.creation.box(extents=tf.BOX_EXTENTS).export(folder / "box.stl")
    doc = copy.deepcopy(_valid_doc())
    doc["object"] = {"mesh": "box.stl", key: value}
    path = _write(folder, doc, "bad_mesh.yaml")
    with pytest.raises(ProblemFileError, match=rf"^{path}: {message}"):
        RegraspProblem.load(path)


@pytest.mark.parametrize("primitive", ["bowl", "cup", "mug", "flat_tool", "holed_box"])
def test_new_primitives_are_known_to_problem_files(folder, primitive):
    """The generated objects load from problem files; unknown parameters name the key (checked before any
    mesh is built or decomposed)."""
    doc = copy.deepcopy(_valid_doc())
    doc["object"] = {"primitive": primitive, "no_such_size": 0.1}
    path = _write(folder, doc, "prim.yaml")
    with pytest.raises(ProblemFileError, match=rf"^{path}: object: unknown key\(s\) no_such_size \(allowed: "
                                               rf"primitive, .*threshold, max_planes_per_piece\)"):
        RegraspProblem.load(path)


def test_problem_files_know_every_primitive_and_its_dimensions():
    import inspect

    from regrasp_casadi import problem
    from regrasp_casadi.objects import PRIMITIVES, ObjectModel

    assert problem._PRIMITIVES == PRIMITIVES
    for kind, dims in problem._PRIMITIVE_DIMENSIONS.items():
        params = inspect.signature(getattr(ObjectModel, kind)).parameters
        assert set(dims) <= set(params), kind
