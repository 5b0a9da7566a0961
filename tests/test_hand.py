"""Tests of regrasp_casadi.hand: SX FK against yourdfpy, golden poses, Jacobians, sphere cover."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yourdfpy
from scipy.optimize import least_squares

from regrasp_casadi.errors import ModelError
from regrasp_casadi.hand import Hand

N_CONFIGS = 100


def _rot_err(Ra: np.ndarray, Rb: np.ndarray) -> float:
    """Rotation angle (rad) of Ra^T Rb, accurate for small angles (from the skew part)."""
    D = Ra.T @ Rb
    w = 0.5 * np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])
    return float(np.arctan2(np.linalg.norm(w), 0.5 * (np.trace(D) - 1.0)))


def _compare_with_yourdfpy(hand: Hand, urdf_path: Path) -> tuple[float, float]:
    ref = yourdfpy.URDF.load(str(urdf_path), load_meshes=False, build_collision_scene_graph=False)
    assert tuple(ref.actuated_joint_names) == hand.joint_names
    rng = np.random.default_rng(1)
    max_p = max_r = 0.0
    for _ in range(N_CONFIGS):
        q = rng.uniform(hand.q_lower, hand.q_upper)
        ref.update_cfg(q)
        T = hand.fk(q)
        assert set(T) == {link.name for link in ref.robot.links}
        for f, R_palm_tiplink in zip(hand.fingers, hand.tip_rotations(q), strict=True):  # the tips alone
            R_ref = ref.get_transform(hand.tip_links[f], ref.base_link)[:3, :3]
            max_r = max(max_r, _rot_err(R_palm_tiplink, R_ref))
        for link, T_palm_link in T.items():
            T_ref = ref.get_transform(link, ref.base_link)
            max_p = max(max_p, float(np.abs(T_palm_link[:3, 3] - T_ref[:3, 3]).max()))
            max_r = max(max_r, _rot_err(T_palm_link[:3, :3], T_ref[:3, :3]))
    return max_p, max_r


def test_fk_matches_yourdfpy_shipped_model(hand):
    max_p, max_r = _compare_with_yourdfpy(hand, hand.urdf_path)
    assert max_p <= 1e-9 and max_r <= 1e-9


@pytest.mark.reference_data
def test_fk_matches_yourdfpy_vendor_urdf(reference_dir):
    path = reference_dir / "allegro_right" / "allegro_hand_right.urdf"
    vendor = Hand.from_urdf(path)
    max_p, max_r = _compare_with_yourdfpy(vendor, path)
    assert max_p <= 1e-9 and max_r <= 1e-9


# SOURCE.md, "FK values to test against": tip link origins in palm_link, m (6 decimals)
_Q_SOURCE = {
    "zero": np.zeros(16),
    "bent": np.array([0, 0.5, 0.5, 0.5] * 3 + [1.0, 0.5, 0.5, 0.5]),
}
_TIP_ORIGINS = {
    "zero": [(0, 0.05531, 0.133442), (0, 0, 0.1362), (0, -0.05531, 0.133442), (-0.0132, 0.167704, -0.086071)],
    "bent": [
        (0.084835, 0.051033, 0.084555),
        (0.084835, 0, 0.087126),
        (0.084835, -0.051033, 0.084555),
        (0.105762, 0.060771, -0.023651),
    ],
}


@pytest.mark.parametrize("case", ["zero", "bent"])
def test_tip_link_origins_match_vendor_golden_values(hand, case):
    q = _Q_SOURCE[case]
    T = hand.fk(q)
    tips = hand.tip_positions(q)
    for k, finger in enumerate(hand.fingers):
        T_palm_tip = T[hand.tip_links[finger]]
        np.testing.assert_allclose(T_palm_tip[:3, 3], _TIP_ORIGINS[case][k], atol=1.5e-6)
        # the contact point is the 14 mm sphere centre, 2 mm beyond the tip link origin along its z axis
        np.testing.assert_allclose(tips[k], T_palm_tip[:3, 3] + 0.002 * T_palm_tip[:3, 2], atol=1e-12)


_TINY_URDF = """<?xml version="1.0"?>
<robot name="tiny">
  <link name="base"><collision><origin xyz="0 0 -0.01"/><geometry><sphere radius="0.02"/></geometry>
  </collision></link>
  <link name="arm"><collision><origin xyz="0.1 0 0"/><geometry><sphere radius="0.015"/></geometry>
  </collision></link>
  <link name="slider"/>
  <link name="tip"><collision name="tip_contact">
  <origin xyz="0 0 0.01"/><geometry><sphere radius="0.01"/></geometry>
  </collision></link>
  <joint name="hinge" type="revolute">
    <parent link="base"/><child link="arm"/><origin xyz="0.1 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2.0" upper="2.0" effort="1" velocity="1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="arm"/><child link="slider"/><origin xyz="0.2 0 0" rpy="0 0 1.5707963267948966"/>
    <axis xyz="1 0 0"/><limit lower="0.0" upper="0.05" effort="1" velocity="1"/>
  </joint>
  <joint name="tip_fixed" type="fixed">
    <parent link="slider"/><child link="tip"/><origin xyz="0 0 0.05"/>
  </joint>
</robot>
"""


@pytest.fixture()
def tiny(tmp_path):
    path = tmp_path / "tiny.urdf"
    path.write_text(_TINY_URDF)
    return Hand.from_urdf(path)


@pytest.mark.parametrize("theta,d", [(0.0, 0.0), (math.pi / 2, 0.03), (-0.7, 0.05)])
def test_tiny_urdf_golden_poses(tiny, theta, d):
    """link 'slider' = Trans(0.1,0,0) Rz(θ) Trans(0.2,0,0) Rz(π/2) Trans(d,0,0), worked out by hand."""
    c, s = math.cos(theta), math.sin(theta)
    T = tiny.fk([theta, d])
    p_slider = np.array([0.1 + 0.2 * c - d * s, 0.2 * s + d * c, 0.0])
    np.testing.assert_allclose(T["arm"][:3, 3], [0.1, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(T["slider"][:3, 3], p_slider, atol=1e-15)
    a = theta + math.pi / 2
    np.testing.assert_allclose(
        T["slider"][:3, :3],
        [[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]],
        atol=1e-15,
    )
    np.testing.assert_allclose(T["tip"][:3, 3], p_slider + [0, 0, 0.05], atol=1e-15)
    np.testing.assert_allclose(tiny.tip_positions([theta, d]), [p_slider + [0, 0, 0.06]], atol=1e-15)
    np.testing.assert_allclose(
        tiny.sphere_centers([theta, d]), [[0, 0, -0.01], [0.1 + 0.1 * c, 0.1 * s, 0]], atol=1e-15
    )


def test_tiny_urdf_structure(tiny):
    assert tiny.joint_names == ("hinge", "slide")
    assert tiny.fingers == ("tip",) and tiny.tip_links == {"tip": "tip"}
    np.testing.assert_array_equal(tiny.finger_joints["tip"], [0, 1])
    np.testing.assert_array_equal(tiny.q_lower, [-2.0, 0.0])
    assert tiny.tip_radius == 0.01
    assert [(s.link, s.finger, s.is_tip) for s in tiny.spheres] == [
        ("base", None, False),
        ("arm", "tip", False),
        ("tip", "tip", True),
    ]
    assert tiny.check_limits([2.5, 0.01]) == [("hinge", 2.5, -2.0, 2.0)]
    assert tiny.check_limits([2.0 + 1e-12, 0.05]) == []
    np.testing.assert_array_equal(tiny.clip([2.5, -1.0]), [2.0, 0.0])
    assert Hand.from_spec(tiny.spec()).spec() == tiny.spec() == {"urdf": str(tiny.urdf_path)}


def test_allegro_structure_and_spec(hand):
    assert hand.name == "allegro_right" and hand.root_link == "palm_link"
    assert hand.fingers == ("index", "middle", "ring", "thumb")
    for k, f in enumerate(hand.fingers):
        np.testing.assert_array_equal(hand.finger_joints[f], np.arange(4 * k, 4 * k + 4))
    assert hand.tip_radius == 0.014
    assert hand.spec() == {"model": "allegro_right"}
    assert Hand.from_spec({"model": "allegro_right"}).urdf_path == hand.urdf_path
    # every non-tip sphere on a finger link belongs to the finger whose joints move it; palm spheres to None
    for s in hand.spheres:
        if s.is_tip:
            continue
        if s.link == "palm_link":
            assert s.finger is None
        else:
            i = int(s.link.split("_")[1].split(".")[0])
            assert s.finger == hand.fingers[i // 4]
    # thumb q = 0 lies below joint_12.0's lower limit (0.263)
    assert hand.check_limits(np.zeros(16)) == [("joint_12.0", 0.0, 0.263, 1.396)]


def _urdf_spheres(ref: yourdfpy.URDF) -> dict[str, tuple[str, np.ndarray, float]]:
    """Collision spheres as written in the URDF: label -> (link, T_link_sphere (4, 4), radius m).

    Labels are the collision names ("<link>#<k>"); the fingertip contact spheres are named
    "tip_contact" in the URDF and labelled "<link>#tip"."""
    spheres = {}
    for link in ref.robot.links:
        for c in link.collisions:
            if c.geometry.sphere is None:
                continue
            label = f"{link.name}#tip" if c.name == "tip_contact" else c.name
            origin = np.eye(4) if c.origin is None else np.asarray(c.origin, dtype=float)
            spheres[label] = (link.name, origin, float(c.geometry.sphere.radius))
    return spheres


@pytest.fixture(scope="module")
def urdf_ref(hand):
    return yourdfpy.URDF.load(str(hand.urdf_path), load_meshes=False, build_collision_scene_graph=False)


def test_sphere_centres_are_the_urdf_collision_spheres_placed_by_yourdfpy(hand, urdf_ref):
    """Centres, labels and radii of every sphere selection agree, in the same order, with the URDF's
    collision spheres placed by yourdfpy's forward kinematics."""
    urdf = _urdf_spheres(urdf_ref)
    assert set(hand.sphere_labels(None, True)) == set(urdf)
    assert len(hand.sphere_labels(None, True)) == len(urdf) == 67
    rng = np.random.default_rng(4)
    for q in rng.uniform(hand.q_lower, hand.q_upper, size=(5, hand.n_joints)):
        urdf_ref.update_cfg(q)
        for finger in (None, *hand.fingers):
            for include_tip in (False, True):
                labels = hand.sphere_labels(finger, include_tip)
                centres = hand.sphere_centers(q, finger, include_tip)
                radii = hand.sphere_radii(finger, include_tip)
                assert len(labels) == len(centres) == len(radii) > 0
                for label, centre, radius in zip(labels, centres, radii, strict=True):
                    link, T_link_sphere, r = urdf[label]
                    T_palm_sphere = urdf_ref.get_transform(link, urdf_ref.base_link) @ T_link_sphere
                    np.testing.assert_allclose(centre, T_palm_sphere[:3, 3], atol=1e-12, err_msg=label)
                    assert radius == r
                n_tips = sum(label.endswith("#tip") for label in labels)
                assert n_tips == (0 if not include_tip else len(hand.fingers) if finger is None else 1)
        # the tip positions are the tip contact spheres
        for finger, tip in zip(hand.fingers, hand.tip_positions(q), strict=True):
            link, T_link_sphere, _ = urdf[f"{hand.tip_links[finger]}#tip"]
            np.testing.assert_allclose(
                tip, (urdf_ref.get_transform(link, urdf_ref.base_link) @ T_link_sphere)[:3, 3], atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tip_jacobian_matches_central_differences(hand, seed):
    q = np.random.default_rng(seed).uniform(hand.q_lower, hand.q_upper)
    h = 1e-6
    for finger in hand.fingers:
        J = hand.tip_jacobian(q, finger)
        J_fd = np.zeros_like(J)
        for i in range(hand.n_joints):
            dq = np.zeros(hand.n_joints)
            dq[i] = h
            k = hand.fingers.index(finger)
            J_fd[:, i] = (hand.tip_positions(q + dq)[k] - hand.tip_positions(q - dq)[k]) / (2 * h)
        np.testing.assert_allclose(J, J_fd, atol=1e-8)
        np.testing.assert_allclose(hand.tips_jacobian(q)[k], J_fd, atol=1e-8)  # all tips in one call
        other = np.setdiff1d(np.arange(hand.n_joints), hand.finger_joints[finger])
        assert np.all(J[:, other] == 0.0)


def test_tip_workspace_samples_are_reachable_and_uniform_in_joint_space(hand, urdf_ref):
    """The samples are tip centres of in-limit configurations of the finger (an IK with bounds reaches
    each of them), distributed as uniform joint angles are: their mean and spread agree with an
    independent Monte Carlo through yourdfpy's FK (other seed, other FK code)."""
    finger = "ring"
    r, idx = hand.fingers.index(finger), hand.finger_joints[finger]
    P = hand.tip_workspace_samples(finger, n=4000, seed=3)
    assert np.array_equal(P, hand.tip_workspace_samples(finger, n=4000, seed=3))
    assert not np.allclose(P[:10], hand.tip_workspace_samples(finger, n=10, seed=4))
    lo, hi = hand.q_lower[idx], hand.q_upper[idx]
    # independent reference: uniform joint angles, yourdfpy FK, tip sphere from the URDF
    link, T_link_tip, _ = _urdf_spheres(urdf_ref)[f"{hand.tip_links[finger]}#tip"]
    ref = []
    for q_r in np.random.default_rng(12345).uniform(lo, hi, size=(1000, len(idx))):
        q = hand.q_mid()
        q[idx] = q_r
        urdf_ref.update_cfg(q)
        ref.append((urdf_ref.get_transform(link, urdf_ref.base_link) @ T_link_tip)[:3, 3])
    ref = np.array(ref)
    z = np.abs(P.mean(0) - ref.mean(0)) / np.sqrt(P.var(0) / len(P) + ref.var(0) / len(ref))
    assert np.all(z <= 5.0), z
    np.testing.assert_allclose(P.std(0), ref.std(0), rtol=0.1)
    # every sample is reachable within the joint limits (bounded least-squares IK from a few starts)
    starts = [hand.q_mid()[idx], *np.random.default_rng(0).uniform(lo, hi, size=(5, len(idx)))]
    for p in P[:10]:
        def residual(q_r, p=p):
            q = hand.q_mid()
            q[idx] = q_r
            return hand.tip_positions(q)[r] - p

        def jacobian(q_r):
            q = hand.q_mid()
            q[idx] = q_r
            return hand.tip_jacobian(q, finger)[:, idx]

        best = np.inf
        for x0 in starts:  # the first start (mid-range) nearly always suffices
            fit = least_squares(residual, x0, jac=jacobian, bounds=(lo, hi), xtol=1e-12, ftol=1e-12,
                                gtol=1e-12)
            best = min(best, float(np.linalg.norm(fit.fun)))
            if best <= 1e-9:
                break
        assert best <= 1e-9


def test_symbolic_functions_are_cached_and_named(hand):
    assert hand.fk_function() is hand.fk_function()
    assert hand.tip_position_function("index") is hand.tip_position_function("index")
    f = hand.tip_position_function("thumb")
    assert f.name_in() == ["q"] and f.name_out() == ["p_palm_tip"]
    assert hand.fk_function().name_out()[0] == "T_palm_palm_link"
    # the buffered numeric conveniences agree with plain CasADi calls of the public functions
    q = np.random.default_rng(7).uniform(hand.q_lower, hand.q_upper)
    T = hand.fk(q)
    for link, T_dm in zip(hand.link_names, hand.fk_function()(q), strict=True):
        np.testing.assert_array_equal(T[link], T_dm.full())
    np.testing.assert_array_equal(hand.tip_jacobian(q, "ring"), hand.tip_jacobian_function("ring")(q).full())
    np.testing.assert_array_equal(hand.sphere_centers(q), hand.sphere_centers_function()(q).full().T)


@pytest.mark.reference_data
def test_sphere_cover_encloses_vendor_meshes(hand, reference_dir):
    """Every vertex of every vendor link mesh (placed by the vendor URDF's FK) lies inside the union of the
    link's spheres (distal link and tip link: the union of both links' spheres, tip sphere included).

    Tolerance: the rubber tip's hemispherical cap IS the contact sphere (its vertices lie on it to ~1e-9 m),
    so a vertex on the cap side of the tip sphere's centre (tip-frame z >= 0.002) counts as covered within
    1e-6 m of the contact sphere; every other vertex must lie inside a sphere (distance <= 0)."""
    ref_dir = reference_dir / "allegro_right"
    ref = yourdfpy.URDF.load(
        str(ref_dir / "allegro_hand_right.urdf"), load_meshes=False, build_collision_scene_graph=False
    )
    meshes = {}
    for link in ref.robot.links:
        for v in link.visuals:
            m = meshes.setdefault(v.geometry.mesh.filename, trimesh.load(ref_dir / v.geometry.mesh.filename))
            T_link_mesh = np.eye(4) if v.origin is None else v.origin
            meshes[(link.name, "T")] = (m, T_link_mesh)
    groups = {}  # link -> links whose spheres form its cover
    for link in hand.link_names:
        group = [link]
        if link.endswith("_tip"):
            group.append(link[: -len("_tip")])
        elif link + "_tip" in hand.link_names:
            group.append(link + "_tip")
        groups[link] = group
    rng = np.random.default_rng(0)
    configs = [
        hand.q_mid(),
        hand.q_lower.copy(),
        hand.q_upper.copy(),
        rng.uniform(hand.q_lower, hand.q_upper),
    ]
    worst = -np.inf
    for q in configs:
        ref.update_cfg(q)
        centres = hand.sphere_centers(q, include_tip=True)
        labels_links = [s.link for s in hand.spheres if not s.is_tip] + [
            hand.tip_links[f] for f in hand.fingers
        ]
        radii = hand.sphere_radii(include_tip=True)
        is_tip_sphere = np.arange(len(labels_links)) >= len(labels_links) - len(hand.fingers)
        for link in hand.link_names:
            m, T_link_mesh = meshes[(link, "T")]
            V = trimesh.transform_points(m.vertices, ref.get_transform(link, ref.base_link) @ T_link_mesh)
            sel = np.array([ln in groups[link] for ln in labels_links])
            assert sel.any(), link
            d = np.linalg.norm(V[:, None, :] - centres[sel][None], axis=-1) - radii[sel]
            tip_link = link if link.endswith("_tip") else link + "_tip"
            if tip_link in hand.link_names:  # cap vertices: within 1e-6 m of the contact sphere is covered
                T_tip = hand.fk(q)[tip_link]
                z_tip = (V - T_tip[:3, 3]) @ T_tip[:3, 2]  # tip-frame z
                is_cap = z_tip >= 0.002 - 1e-9
                d[:, is_tip_sphere[sel]] -= np.where(is_cap, 1e-6, 0.0)[:, None]
            out = float(d.min(axis=1).max())
            assert out <= 0.0, f"{link}: a vertex lies {out * 1e3:.3f} mm outside the sphere cover"
            worst = max(worst, out)
    assert worst < 0.0


def test_missing_file_raises_model_error(tmp_path):
    with pytest.raises(ModelError, match="not found.*nope.urdf"):
        Hand.from_urdf(tmp_path / "nope.urdf")


def test_malformed_xml_raises_model_error(tmp_path):
    path = tmp_path / "broken.urdf"
    path.write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(ModelError, match="broken.urdf.*malformed XML"):
        Hand.from_urdf(path)


@pytest.mark.parametrize("jtype", ["floating", "planar", "spherical"])
def test_unsupported_joint_type_raises_model_error(tmp_path, jtype):
    path = tmp_path / "float.urdf"
    path.write_text(_TINY_URDF.replace('name="slide" type="prismatic"', f'name="slide" type="{jtype}"'))
    with pytest.raises(ModelError, match=f"float.urdf.*'slide'.*{jtype}"):
        Hand.from_urdf(path)


def test_two_parents_raise_model_error(tmp_path):
    path = tmp_path / "twoparents.urdf"
    extra = '<joint name="second" type="fixed"><parent link="base"/><child link="slider"/></joint>\n</robot>'
    path.write_text(_TINY_URDF.replace("</robot>", extra))
    with pytest.raises(ModelError, match="twoparents.urdf.*'slider' has two parents.*'second'"):
        Hand.from_urdf(path)


def test_loop_without_root_raises_model_error(tmp_path):
    path = tmp_path / "loop.urdf"
    extra = '<joint name="back" type="fixed"><parent link="tip"/><child link="base"/></joint>\n</robot>'
    path.write_text(_TINY_URDF.replace("</robot>", extra))
    with pytest.raises(ModelError, match="loop.urdf.*root link"):
        Hand.from_urdf(path)


def test_unknown_tip_link_and_model_raise_model_error(tmp_path):
    path = tmp_path / "tiny.urdf"
    path.write_text(_TINY_URDF)
    with pytest.raises(ModelError, match="'nowhere'"):
        Hand.from_urdf(path, fingers={"f": "nowhere"})
    with pytest.raises(ModelError, match="unknown hand model"):
        Hand.from_spec({"model": "shadow"})
