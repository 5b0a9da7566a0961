"""Plan viewer: thin Meshcat front ends (live view, static HTML) over the plan's keyframes (`keyframes`).

`keyframes.plan_keyframes` turns a `Plan` into a list of `Keyframe`s — every link pose, the object pose
and the current contacts in the palm frame at a given time: a plan with trajectories plays its motion
(every step's `StepPath`: a gait's lift-off along the contact normal, transit and touch-down, a
reposing, a slide) at its own time stamps scaled by `speed`, each step at least `MIN_STEP_SECONDS` on
screen; a plan without paths interpolates its steps (smoothstep, `seconds_per_step` each). There is one
keyframe exactly at each step. `Keyframe`, `plan_keyframes` and `step_times` are re-exported here.

`show` (live viewer on localhost) and `write_html` (one self-contained HTML file that plays offline) are
thin shells over Meshcat, imported lazily inside them (`import regrasp_casadi.viewer` never imports
meshcat nor starts a server). The scene, drawn in the palm frame:

* the hand (`hand_visuals`): the visual meshes of its URDF when it has them (a vendor URDF), else
  shapes that read as the robot (rounded boxes), one colour per finger and a grey palm (hand.yaml's
  ``viewer.colors``, with defaults), light fingertips;
* the object mesh (`OBJECT_COLOR`, a light sand colour, slightly transparent);
* the desired contacts as blue rings (`GOAL_COLOR`) fixed to the object frame (as in the paper's plan
  figures) and the current contacts as orange dots (`CONTACT_COLOR`; Okabe–Ito colours, told apart by
  shape too), each outlined in black and drawn over everything (their materials do not depth-test, and
  they are drawn last), so that a contact behind the object or a finger stays visible. With the plan's
  motion a dot rides on its fingertip and is hidden while a gait's finger is off the surface (from its
  lift-off to its touch-down, `Keyframe.contacts_visible`);
* what is happening: the label of the step being moved into ("gait 3/33: index finger", `step_label`).
  The static HTML shows it in an HTML overlay (`replay_overlay`) with a progress bar and a legend of the
  colours; the live viewer shows it as a Meshcat `_text` plane attached to the camera, one per step
  whose `visible` flag is animated. The HTML `<title>` names the plan (steps, method, status).

Only transforms and visibility are animated (no track keeps the interior keys of a constant run);
geometry is sent once. The static HTML's static scene is the final step (what a page shows if it does not
play the animation); the live viewer's is the first. The static HTML is produced without a Meshcat
server: the commands are recorded in-process and assembled the way Meshcat's own `static_html()` does,
with the animation last (`meshcat_html`).
"""

from __future__ import annotations

import contextlib
import io
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from regrasp_casadi.files import atomic_write_text
from regrasp_casadi.hand_visuals import hand_colors, hand_visuals
from regrasp_casadi.keyframes import DEFAULT_SPEED, Keyframe, plan_keyframes, step_times
from regrasp_casadi.meshcat_html import RecordingWindow, import_meshcat, mesh_in_order
from regrasp_casadi.problem import plan_models
from regrasp_casadi.replay_overlay import LegendEntry, overlay_html
from regrasp_casadi.scene_hud import (
    CAMERA_FOV_DEG,
    LABELS,
    LEGEND,
    add_legend,
    add_step_labels,
    animate_step_labels,
)

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import Plan

__all__ = ["Keyframe", "plan_keyframes", "step_times", "write_html", "show", "scene_html",
           "stop_live_viewers", "DEFAULT_SPEED"]

logger = logging.getLogger(__name__)

OBJECT_COLOR = 0xE2CFA6     # light sand
OBJECT_OPACITY = 0.8        # a finger behind the object shows through
CONTACT_COLOR = 0xE69F00    # Okabe-Ito orange: current contacts (filled dots)
GOAL_COLOR = 0x0072B2       # Okabe-Ito blue: desired contacts (rings)
OUTLINE_COLOR = 0x1A1A1A    # the markers' outline
EDGE_COLOR = 0x8A7650       # the object's sharp edges
EDGE_ANGLE_DEG = 50.0
CONTACT_RADIUS = 0.0035     # m, the current-contact dot (its outline: x OUTLINE_SCALE)
GOAL_RADIUS = 0.0055        # m, the desired-contact ring (its hole: x GOAL_HOLE)
OUTLINE_SCALE = 1.4
GOAL_HOLE = 0.6
MARKER_RENDER_ORDER = 10    # three.js renderOrder of the markers: drawn after the scene (order 0)

_ROOT = "regrasp"          # under /meshcat

LIVE_VIEWERS: list = []     # live visualizers started by `show` (kept alive here)


def _scene_bounds(frames: list[Keyframe], obj: ObjectModel) -> tuple[NDArray, float]:
    """Centre (3,) and radius (m) of a sphere holding every link origin and the object at every step."""
    pts = []
    verts = np.asarray(obj.mesh.bounds, dtype=float)  # (2,3) corners are enough for framing
    corners = np.array([[verts[i, 0], verts[j, 1], verts[k, 2]]
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    for f in frames:
        pts.extend(T[:3, 3] for T in f.T_palm_link.values())
        pts.extend(corners @ f.T_palm_object[:3, :3].T + f.T_palm_object[:3, 3])
    pts = np.asarray(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    center = 0.5 * (lo + hi)
    radius = float(max(np.linalg.norm(pts - center, axis=1).max(), 0.05))
    return center, radius


def camera_offset(frames: list[Keyframe], center: NDArray, radius: float,
                  hand: Hand | None = None) -> NDArray:
    """Camera position relative to the scene centre (palm frame, m).

    The camera looks across the grasp: perpendicular to the opposition axis (`hand.thumb`, else the last
    finger, against the mean of the others) and to the palm -> object direction `u`, turned towards `u` so
    that the palm side is seen, raised; the turn and the lift come from the hand's metadata
    (`hand.metadata.camera`, from its hand.yaml; defaults without a hand). At a distance that fits a
    sphere of `radius`.
    """
    from regrasp_casadi.hand_model import CameraHint

    view = hand.metadata.camera if hand is not None else CameraHint()
    f0 = frames[0]
    hand_c = np.mean([T[:3, 3] for T in f0.T_palm_link.values()], axis=0)
    u = f0.T_palm_object[:3, 3] - hand_c
    u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-6 else np.array([1.0, 0.0, 0.0])
    p = f0.p_palm_contacts
    k = hand.fingers.index(hand.thumb) if hand is not None and hand.thumb is not None else len(p) - 1
    opp = p[k] - np.delete(p, k, axis=0).mean(axis=0) if len(p) > 1 else np.array([0.0, 1.0, 0.0])
    side = np.cross(u, opp)
    if np.linalg.norm(side) < 1e-6:
        side = np.cross(u, np.array([0.0, 0.0, 1.0]))
    if np.linalg.norm(side) < 1e-6:
        side = np.array([0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    v = side + view.toward_palm_side * u + np.asarray(view.lift_palm, dtype=float)
    v /= np.linalg.norm(v)
    dist = 1.2 * radius / np.tan(np.radians(CAMERA_FOV_DEG) / 2.0)
    return v * dist


_KIND_TEXT = {"initial": "initial grasp", "gait": "gait", "repose": "repose", "final": "final move"}


def step_label(plan: Plan, i: int) -> str:
    """Text shown while the replay moves into step i: "gait 3/33: index finger", "repose 7/33",
    "initial grasp 0/33", "final move 33/33" (`finger_phrase`)."""
    st = plan.steps[i]
    text = f"{_KIND_TEXT.get(st.kind, st.kind)} {i}/{len(plan.steps) - 1}"
    return text + (f": {finger_phrase(st.finger)}" if st.finger else "")


def finger_phrase(finger: str) -> str:
    """"index" -> "index finger"; a name that says "thumb" or "finger" stays as it is."""
    name = str(finger)
    return name if any(w in name.lower() for w in ("thumb", "finger")) else f"{name} finger"


# --------------------------------------------------------------------------------------------------------
# Meshcat front ends (meshcat imported lazily).


def _rot_x90() -> NDArray:
    T = np.eye(4)
    T[1:3, 1:3] = [[0.0, -1.0], [1.0, 0.0]]
    return T


def stage_scene(vis, frames: list[Keyframe], hand: Hand, obj: ObjectModel):
    """Light background, no grid, the camera framed on `frames`; returns (the scene root, T_world_palm
    (4,4): the palm frame placed so that the scene centre is at the origin, where the camera looks, the
    camera's distance from it, m)."""
    center, radius = _scene_bounds(frames, obj)
    T_world_palm = np.eye(4)
    T_world_palm[:3, 3] = -center
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)
    vis["/Background"].set_property("top_color", [1.0, 1.0, 1.0])
    vis["/Background"].set_property("bottom_color", [0.9, 0.92, 0.95])   # a light floor-like gradient
    off = camera_offset(frames, center, radius, hand)
    vis["/Cameras/default"].set_transform(np.eye(4))
    # the camera lives in a frame rotated +90° about x (three.js y-up): world (a, b, c) -> (a, c, -b)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [off[0], off[2], -off[1]])
    root = vis[_ROOT]
    root.set_transform(T_world_palm)
    return root, T_world_palm, float(np.linalg.norm(off))


def _build_scene(vis, plan: Plan, hand: Hand, obj: ObjectModel, frames: list[Keyframe], fps: float,
                 *, static_frame: int = -1, scene_hud: bool = True) -> None:
    """Send geometry once, `frames[static_frame]` as the static pose, and the animation of transforms.

    The static pose is what a viewer shows before the animation starts and where a property is not
    animated yet; it must equal the animation's first frame when the animation may reach the browser
    before the static commands (meshcat's live server replays the animation first), see
    `meshcat_html.RecordingWindow.get_scene`. `scene_hud`: the step labels and the legend drawn in the
    scene (`scene_hud`: the live viewer; the static HTML has its HTML overlay instead).
    """
    import meshcat.animation as mca

    root, _, camera_distance = stage_scene(vis, frames, hand, obj)
    _add_hand_geometry(root["hand"], hand)
    _add_object(root["object"], plan, obj)
    _add_contact_markers(root["contacts"], plan)
    if scene_hud:
        labels = [step_label(plan, i) for i in range(len(plan.steps))]
        add_step_labels(vis[LABELS], labels, camera_distance, frames[static_frame].step)
        add_legend(vis[LEGEND], legend_entries(plan, hand, obj), camera_distance)
    _set_pose(root, plan, frames[static_frame])
    anim = mca.Animation(default_framerate=fps)
    _animate_transforms(anim, root, plan, frames, fps)
    if scene_hud:
        animate_step_labels(anim, vis[LABELS], [f.time for f in frames if f.alpha >= 1.0], fps)
    vis.set_animation(anim, play=True, repetitions=1)


def _add_hand_geometry(hand_node, hand: Hand) -> None:
    """The hand's coloured shapes (`hand_visuals`), one node per shape under `hand_node/<link>` (animated
    per link)."""
    import meshcat.geometry as g

    materials: dict[int, Any] = {}
    for n, sh in enumerate(hand_visuals(hand)):
        node = hand_node[sh.link][f"v{n}"]
        T = sh.T_link_visual
        mat = materials.setdefault(sh.color, g.MeshPhongMaterial(color=sh.color, shininess=40,
                                                                 specular=0x2A2A2A))
        if sh.kind == "sphere":
            geom = g.Sphere(sh.params["radius"])
        elif sh.kind == "cylinder":  # three.js cylinders run along y, URDF ones along z
            geom = g.Cylinder(sh.params["length"], sh.params["radius"])
            T = T @ _rot_x90()
        else:
            geom = g.TriangularMeshGeometry(sh.params["vertices"], sh.params["faces"])
        node.set_object(geom, mat)
        node.set_transform(T)


def _add_object(object_node, plan: Plan, obj: ObjectModel) -> None:
    """The object mesh (shaded smoothly except along sharp edges) and the desired contacts (outlined blue
    rings, `_marker`) fixed in the object frame."""
    import meshcat.geometry as g

    shaded = obj.mesh.smooth_shaded
    object_node["mesh"].set_object(
        g.TriangularMeshGeometry(np.asarray(shaded.vertices), np.asarray(shaded.faces)),
        g.MeshPhongMaterial(color=OBJECT_COLOR, opacity=OBJECT_OPACITY, shininess=20, specular=0x222222))
    mesh = obj.mesh   # its sharp edges (faces meeting at more than EDGE_ANGLE_DEG) drawn as thin lines
    sharp = mesh.face_adjacency_edges[mesh.face_adjacency_angles > np.radians(EDGE_ANGLE_DEG)]
    if len(sharp):
        ends = np.asarray(mesh.vertices, dtype=np.float32)[sharp].reshape(-1, 3)
        object_node["edges"].set_object(g.LineSegments(g.PointsGeometry(ends.T),
                                                       g.LineBasicMaterial(color=EDGE_COLOR)))
    for r, p in enumerate(np.asarray(plan.goal_contacts_object, dtype=float)):
        node = object_node["goal_contacts"][str(plan.fingers[r])]
        _marker(node, [(OUTLINE_SCALE * GOAL_RADIUS, OUTLINE_COLOR), (GOAL_RADIUS, GOAL_COLOR),
                       (GOAL_HOLE * GOAL_RADIUS, 0xFFFFFF)], MARKER_RENDER_ORDER)
        node.set_transform(_translation(p))


def _add_contact_markers(contacts_node, plan: Plan) -> None:
    """One outlined orange dot per finger for the current contact (placed in the palm frame by the
    animation), drawn after the desired contacts' rings: a contact on its goal is a dot in a ring."""
    for finger in plan.fingers:
        _marker(contacts_node[str(finger)], [(OUTLINE_SCALE * CONTACT_RADIUS, OUTLINE_COLOR),
                                             (CONTACT_RADIUS, CONTACT_COLOR)], MARKER_RENDER_ORDER + 3)


def _marker(node, discs: list[tuple[float, int]], render_order: int) -> None:
    """Concentric flat-coloured spheres (radius m, colour) under `node`, drawn over the whole scene in the
    given order (materials without depth test, transparent so that three.js draws them after the opaque
    scene, increasing renderOrder): seen from anywhere, an outlined disc or ring."""
    import meshcat.geometry as g

    for k, (radius, color) in enumerate(discs):
        mat = g.MeshBasicMaterial(color=color, transparent=True, opacity=1.0, depthTest=False,
                                  depthWrite=False)
        node[f"disc{k}"].set_object(mesh_in_order(g.Sphere(radius), mat, render_order + k))


def _set_pose(root, plan: Plan, f: Keyframe) -> None:
    """The static pose of every link, the object and the contact markers at keyframe `f`."""
    for link, T in f.T_palm_link.items():
        root["hand"][link].set_transform(T)
    root["object"].set_transform(f.T_palm_object)
    for r, finger in enumerate(plan.fingers):
        root["contacts"][str(finger)].set_transform(_translation(f.p_palm_contacts[r]))


def _animate_transforms(anim, root, plan: Plan, frames: list[Keyframe], fps: float) -> None:
    """Position and rotation tracks of every link, the object and the contact markers."""
    key_frames = [f.time * fps for f in frames]
    for link in frames[0].T_palm_link:
        _transform_tracks(anim, root["hand"][link].path, key_frames,
                          np.stack([f.T_palm_link[link] for f in frames]), fps)
    _transform_tracks(anim, root["object"].path, key_frames, np.stack([f.T_palm_object for f in frames]), fps)
    for r, finger in enumerate(plan.fingers):
        Ts = np.stack([_translation(f.p_palm_contacts[r]) for f in frames])
        _transform_tracks(anim, root["contacts"][str(finger)].path, key_frames, Ts, fps)
        shown = [f.contacts_visible is None or bool(f.contacts_visible[r]) for f in frames]
        if not all(shown):
            _visibility_track(anim, root["contacts"][str(finger)].path, key_frames, shown, fps)


def _visibility_track(anim, path, frames: list[float], shown: list[bool], fps: float) -> None:
    """A boolean (discrete: each value holds until the next key) `visible` track with a key at the first
    frame and wherever the value changes."""
    import meshcat.animation as mca

    keys = [j for j in range(len(shown)) if j == 0 or shown[j] != shown[j - 1]]
    clip = anim.clips.setdefault(path, mca.AnimationClip(fps=fps))
    clip.tracks["visible"] = mca.AnimationTrack("visible", "boolean", [float(frames[j]) for j in keys],
                                                [shown[j] for j in keys])


def _translation(p: NDArray) -> NDArray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _compact(frames: list[float], values: NDArray, tol: float = 1e-7) -> tuple[list[float], list]:
    """Keys (frames, values (N, d)) without the interior keys of constant runs (three.js interpolates
    between the kept ones)."""
    n = len(frames)
    keep = np.ones(n, dtype=bool)
    if n >= 3:
        same = np.all(np.abs(np.diff(values, axis=0)) <= tol, axis=1)   # same[j]: key j+1 == key j
        keep[1:-1] = ~(same[:-1] & same[1:])
    idx = np.flatnonzero(keep)
    return [float(frames[j]) for j in idx], values[idx].tolist()


def _transform_tracks(anim, path, frames: list[float], Ts: NDArray, fps: float) -> None:
    """Position and quaternion (xyzw, sign-continuous) tracks of poses Ts (N, 4, 4) at `frames`."""
    import meshcat.animation as mca

    quat = Rotation.from_matrix(Ts[:, :3, :3]).as_quat()   # xyzw, as three.js wants
    if len(quat) > 1:   # q and -q are the same rotation: keep neighbours in one hemisphere
        flips = np.where(np.sum(quat[1:] * quat[:-1], axis=1) < 0.0, -1.0, 1.0)
        quat[1:] *= np.cumprod(flips)[:, None]
    clip = anim.clips.setdefault(path, mca.AnimationClip(fps=fps))
    clip.tracks["position"] = mca.AnimationTrack("position", "vector3", *_compact(frames, Ts[:, :3, 3]))
    clip.tracks["quaternion"] = mca.AnimationTrack("quaternion", "quaternion", *_compact(frames, quat))


def _title(plan: Plan, obj: ObjectModel) -> str:
    return (f"regrasp replay: {obj.name}, {len(plan.steps)} steps, method {plan.method}, "
            f"{plan.status}, {plan.iterations} iterations")


LEGEND_HINT = "drag: turn · scroll: zoom · Open Controls › Animations: play again, scrub time"


def legend_entries(plan: Plan, hand: Hand, obj: ObjectModel) -> list[LegendEntry]:
    """The legend of the replay, top to bottom: contact markers, fingers (in the plan's finger order),
    palm, object."""
    colors = hand_colors(hand)
    rows = [LegendEntry("dot", CONTACT_COLOR, "current contact"),
            LegendEntry("ring", GOAL_COLOR, "desired contact")]
    for finger in plan.fingers:
        rows.append(LegendEntry("block", colors.get(str(finger), colors["palm"]), finger_phrase(finger)))
    rows.append(LegendEntry("block", colors["palm"], "palm"))
    rows.append(LegendEntry("block", OBJECT_COLOR, f"object ({obj.name})"))
    return rows


def scene_html(plan: Plan, hand: Hand | None = None, obj: ObjectModel | None = None, fps: float = 8,
               seconds_per_step: float = 0.8, *, speed: float = DEFAULT_SPEED) -> str:
    """The self-contained HTML replay of `plan` as a string (see `write_html`)."""
    meshcat = import_meshcat()
    hand, obj = plan_models(plan, hand, obj)
    frames = plan_keyframes(plan, hand, obj, fps=fps, seconds_per_step=seconds_per_step, speed=speed)
    window = RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    _build_scene(vis, plan, hand, obj, frames, fps, scene_hud=False)
    times = [f.time for f in frames if f.alpha >= 1.0]   # = step_times(plan, seconds_per_step, speed)
    subtitle = (f"{obj.name} · method {plan.method} · {plan.status} after {plan.iterations} "
                f"iteration{'s' if plan.iterations != 1 else ''}")
    window.overlay = overlay_html(subtitle, [step_label(plan, i) for i in range(len(plan.steps))], times,
                                  legend_entries(plan, hand, obj), hint=LEGEND_HINT)
    html = vis.static_html()
    title = _title(plan, obj).replace("&", "&amp;").replace("<", "&lt;")
    return html.replace("<title>MeshCat</title>", f"<title>{title}</title>", 1)


def write_html(plan: Plan, path: str | Path, hand: Hand | None = None, obj: ObjectModel | None = None,
               fps: float = 8, seconds_per_step: float = 0.8, *, speed: float = DEFAULT_SPEED) -> Path:
    """Write ONE self-contained HTML file (three.js/Meshcat bundle included) that replays `plan` offline.

    A plan with paths plays its motion (`keyframes`): `speed` plan seconds per replay second, each step
    at least `keyframes.MIN_STEP_SECONDS` s, keyframes where the motion needs them (three.js interpolates
    in between). A plan without paths interpolates its steps, `seconds_per_step` s each, `fps` frames per
    second. The replay ends at `step_times(plan, seconds_per_step, speed)[-1]` s.

    Args:
        plan: the plan.
        path: output file (parent folders are created).
        hand, obj: the plan's hand and object (default: rebuilt from the plan's specs).
        fps: keyframes per second of interpolated steps; the animation's frame unit.
        seconds_per_step: replay duration of one interpolated step, s.
        speed: plan seconds played per replay second, with the plan's motion (> 0; 1: its own time).

    Returns:
        The path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    html = scene_html(plan, hand, obj, fps=fps, seconds_per_step=seconds_per_step, speed=speed)
    atomic_write_text(path, html)
    logger.info("wrote %s (%.0f kB)", path, path.stat().st_size / 1e3)
    return path


def show(plan: Plan, hand: Hand | None = None, obj: ObjectModel | None = None, fps: float = 30,
         seconds_per_step: float = 0.8, zmq_url: str | None = None, host: str = "127.0.0.1",
         *, speed: float = DEFAULT_SPEED):
    """Start a live Meshcat viewer, load the scene and play the plan.

    Meshcat's own start-up message is swallowed; nothing is printed.

    Args:
        plan, hand, obj, fps, seconds_per_step, speed: as for `write_html`.
        zmq_url: a running Meshcat server to draw in (default: start one, see `live_server`).
        host: address the started server's web page listens on: 127.0.0.1 (default) is this machine
            only; another address (e.g. 0.0.0.0) makes the viewer reachable from other machines.

    Returns:
        The URL to open in a browser. The Meshcat server runs in a subprocess that ends with this Python
        process (or with `stop_live_viewers`); the visualizer is kept in `viewer.LIVE_VIEWERS`.

    Raises:
        ValueError: `host` is not an address of this machine.
        RegraspError: the server did not start.
    """
    meshcat = import_meshcat()
    hand, obj = plan_models(plan, hand, obj)
    frames = plan_keyframes(plan, hand, obj, fps=fps, seconds_per_step=seconds_per_step, speed=speed)
    if zmq_url is None:
        from regrasp_casadi.live_server import start_server

        server = start_server(host)
        try:
            vis = meshcat.Visualizer(window=server.window())
        except BaseException:
            server.stop()
            raise
    else:
        with contextlib.redirect_stdout(io.StringIO()):
            vis = meshcat.Visualizer(zmq_url=zmq_url)
    LIVE_VIEWERS.append(vis)
    _build_scene(vis, plan, hand, obj, frames, fps, static_frame=0)
    return vis.url()


def stop_live_viewers() -> None:
    """Terminate the Meshcat server subprocesses started by `show` (they also end with Python)."""
    while LIVE_VIEWERS:
        proc = getattr(LIVE_VIEWERS.pop().window, "server_proc", None)
        if proc is not None and proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except Exception:  # noqa: BLE001 - best effort, then kill
                proc.kill()
