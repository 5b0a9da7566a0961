"""Viewer tests without a browser: keyframes (timing, transforms, interpolation) and the Meshcat scene.

Transforms are compared against yourdfpy's own FK (independent of the CasADi FK the viewer uses), the
object pose against the plan, and interpolation against closed forms (smoothstep(½) = ½, slerp halves
the rotation angle). The scene is inspected through the recorded Meshcat commands (msgpack), so the
desired-contact markers are checked where the HTML puts them.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from regrasp_casadi.plan import Plan, PlanStep
from regrasp_casadi.transforms import make_T, rot_axis_angle, rotation_angle

viewer = pytest.importorskip("regrasp_casadi.viewer")


def make_plan(hand, n_steps: int = 3) -> Plan:
    """A hand-built plan: initial grasp, an index-finger gait, then a reposing (object turned 30° about z
    and moved 1 cm). Contacts are the tip centres in the object frame (the viewer does not need them on
    the surface)."""
    q0 = 0.5 * (hand.q_lower + hand.q_upper)
    T0 = make_T(rot_axis_angle([0, 1, 0], 0.2), [0.09, 0.0, 0.07])
    qs, Ts = [q0], [T0]
    q1 = q0.copy()
    q1[hand.finger_joints["index"]] += 0.15
    qs.append(q1)
    Ts.append(T0)
    T2 = make_T(rot_axis_angle([0, 0, 1], np.radians(30)) @ T0[:3, :3], T0[:3, 3] + [0, 0.01, 0])
    q2 = q1 + 0.05
    qs.append(np.clip(q2, hand.q_lower, hand.q_upper))
    Ts.append(T2)
    kinds = ["initial", "gait", "repose", "final", "gait"]
    fingers = [None, "index", None, None, "thumb"]
    steps = []
    for i in range(n_steps):
        q, T = qs[min(i, 2)], Ts[min(i, 2)]
        tips = hand.tip_positions(q)  # (m, 3) palm frame
        c_obj = (tips - T[:3, 3]) @ T[:3, :3]
        steps.append(PlanStep(kind=kinds[i], finger=fingers[i], q=q, T_palm_object=T,
                              contacts_object=c_obj, contact_error=np.zeros(len(hand.fingers)),
                              solver_status="" if i == 0 else "Solve_Succeeded", solve_time=0.0))
    goal = steps[0].contacts_object + np.array([0.0, 0.0, 0.01])
    return Plan(steps=tuple(steps), goal_contacts_object=goal, goal_T_palm_object=Ts[-1],
                fingers=tuple(hand.fingers), hand_spec=hand.spec(),
                object_spec={"primitive": "box", "extents": [0.05, 0.06, 0.12]}, method="svd",
                status="converged", status_detail="", iterations=1, iteration_errors=np.zeros(2),
                timing={"total": 0.0}, options={})


@pytest.fixture(scope="module")
def obj():
    from regrasp_casadi.objects import ObjectModel

    return ObjectModel.box((0.05, 0.06, 0.12))


@pytest.fixture(scope="module")
def plan(hand):
    return make_plan(hand)


@pytest.fixture(scope="module")
def yourdfpy_fk(hand):
    import yourdfpy

    robot = yourdfpy.URDF.load(str(hand.urdf_path), build_scene_graph=True, load_meshes=False)

    def fk(q):
        robot.update_cfg(dict(zip(hand.joint_names, np.asarray(q, float), strict=True)))
        return {link: robot.get_transform(link, hand.root_link) for link in hand.link_names}

    return fk


def test_one_keyframe_exactly_at_each_step(plan, hand, obj):
    fps, sps = 30, 0.8
    frames = viewer.plan_keyframes(plan, hand, obj, fps=fps, seconds_per_step=sps)
    k = round(fps * sps)
    assert len(frames) == 1 + (len(plan.steps) - 1) * k
    at_steps = [f for f in frames if f.alpha == 1.0]
    assert [f.step for f in at_steps] == list(range(len(plan.steps)))
    assert [f.time for f in at_steps] == pytest.approx([i * sps for i in range(len(plan.steps))], abs=1e-12)
    assert [f.kind for f in at_steps] == [s.kind for s in plan.steps]
    assert [f.finger for f in at_steps] == [s.finger for s in plan.steps]
    times = np.array([f.time for f in frames])
    assert np.all(np.diff(times) > 0)
    assert np.diff(times) == pytest.approx(np.full(len(times) - 1, 1.0 / fps))


def test_transforms_at_step_times_equal_the_plan(plan, hand, obj, yourdfpy_fk):
    frames = viewer.plan_keyframes(plan, hand, obj, fps=10, seconds_per_step=0.5)
    for f in (f for f in frames if f.alpha == 1.0):
        step = plan.steps[f.step]
        np.testing.assert_array_equal(f.q, step.q)
        np.testing.assert_array_equal(f.T_palm_object, step.T_palm_object)
        ref = yourdfpy_fk(step.q)
        assert set(f.T_palm_link) >= set(hand.link_names)
        for link in hand.link_names:
            np.testing.assert_allclose(f.T_palm_link[link], ref[link], atol=1e-9)
        T = step.T_palm_object
        np.testing.assert_allclose(f.p_palm_contacts, step.contacts_object @ T[:3, :3].T + T[:3, 3],
                                   atol=1e-12)
        # the contacts were made from the tips: at a step they sit on the tip centres
        np.testing.assert_allclose(f.p_palm_contacts, hand.tip_positions(step.q), atol=1e-9)


def test_midpoint_interpolation(plan, hand, obj):
    fps, sps = 10, 1.0   # 10 frames per step: frame 5 of a segment is its midpoint
    frames = viewer.plan_keyframes(plan, hand, obj, fps=fps, seconds_per_step=sps)
    s1, s2 = plan.steps[1], plan.steps[2]
    mid = next(f for f in frames if f.step == 2 and f.alpha == pytest.approx(0.5))
    assert mid.time == pytest.approx(1.5)
    np.testing.assert_allclose(mid.q, 0.5 * (s1.q + s2.q), atol=1e-12)   # smoothstep(1/2) = 1/2
    T1, T2, Tm = s1.T_palm_object, s2.T_palm_object, mid.T_palm_object
    np.testing.assert_allclose(Tm[:3, 3], 0.5 * (T1[:3, 3] + T2[:3, 3]), atol=1e-12)
    full = rotation_angle(T1[:3, :3], T2[:3, :3])
    assert full == pytest.approx(np.radians(30), abs=1e-9)
    assert rotation_angle(T1[:3, :3], Tm[:3, :3]) == pytest.approx(full / 2, abs=1e-9)
    assert rotation_angle(Tm[:3, :3], T2[:3, :3]) == pytest.approx(full / 2, abs=1e-9)
    np.testing.assert_allclose(Tm[:3, :3] @ Tm[:3, :3].T, np.eye(3), atol=1e-12)
    c_mid = 0.5 * (s1.contacts_object + s2.contacts_object)
    np.testing.assert_allclose(mid.p_palm_contacts, c_mid @ Tm[:3, :3].T + Tm[:3, 3], atol=1e-12)


def test_gait_moves_only_its_finger_and_eases_monotonically(plan, hand, obj):
    frames = viewer.plan_keyframes(plan, hand, obj, fps=30, seconds_per_step=0.8)
    seg = [f for f in frames if f.step == 1]
    moving = hand.finger_joints["index"]
    still = np.setdiff1d(np.arange(hand.n_joints), moving)
    q0, q1 = plan.steps[0].q, plan.steps[1].q
    progress = [(f.q[moving] - q0[moving]) / (q1[moving] - q0[moving]) for f in seg]
    for p in progress:
        assert np.allclose(p, p[0])            # all joints of the finger on the same straight line
    p = np.array([x[0] for x in progress])
    assert np.all(np.diff(p) > 0) and p[-1] == pytest.approx(1.0)
    assert p[0] < 1.0 / len(seg)               # smoothstep starts slower than constant speed
    for f in seg:
        np.testing.assert_array_equal(f.q[still], q0[still])
        np.testing.assert_array_equal(f.T_palm_object, plan.steps[0].T_palm_object)


def test_linear_option_and_bad_arguments(plan, hand, obj):
    frames = viewer.plan_keyframes(plan, hand, obj, fps=4, seconds_per_step=1.0, easing=False)
    first = next(f for f in frames if f.step == 1)
    np.testing.assert_allclose(first.q, 0.75 * plan.steps[0].q + 0.25 * plan.steps[1].q, atol=1e-12)
    with pytest.raises(ValueError):
        viewer.plan_keyframes(plan, hand, obj, fps=0)
    single = make_plan(hand, n_steps=1)
    assert len(viewer.plan_keyframes(single, hand, obj)) == 1


def _recorded_scene(plan, hand, obj, fps=8, sps=0.5):
    from regrasp_casadi.meshcat_html import RecordingWindow, import_meshcat

    meshcat = import_meshcat()
    window = RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    frames = viewer.plan_keyframes(plan, hand, obj, fps=fps, seconds_per_step=sps)
    viewer._build_scene(vis, plan, hand, obj, frames, fps)
    return window, frames


def _node(window, path: str):
    from meshcat.servers.tree import find_node

    return find_node(window.tree, [p for p in path.split("/") if p])


def _unpack(data):
    import umsgpack

    return umsgpack.unpackb(data)


def test_desired_contacts_are_fixed_in_the_object_frame(plan, hand, obj):
    window, _ = _recorded_scene(plan, hand, obj)
    for r, finger in enumerate(plan.fingers):
        node = _node(window, f"/meshcat/regrasp/object/goal_contacts/{finger}")
        T = np.array(_unpack(node.transform)["matrix"], dtype=float).reshape(4, 4).T  # column-major
        np.testing.assert_allclose(T[:3, 3], plan.goal_contacts_object[r], atol=1e-7)
        np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-7)
        # an outlined blue ring: dark outline, the ring, a white hole, drawn in that order
        discs = [_unpack(node[f"disc{k}"].object)["object"] for k in range(3)]
        radii = [d["geometries"][0]["radius"] for d in discs]
        assert radii[1] == pytest.approx(viewer.GOAL_RADIUS) and radii[0] > radii[1] > radii[2]
        assert [d["materials"][0]["color"] for d in discs] == [viewer.OUTLINE_COLOR, viewer.GOAL_COLOR,
                                                               0xFFFFFF]
        orders = [d["object"]["renderOrder"] for d in discs]
        assert orders == sorted(orders) and orders[0] > 0
    # the markers are children of the animated object node, so they move with the object
    anim = _unpack(window.tree.animation)
    animated = {a["path"] for a in anim["animations"]}
    assert "/meshcat/regrasp/object" in animated
    assert not any("goal_contacts" in p for p in animated)


def test_animation_tracks_match_keyframes(plan, hand, obj):
    fps = 8
    window, frames = _recorded_scene(plan, hand, obj, fps=fps)
    anim = {a["path"]: a["clip"] for a in _unpack(window.tree.animation)["animations"]}
    clip = anim["/meshcat/regrasp/object"]
    pos = next(t for t in clip["tracks"] if t["name"] == ".position")
    quat = next(t for t in clip["tracks"] if t["name"] == ".quaternion")
    for f in frames:
        key = next((k for k in pos["keys"] if k["time"] == pytest.approx(f.time * fps, abs=1e-4)), None)
        if key is None:   # dropped as an interior key of a constant run
            continue
        np.testing.assert_allclose(key["value"], f.T_palm_object[:3, 3], atol=1e-6)
    last = quat["keys"][-1]["value"]   # xyzw
    R = Rotation.from_quat(last).as_matrix()
    assert rotation_angle(R, plan.steps[-1].T_palm_object[:3, :3]) < 1e-5
    # the index finger's last link is animated with FK poses at the step times
    link_clip = anim["/meshcat/regrasp/hand/link_3.0_tip"]
    lpos = next(t for t in link_clip["tracks"] if t["name"] == ".position")
    for f in (f for f in frames if f.alpha == 1.0):
        key = next(k for k in lpos["keys"] if k["time"] == pytest.approx(f.time * fps, abs=1e-4))
        np.testing.assert_allclose(key["value"], f.T_palm_link["link_3.0_tip"][:3, 3], atol=1e-6)
    # one label per step, visible while the replay moves into its step (step 0: only before it plays)
    n = len(plan.steps)
    for i in range(n):
        lab = anim[f"/Cameras/default/rotated/<object>/labels/step_{i}"]
        keys = [(k["time"] / fps, k["value"]) for k in lab["tracks"][0]["keys"]]
        on = [t for t, v in keys if v]
        off = [t for t, v in keys if not v and t > 0]
        assert on == pytest.approx([] if i == 0 else [(i - 1) * 0.5])
        assert off == pytest.approx([i * 0.5] if 0 < i < n - 1 else [])   # the last label stays on
        text = _unpack(_node(window, f"/Cameras/default/rotated/<object>/labels/step_{i}").object)["object"]
        assert text["textures"][0]["text"] == viewer.step_label(plan, i)
        assert plan.steps[i].kind in text["textures"][0]["text"]


def test_write_html_is_one_small_self_contained_file(plan, hand, obj, tmp_path):
    path = viewer.write_html(plan, tmp_path / "sub" / "replay.html", hand=hand, obj=obj)
    html = path.read_text(encoding="utf-8")
    assert path.stat().st_size < 1.5e6
    assert "MeshCat.Viewer" in html and html.count("<script") >= 2
    assert "<script src=" not in html             # nothing loaded from elsewhere
    assert f"{len(plan.steps)} steps" in html.split("<title>")[1].split("</title>")[0]
    # the animation is the last command (three.js only writes animated values when they change, so a
    # static command after it would win), and the static scene before it is the final step
    import base64
    import json
    import re

    import umsgpack

    blobs = re.findall(r'base64,([A-Za-z0-9+/=]+)"', html)
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    assert [c["type"] for c in cmds].index("set_animation") == len(cmds) - 1
    (T_obj,) = [c["matrix"] for c in cmds if c["type"] == "set_transform"
                and c["path"] == "/meshcat/regrasp/object"]
    T_obj = np.array(T_obj, dtype=float).reshape(4, 4).T
    np.testing.assert_allclose(T_obj, plan.steps[-1].T_palm_object, atol=1e-6)
    # the step labels and the legend are the HTML overlay, not text planes in the scene
    assert not [c for c in cmds if "/labels/" in c["path"] or "/legend/" in c["path"]]
    data = re.search(r'<script type="application/json" id="rg-data">(.*?)</script>', html).group(1)
    data = json.loads(data)
    assert data["labels"] == [viewer.step_label(plan, i) for i in range(len(plan.steps))]
    assert data["times"] == pytest.approx([0.0, 0.8, 1.6])


def test_import_viewer_does_not_import_meshcat():
    code = "import sys, regrasp_casadi.viewer, regrasp_casadi.cli; assert 'meshcat' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_show_serves_the_scene_on_localhost(plan, hand, obj, capsys):
    import base64
    import re

    import umsgpack

    try:
        url = viewer.show(plan, hand=hand, obj=obj, fps=4)
        assert url.startswith("http://127.0.0.1:")
        assert capsys.readouterr().out == ""          # meshcat's own banner is swallowed
        html = viewer.LIVE_VIEWERS[-1].static_html()  # the scene as the server holds it
    finally:
        procs = [v.window.server_proc for v in viewer.LIVE_VIEWERS]
        viewer.stop_live_viewers()
    assert all(p.poll() is not None for p in procs)
    blobs = re.findall(r'base64,([A-Za-z0-9+/=]+)"', html)
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    paths = {c["path"] for c in cmds}
    assert "/meshcat/regrasp/object/mesh" in paths
    # the live server replays the animation before the static commands: the static scene is step 0
    (T_obj,) = [c["matrix"] for c in cmds if c["type"] == "set_transform"
                and c["path"] == "/meshcat/regrasp/object"]
    T_obj = np.array(T_obj, dtype=float).reshape(4, 4).T
    np.testing.assert_allclose(T_obj, plan.steps[0].T_palm_object, atol=1e-6)
    assert {f"/meshcat/regrasp/object/goal_contacts/{f}" for f in plan.fingers} <= paths


def test_keyframes_of_a_real_plan(yourdfpy_fk):
    """A short plan from the real planner: every step's keyframe matches yourdfpy FK and the plan's
    object pose, and during a gait only the moved finger's joints change."""
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "problems" / "box_rotate.yaml"
    if not path.is_file():
        pytest.skip(f"{path} not present")
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem

    problem = RegraspProblem.load(path)
    hand = problem.hand
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, max_iters=2)
    assert len(plan.steps) > 2
    frames = viewer.plan_keyframes(plan, hand, problem.obj, fps=5, seconds_per_step=0.4)
    at_steps = [f for f in frames if f.alpha == 1.0]
    assert len(at_steps) == len(plan.steps)
    for f, step in zip(at_steps, plan.steps, strict=True):
        np.testing.assert_array_equal(f.T_palm_object, step.T_palm_object)
        ref = yourdfpy_fk(step.q)
        for link in hand.link_names:
            np.testing.assert_allclose(f.T_palm_link[link], ref[link], atol=1e-9)
    for f in frames:
        step = plan.steps[f.step]
        if step.kind == "gait" and f.step > 0:
            others = np.setdiff1d(np.arange(hand.n_joints), hand.finger_joints[step.finger])
            np.testing.assert_array_equal(f.q[others], plan.steps[f.step - 1].q[others])


# --------------------------------------------------------------------------------------------------------
# What the replay looks like: colours from the hand's metadata, markers over the scene, legend, meshes.

REPO = Path(__file__).resolve().parents[1]


def _link_colors(window, hand) -> dict[str, set[int]]:
    """link -> the colours of its shapes in the recorded scene."""
    out = {}
    for link in hand.link_names:
        node = _node(window, f"/meshcat/regrasp/hand/{link}")
        out[link] = {_unpack(child.object)["object"]["materials"][0]["color"]
                     for child in node.values() if child.object is not None}
    return out


def test_finger_colours_come_from_hand_yaml(tmp_path, plan, obj):
    """A colour changed in a copy of the model folder's hand.yaml is the colour of that finger's links in
    the scene and in the legend; a finger without a colour gets the first default; tips are tinted."""
    import shutil

    import yaml

    from regrasp_casadi.hand import Hand
    from regrasp_casadi.hand_visuals import DEFAULT_FINGER_COLORS

    folder = tmp_path / "allegro_copy"
    shutil.copytree(REPO / "models" / "allegro_right", folder)
    meta = yaml.safe_load((folder / "hand.yaml").read_text())
    meta["viewer"]["colors"] = {"palm": "#444444", "middle": "#123456"}   # index, ring, thumb: defaults
    (folder / "hand.yaml").write_text(yaml.safe_dump(meta))
    hand = Hand.from_model(folder)
    window, _ = _recorded_scene(plan, hand, obj)
    colors = _link_colors(window, hand)
    assert colors["palm_link"] == {0x444444}
    for k in (4, 5, 6, 7):                       # the middle finger: joints 4-7, links link_4.0 .. link_7.0
        assert colors[f"link_{k}.0"] == {0x123456}
    # the tip: 0x12, 0x34, 0x56 mixed 55 % with white -> 0x94, 0xA4, 0xB3
    assert colors["link_7.0_tip"] == {0x94A4B3}
    assert colors["link_1.0"] == {DEFAULT_FINGER_COLORS[0]}   # index: first finger, first default
    assert colors["link_13.0"] == {DEFAULT_FINGER_COLORS[3]}  # thumb: fourth finger
    html = viewer.scene_html(plan, hand, obj)
    assert "background:#123456" in html and "middle finger" in html


def test_contact_markers_do_not_depth_test(plan, hand, obj):
    """Every disc of the current and desired contact markers is drawn over the scene: its material does not
    depth-test (nor write depth), is transparent (drawn after the opaque scene) and has a renderOrder
    after the scene's; a current contact's dot is drawn after (over) a desired contact's ring."""
    window, _ = _recorded_scene(plan, hand, obj)
    orders = {}
    for kind, base in (("current", "/meshcat/regrasp/contacts"),
                       ("goal", "/meshcat/regrasp/object/goal_contacts")):
        for finger in plan.fingers:
            node = _node(window, f"{base}/{finger}")
            discs = [_unpack(c.object)["object"] for c in node.values() if c.object is not None]
            assert len(discs) >= 2
            for d in discs:
                mat = d["materials"][0]
                assert mat["depthTest"] is False and mat["depthWrite"] is False and mat["transparent"] is True
            orders.setdefault(kind, []).extend(d["object"]["renderOrder"] for d in discs)
    assert min(orders["goal"]) > 0 and min(orders["current"]) > max(orders["goal"])
    dot = _unpack(_node(window, f"/meshcat/regrasp/contacts/{plan.fingers[0]}/disc1").object)["object"]
    assert dot["materials"][0]["color"] == viewer.CONTACT_COLOR
    assert dot["geometries"][0]["radius"] == pytest.approx(viewer.CONTACT_RADIUS)


def test_step_labels_name_kind_number_and_finger(plan):
    assert [viewer.step_label(plan, i) for i in range(3)] == [
        "initial grasp 0/2", "gait 1/2: index finger", "repose 2/2"]
    assert viewer.finger_phrase("thumb") == "thumb" and viewer.finger_phrase("ring") == "ring finger"


def test_legend_is_in_the_html(plan, hand, obj, tmp_path):
    import html as html_lib

    from regrasp_casadi.hand_visuals import hand_colors

    html = viewer.write_html(plan, tmp_path / "r.html", hand=hand, obj=obj).read_text(encoding="utf-8")
    legend = html.split('id="rg-legend"')[1].split('id="rg-hint"')[0]
    texts = ["current contact", "desired contact", "index finger", "middle finger", "ring finger", "thumb",
             "palm", f"object ({html_lib.escape(obj.name)})"]
    positions = [legend.index(t) for t in texts]
    assert positions == sorted(positions)               # in this order, top to bottom
    for part, color in hand_colors(hand).items():
        assert f"background:#{color:06x}" in legend, part
    assert f"#{viewer.CONTACT_COLOR:06x}" in legend and f"#{viewer.GOAL_COLOR:06x}" in legend
    assert "gait 1/2: index finger" in html             # the step labels ride in the overlay's data


def _binary_stl_vertices(path: Path) -> np.ndarray:
    """(3 f, 3) triangle corners of a binary STL file, read with numpy only (a reference for trimesh)."""
    data = path.read_bytes()
    n = int(np.frombuffer(data[80:84], dtype="<u4")[0])
    rec = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    return np.frombuffer(data[84:84 + 50 * n], dtype=rec)["v"].reshape(-1, 3).astype(float)


@pytest.mark.reference_data
def test_vendor_urdf_is_drawn_with_its_meshes(reference_dir, plan, hand, obj):
    """With the vendor URDF (STL visual meshes), every link that has a visual mesh is drawn with it: the
    scene's geometry under that link spans the STL file's bounds (read with numpy) and sits at the
    <visual><origin> of the URDF (read with lxml)."""
    from lxml import etree

    from regrasp_casadi.hand import Hand

    urdf = reference_dir / "allegro_right" / "allegro_hand_right.urdf"
    vendor = Hand.from_urdf(urdf, fingers=hand.tip_links)
    window, _ = _recorded_scene(plan, vendor, obj)
    with_mesh = 0
    for link in etree.parse(str(urdf)).getroot().findall("link"):
        mesh = link.find("visual/geometry/mesh")
        if mesh is None:
            continue
        with_mesh += 1
        origin = link.find("visual/origin")
        xyz = [float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()]
        rpy = [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()]
        T_ref = make_T(Rotation.from_euler("xyz", rpy).as_matrix(), xyz)   # URDF: fixed-axis roll-pitch-yaw
        ref = _binary_stl_vertices(urdf.parent / mesh.get("filename"))
        (child,) = [c for c in _node(window, f"/meshcat/regrasp/hand/{link.get('name')}").values()
                    if c.object is not None]
        geom = _unpack(child.object)["object"]["geometries"][0]
        assert geom["type"] == "BufferGeometry"
        position = geom["data"]["attributes"]["position"]["array"].data
        v = np.frombuffer(position, dtype=np.float32).reshape(-1, 3)
        np.testing.assert_allclose(v.min(axis=0), ref.min(axis=0), atol=1e-6)
        np.testing.assert_allclose(v.max(axis=0), ref.max(axis=0), atol=1e-6)
        T = np.array(_unpack(child.transform)["matrix"], dtype=float).reshape(4, 4).T
        np.testing.assert_allclose(T, T_ref, atol=1e-6)
    assert with_mesh == len(vendor.link_names) == 21


def test_bundled_boxes_become_rounded_boxes_of_the_same_size(hand):
    """The bundled URDF's box visuals are drawn as rounded boxes: the same extents as the box (read from
    the URDF with lxml), every vertex inside the box, its corners cut (no vertex near a box corner)."""
    from lxml import etree

    from regrasp_casadi.hand_visuals import hand_visuals

    boxes = {link.get("name"): np.array(link.find("visual/geometry/box").get("size").split(), dtype=float)
             for link in etree.parse(str(hand.urdf_path)).getroot().findall("link")
             if link.find("visual/geometry/box") is not None}
    shapes = {s.link: s for s in hand_visuals(hand) if s.link in boxes}
    assert set(shapes) == set(boxes) and len(boxes) >= 16
    for link, size in boxes.items():
        v = shapes[link].params["vertices"]
        np.testing.assert_allclose(v.max(axis=0) - v.min(axis=0), size, atol=1e-9)
        corner = 0.5 * size
        assert np.all(np.abs(v) <= corner + 1e-12)
        assert np.min(np.linalg.norm(np.abs(v) - corner, axis=1)) > 0.1 * size.min()
