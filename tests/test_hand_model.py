"""A hand is data: its metadata (hand.yaml beside the URDF) names fingers, thumb, gait order, grasp region
and camera; a second hand is one model folder, with no code change."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from test_hand import _TINY_URDF

from regrasp_casadi.errors import ModelError, ProblemFileError
from regrasp_casadi.hand import Hand
from regrasp_casadi.planner import gait_pattern
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.viewer import Keyframe, camera_offset

MODELS = Path(__file__).resolve().parents[1] / "models"
ALLEGRO_DIR = MODELS / "allegro_right"

# a three-finger hand made of the Allegro URDF: renamed fingers, the ring finger dropped, thumb first
_THREE = {
    "schema_version": 1,
    "urdf": "three.urdf",
    "fingers": {"opposer": "link_15.0_tip", "first": "link_7.0_tip", "second": "link_3.0_tip"},
    "thumb": "opposer",
    "gait": {"forward": ["second", "first", "opposer"], "reversible": True},
    "grasp_region": {"lower": [0.05, -0.01, 0.01], "upper": [0.1, 0.04, 0.06]},
}


def _model_folder(root: Path, meta: dict, name: str = "three") -> Path:
    folder = root / name
    folder.mkdir()
    shutil.copy(ALLEGRO_DIR / "allegro_right.urdf", folder / f"{name}.urdf")
    (folder / "hand.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    return folder


@pytest.fixture()
def three(tmp_path) -> Hand:
    return Hand.from_model(_model_folder(tmp_path, _THREE))


def test_allegro_metadata_is_its_hand_yaml(hand):
    meta = yaml.safe_load((ALLEGRO_DIR / "hand.yaml").read_text())
    assert hand.tip_links == meta["fingers"] and hand.fingers == tuple(meta["fingers"])
    assert hand.thumb == meta["thumb"] == "thumb"
    assert hand.gait_forward == tuple(meta["gait"]["forward"]) and hand.metadata.gait_reversible
    np.testing.assert_array_equal(hand.grasp_region[0], meta["grasp_region"]["lower"])
    np.testing.assert_array_equal(hand.grasp_region[1], meta["grasp_region"]["upper"])
    assert hand.metadata.camera.lift_palm == tuple(meta["viewer"]["lift"])
    assert hand.metadata.source == (ALLEGRO_DIR / "hand.yaml").resolve()


def test_second_hand_is_one_model_folder(three, tmp_path):
    assert three.fingers == ("opposer", "first", "second") and three.thumb == "opposer"
    assert three.gait_forward == ("second", "first", "opposer")
    # the joints that move each finger follow from the URDF tree: link_7.0_tip hangs on joint_4.0..7.0
    moving = [three.joint_names[i] for i in three.finger_joints["first"]]
    assert moving == [f"joint_{k}.0" for k in range(4, 8)]
    np.testing.assert_array_equal(three.grasp_region[0], [0.05, -0.01, 0.01])
    # a hand outside the shipped models is rebuilt from its URDF path, hand.yaml included
    assert three.spec() == {"urdf": str(tmp_path / "three" / "three.urdf")}
    again = Hand.from_spec(three.spec())
    assert again.fingers == three.fingers and again.thumb == three.thumb
    assert again.gait_forward == three.gait_forward


def test_gait_pattern_comes_from_the_model_folder(three):
    """forward[0] = "second" (row 2), forward[1] = "first" (row 1): forward when the goal of "second" is
    farther from the contact of "first" than from its own."""
    contacts = np.array([[5.0, 5.0, 5.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    goal = contacts.copy()
    goal[2] = [1.1, 0.0, 0.0]  # 1.1 from "first", 0.1 from its own
    assert gait_pattern(three, contacts, goal) == ("second", "first", "opposer")
    goal[2] = [0.1, 0.0, 0.0]  # 0.1 from "first", 0.9 from its own
    assert gait_pattern(three, contacts, goal) == ("opposer", "first", "second")


def test_camera_looks_across_the_thumb_of_the_metadata(three):
    """The thumb is row 0 of this hand: the camera must equal the one of the same scene with the thumb's
    row moved last and no hand (whose opposing finger is the last)."""
    T_palm_object = np.eye(4)
    T_palm_object[:3, 3] = [0.1, 0.0, 0.05]
    p = np.array([[0.09, 0.06, 0.0], [0.1, -0.02, 0.08], [0.1, 0.03, 0.09]])
    links = three.fk(three.q_mid())

    def frame(p_palm_contacts):
        return Keyframe(0.0, 0, 1.0, "initial", None, three.q_mid(), links, T_palm_object, p_palm_contacts)

    centre = np.array([0.05, 0.0, 0.05])
    off = camera_offset([frame(p)], centre, 0.2, three)
    np.testing.assert_array_equal(off, camera_offset([frame(np.roll(p, -1, axis=0))], centre, 0.2))
    assert not np.allclose(off, camera_offset([frame(p)], centre, 0.2))


def test_problem_file_names_a_model_folder(tmp_path):
    folder = tmp_path / "tiny"
    folder.mkdir()
    (folder / "tiny.urdf").write_text(_TINY_URDF)
    (folder / "hand.yaml").write_text("schema_version: 1\nurdf: tiny.urdf\nfingers: {tip: tip}\n")
    problem = tmp_path / "p.yaml"
    problem.write_text(yaml.safe_dump({
        "schema_version": 1, "hand": {"model": "./tiny"},
        "object": {"primitive": "box", "extents": [0.05] * 3},
        "grasp0": {"joints": [0.0], "T_palm_object": {"xyz": [0.1, 0, 0], "rpy": [0, 0, 0]}},
        "grasp_goal": {"contacts": {}, "T_palm_object": {"xyz": [0.1, 0, 0], "rpy": [0, 0, 0]}},
    }))
    # the hand of the folder beside the file (2 joints) was loaded before the joint count was checked
    with pytest.raises(ProblemFileError, match="grasp0.joints: expected 2 joint angles for tiny, got 1"):
        RegraspProblem.load(problem)


def test_urdf_without_metadata_falls_back(tmp_path):
    path = tmp_path / "tiny.urdf"
    path.write_text(_TINY_URDF)
    tiny = Hand.from_urdf(path)
    assert tiny.thumb is None and tiny.gait_forward == tiny.fingers == ("tip",)
    assert not tiny.metadata.gait_reversible and tiny.metadata.source is None
    # the grasp region falls back to the tips at mid-range: hinge 0, slide 0.025 -> tip (0.3, 0.025, 0.06)
    for corner in tiny.grasp_region:
        np.testing.assert_allclose(corner, [0.3, 0.025, 0.06], atol=1e-15)


def test_fallback_gait_is_the_finger_order_whatever_the_contacts(tmp_path):
    folder = _model_folder(tmp_path, _THREE)
    two = Hand.from_urdf(folder / "three.urdf", fingers={"b": "link_3.0_tip", "a": "link_7.0_tip"})
    contacts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    for goal_b in ([0.1, 0.0, 0.0], [0.9, 0.0, 0.0]):
        assert gait_pattern(two, contacts, np.array([goal_b, [1.0, 0.0, 0.0]])) == ("b", "a")
    # fingers that differ from hand.yaml drop its finger entries, keep the hand-level ones
    assert two.thumb is None and two.metadata.grasp_region == ((0.05, -0.01, 0.01), (0.1, 0.04, 0.06))
    fingers = {"b": "link_3.0_tip", "a": "link_7.0_tip"}
    assert two.spec() == {"urdf": str(folder / "three.urdf"), "fingers": fingers}


def test_shipped_urdf_by_path_is_the_shipped_model(hand):
    by_path = Hand.from_urdf(hand.urdf_path)
    assert by_path.spec() == {"model": "allegro_right"} and by_path.thumb == "thumb"
    reordered = Hand.from_urdf(hand.urdf_path, fingers=dict(reversed(list(hand.tip_links.items()))))
    assert reordered.spec()["fingers"] == dict(reversed(list(hand.tip_links.items())))


@pytest.mark.parametrize("change,match", [
    ({"thumb": "pinky"}, r"hand.yaml: thumb: 'pinky' is not a finger"),
    ({"fingers": {"first": "link_99_tip"}}, r"hand.yaml: fingers.first: tip link 'link_99_tip'"),
    ({"gait": {"forward": ["first", "opposer"]}}, r"hand.yaml: gait.forward: expected a permutation"),
    ({"gait": {"forward": ["second", "first", "opposer"], "reversible": "yes"}}, r"gait.reversible"),
    ({"grasp_region": {"lower": [0, 0, 1], "upper": [1, 1, 0]}}, r"grasp_region: lower .* exceeds upper"),
    ({"viewer": {"lift": [0, 1]}}, r"viewer.lift: expected a list of 3"),
    ({"viewer": {"colors": {"pinky": "#ff0000"}}}, r"viewer.colors.pinky: not a part of the hand"),
    ({"viewer": {"colors": {"first": "red"}}}, r"viewer.colors.first: expected a colour '#rrggbb', got"),
    ({"viewer": {"colors": {"palm": None}}}, r"viewer.colors.palm: .* got None \(quote it: # starts a YAML"),
    ({"viewer": {"colors": ["#ff0000"]}}, r"viewer.colors: expected a mapping"),
    ({"colour": "red"}, r"hand.yaml: colour: unknown key"),
    ({"schema_version": 2}, r"hand.yaml: schema_version: expected 1"),
])
def test_invalid_metadata_names_the_file_and_key(tmp_path, change, match):
    meta = {**_THREE, **change}
    if change.get("fingers"):
        meta["thumb"], meta["gait"] = None, {}
    with pytest.raises(ModelError, match=match):
        Hand.from_model(_model_folder(tmp_path, meta))


def test_unknown_model_and_folder_without_metadata(tmp_path):
    with pytest.raises(ModelError, match="unknown hand model 'shadow'.*'allegro_right'"):
        Hand.from_model("shadow")
    with pytest.raises(ModelError, match="not a hand model folder"):
        Hand.from_model(tmp_path)
