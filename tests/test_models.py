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
    hand = Hand.from_model(model_dir.name)  # the folder's hand.yaml names the URDF and the fingers
    assert hand.urdf_path == urdfs[0].resolve() and hand.spec() == {"model": model_dir.name}
    assert hand.metadata.source == (model_dir / "hand.yaml").resolve()
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


def _max_over_cone(d: np.ndarray, half_angle: float) -> float:
    """max of u·d over unit u within half_angle of +z (closed form: |d| if d is inside the cone, else
    |d| cos(angle between d and the cone's nearest boundary ray))."""
    n = float(np.linalg.norm(d))
    phi = float(np.arccos(np.clip(d[2] / n, -1.0, 1.0)))
    return n if phi <= half_angle else n * float(np.cos(phi - half_angle))


def test_allegro_distal_spheres_clear_every_contact_in_a_60deg_cone():
    """For each finger, every non-tip sphere (c, ρ) rigidly attached to the tip sphere (c_t, r) keeps β = 1 mm
    from the tangent plane of any fingertip contact whose outward normal u lies within 60° of the tip axis:
    u·(c − c_t) ≤ r − ρ − β. Rigid attachment and tip-frame positions come from Hand FK (URDF only)."""
    hand = Hand.allegro_right()
    beta, half_angle = 0.001, np.deg2rad(60.0)
    rng = np.random.default_rng(0)
    Q = [rng.uniform(hand.q_lower, hand.q_upper) for _ in range(3)]
    Ts = [hand.fk(q) for q in Q]
    # dense grid of cone directions (axis, rings, boundary) as an independent check of the closed form
    th, az = np.meshgrid(np.linspace(0.0, half_angle, 61), np.linspace(0.0, 2 * np.pi, 361))
    U = np.stack([np.sin(th) * np.cos(az), np.sin(th) * np.sin(az), np.cos(th)], axis=-1).reshape(-1, 3)
    for finger in hand.fingers:
        tip = next(s for s in hand.spheres if s.is_tip and s.finger == finger)
        rel = [np.linalg.inv(T[tip.link]) for T in Ts]
        rigid = [
            s for s in hand.spheres if not s.is_tip and all(
                np.allclose(R @ T[s.link], rel[0] @ Ts[0][s.link], atol=1e-12)
                for R, T in zip(rel, Ts, strict=True)
            )
        ]
        assert len(rigid) >= 3, finger  # the distal link's spheres (incl. the one behind the cap)
        assert {s.link for s in rigid} == {tip.link.removesuffix("_tip")}
        for s in rigid:
            T_tip_link = rel[0] @ Ts[0][s.link]
            d = T_tip_link[:3, :3] @ s.center_link + T_tip_link[:3, 3] - tip.center_link
            bound = tip.radius - s.radius - beta
            assert _max_over_cone(d, half_angle) <= bound, (s.label, _max_over_cone(d, half_angle), bound)
            assert float((U @ d).max()) <= _max_over_cone(d, half_angle) + 1e-12
            assert float((U @ d).max()) >= _max_over_cone(d, half_angle) - 1e-4 * np.linalg.norm(d)
