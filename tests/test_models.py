"""Collection tests over every shipped hand model in models/*/ (menagerie style)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
import yourdfpy

from regrasp_casadi.hand import Hand

MODELS = Path(__file__).resolve().parents[1] / "models"
MODEL_DIRS = sorted(p for p in MODELS.iterdir() if p.is_dir() and not p.name.startswith(("_", ".")))


def test_there_is_at_least_the_allegro_model():
    assert MODELS / "allegro_right" in MODEL_DIRS


@pytest.mark.parametrize("model_dir", MODEL_DIRS, ids=lambda p: p.name)
def test_model_folder_is_complete_and_loads(model_dir):
    urdfs = sorted(model_dir.glob("*.urdf"))
    assert [u.name for u in urdfs] == [f"{model_dir.name}.urdf"]
    for name in ("README.md", "LICENSE", "CHANGELOG.md"):
        assert (model_dir / name).is_file(), name
        assert (model_dir / name).read_text().strip(), name
    ref = yourdfpy.URDF.load(str(urdfs[0]), load_meshes=False, build_collision_scene_graph=False)
    hand = Hand.from_urdf(urdfs[0])
    assert hand.joint_names == tuple(ref.actuated_joint_names)
    assert hand.root_link == ref.base_link
    assert np.all(hand.q_lower < hand.q_upper)
    # every link carries at least one collision sphere (the project's models are sphere-covered)
    assert {s.link for s in hand.spheres} == set(hand.link_names)


def test_allegro_license_and_tip_geometry():
    d = MODELS / "allegro_right"
    assert "BSD" in (d / "LICENSE").read_text() and "Redistribution" in (d / "LICENSE").read_text()
    hand = Hand.allegro_right()
    tips = [s for s in hand.spheres if s.is_tip]
    assert [s.link for s in tips] == ["link_3.0_tip", "link_7.0_tip", "link_11.0_tip", "link_15.0_tip"]
    for s in tips:
        assert s.radius == 0.014
        np.testing.assert_array_equal(s.center_link, [0.0, 0.0, 0.002])


def test_allegro_urdf_is_what_generate_py_writes():
    d = MODELS / "allegro_right"
    spec = importlib.util.spec_from_file_location("allegro_generate", d / "generate.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    cover = json.loads((d / "sphere_cover.json").read_text())
    assert gen.build_urdf(cover) == (d / "allegro_right.urdf").read_text()


@pytest.mark.reference_data
def test_allegro_joints_equal_vendor_joints(reference_dir):
    ours = yourdfpy.URDF.load(
        str(MODELS / "allegro_right" / "allegro_right.urdf"),
        load_meshes=False,
        build_collision_scene_graph=False,
    )
    vendor = yourdfpy.URDF.load(
        str(reference_dir / "allegro_right" / "allegro_hand_right.urdf"),
        load_meshes=False,
        build_collision_scene_graph=False,
    )
    assert [link.name for link in ours.robot.links] == [link.name for link in vendor.robot.links]
    for a, b in zip(ours.robot.joints, vendor.robot.joints, strict=True):
        assert (a.name, a.type, a.parent, a.child) == (b.name, b.type, b.parent, b.child)
        np.testing.assert_allclose(a.origin, b.origin, atol=1e-12)
        if a.type != "fixed":
            np.testing.assert_array_equal(a.axis, b.axis)
            assert (a.limit.lower, a.limit.upper) == (b.limit.lower, b.limit.upper)
