"""The replay plays the plan's motion (issue 15, item 5): keyframes against the steps' paths, the lifted
tip against the exact object surface, the overlay's step label and timing, the keyframe budget.

The plan is the schema-1 golden plan of box_rotate (tests/data, 6 steps: 4 gaits and a reposing) with
its paths attached by `trajectory.attach_trajectories` (a fraction of a second; some paths are flagged
by their self-clearance check, which does not matter to the replay). The references are independent of
`motion.interpolate_knots`: joints by `np.interp` per joint over the path's knots, rotations by scipy's
`Slerp`, distances by the object's exact mesh distance, tip centres from the keyframes' link poses.
"""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from regrasp_casadi import keyframes
from regrasp_casadi.plan import Plan
from regrasp_casadi.problem import plan_models
from regrasp_casadi.trajectory import attach_trajectories

GOLDEN_V1 = Path(__file__).resolve().parent / "data" / "plan_v1_box_rotate.json"


@pytest.fixture(scope="module")
def v1_plan():
    return Plan.load(GOLDEN_V1)


@pytest.fixture(scope="module")
def models(v1_plan, hand):
    return plan_models(v1_plan, hand)


@pytest.fixture(scope="module")
def motion_plan(v1_plan, models):
    plan = attach_trajectories(v1_plan, *models)
    assert all(s.path is not None for s in plan.steps[1:])
    assert [s.kind for s in plan.steps] == ["initial", "gait", "gait", "gait", "gait", "repose"]
    return plan


@pytest.fixture(scope="module")
def frames(motion_plan, models):
    return keyframes.plan_keyframes(motion_plan, *models)


def _expected_step_times(plan: Plan, speed: float) -> np.ndarray:
    """The stated rule: step i plays in max(d_i / speed, MIN_STEP_SECONDS) s, d_i its path's duration."""
    d = np.array([s.path.t[-1] for s in plan.steps[1:]])
    return np.concatenate([[0.0], np.cumsum(np.maximum(d / speed, keyframes.MIN_STEP_SECONDS))])


def _path_at(path, s: float) -> tuple[np.ndarray, np.ndarray]:
    """q (n,) and T_palm_object (4, 4) of a path at s (s from the step's start): linear per joint and in
    translation, geodesic in rotation between knots (np.interp and scipy's Slerp)."""
    s = float(np.clip(s, 0.0, path.t[-1]))
    q = np.array([np.interp(s, path.t, path.q[:, j]) for j in range(path.q.shape[1])])
    T = np.eye(4)
    T[:3, 3] = [np.interp(s, path.t, path.T_palm_object[:, k, 3]) for k in range(3)]
    R = path.T_palm_object[:, :3, :3]
    T[:3, :3] = R[0] if np.all(R == R[0]) else Slerp(path.t, Rotation.from_matrix(R))([s]).as_matrix()[0]
    return q, T


def _tip_centre(hand, f, finger: str) -> np.ndarray:
    """The tip sphere's centre as the replay draws it: the tip link's keyframe pose times the sphere's
    centre in the link frame, palm frame (m)."""
    (s,) = [s for s in hand.spheres if s.is_tip and s.finger == finger]
    T = f.T_palm_link[s.link]
    return T[:3, :3] @ s.center_link + T[:3, 3]


def test_keyframes_play_the_paths_at_the_stated_timing(motion_plan, models, frames):
    plan = motion_plan
    times = _expected_step_times(plan, 1.0)
    np.testing.assert_allclose(keyframes.step_times(plan), times, atol=1e-12)
    starts = np.concatenate([[0.0], np.cumsum([s.path.t[-1] for s in plan.steps[1:]])])  # plan time
    assert [f.step for f in frames if f.alpha == 1.0] == list(range(len(plan.steps)))
    assert np.all(np.diff([f.time for f in frames]) > 0)
    for f in frames[1:]:
        i, path = f.step, plan.steps[f.step].path
        s = f.plan_time - starts[i - 1]
        assert -1e-12 <= s <= path.t[-1] + 1e-12
        assert f.alpha == pytest.approx(s / path.t[-1], abs=1e-12)
        assert f.time == pytest.approx(times[i - 1] + f.alpha * (times[i] - times[i - 1]), abs=1e-12)
        q, T = _path_at(path, s)
        np.testing.assert_allclose(f.q, q, atol=1e-12)
        np.testing.assert_allclose(f.T_palm_object, T, atol=1e-12)
        k = int(np.searchsorted(path.t, s - 1e-12))    # the segment (t[k-1], t[k]] holding s
        assert f.phase == path.phases[max(k, 1) - 1]
        if f.alpha == 1.0:                             # the step itself, bit for bit
            np.testing.assert_array_equal(f.q, plan.steps[i].q)
            np.testing.assert_array_equal(f.T_palm_object, plan.steps[i].T_palm_object)
    # a lift-off keyframe equals Plan.sample at the same plan time (dt chosen to land on it)
    f = next(f for f in frames if f.step == 1 and f.phase == "lift")
    t, q, T = plan.sample(f.plan_time / 40)
    assert t[40] == pytest.approx(f.plan_time, abs=1e-12)
    np.testing.assert_allclose(q[40], f.q, atol=1e-9)
    np.testing.assert_allclose(T[40], f.T_palm_object, atol=1e-9)


def test_a_gait_lifts_the_tip_off_the_surface_and_hides_its_contact(motion_plan, models, frames, hand):
    plan, obj = motion_plan, models[1]
    lift = plan.options["trajectory"]["lift_height"]
    rise_tol = 0.1   # gait_path._RISE_TOL: a lift may fall short of its height by 10 % (joint limits)

    def clearance(f, finger):
        T = f.T_palm_object
        p = (_tip_centre(hand, f, finger) - T[:3, 3]) @ T[:3, :3]
        return float(obj.exact_signed_distance(p[None])[0]) - hand.tip_radii[finger]

    gaits = [i for i, s in enumerate(plan.steps) if s.kind == "gait"]
    assert len(gaits) == 4
    for i in gaits:
        finger, r = plan.steps[i].finger, plan.fingers.index(plan.steps[i].finger)
        seg = [f for f in frames if f.step == i]
        lifting = [f for f in seg if f.phase == "lift"]
        rise = [clearance(f, finger) for f in lifting]
        assert len(lifting) >= 2 and np.all(np.diff(rise) > 0)
        assert rise[0] < 0.5 * lift                            # it starts at the surface ...
        assert rise[-1] >= (1 - rise_tol) * lift - 1e-5        # ... and ends the lift-off lifted
        transit = [clearance(f, finger) for f in seg if f.phase == "transit"]
        assert transit and min(transit) > 1e-3                 # clear of the object (β = 1 mm)
        # the straight joint-space blend between the two steps is not the replay: at the lift's end it
        # is lower
        q0, q1 = plan.steps[i - 1].q, plan.steps[i].q
        blend = q0 + lifting[-1].alpha * (q1 - q0)
        T = plan.steps[i].T_palm_object
        p = (hand.tip_positions(blend)[hand.fingers.index(finger)] - T[:3, 3]) @ T[:3, :3]
        assert float(obj.exact_signed_distance(p[None])[0]) - hand.tip_radius < rise[-1] - 1e-3
        for f in seg:
            shown = f.contacts_visible
            if f.alpha < 1.0:   # off the surface: this finger's marker hidden, the others shown
                assert shown == tuple(k != r for k in range(len(plan.fingers)))
                # the held fingers' markers stay on their contacts; the hidden one rides on its tip
                T = f.T_palm_object
                held = [k for k in range(len(plan.fingers)) if k != r]
                c = plan.steps[i].contacts_object[held] @ T[:3, :3].T + T[:3, 3]
                np.testing.assert_allclose(f.p_palm_contacts[held], c, atol=1e-9)
                gap = np.linalg.norm(f.p_palm_contacts[r] - _tip_centre(hand, f, finger))
                assert gap <= hand.tip_radii[finger] + 1e-3
            else:
                assert all(shown)
                T = f.T_palm_object
                np.testing.assert_allclose(f.p_palm_contacts, plan.steps[i].contacts_object @ T[:3, :3].T
                                           + T[:3, 3], atol=1e-12)


def test_the_replay_stays_on_the_plans_motion(motion_plan, models, frames, hand):
    """Between keyframes three.js moves every link linearly: every fingertip of that replay stays within
    MAX_KEYFRAME_MOVE / 2 of the plan's motion (sampled every 2 ms of plan time), and no link origin
    moves more than MAX_KEYFRAME_MOVE from one keyframe to the next."""
    plan = motion_plan
    budget = keyframes.MAX_KEYFRAME_MOVE
    pt = np.array([f.plan_time for f in frames])
    tips = np.stack([np.stack([_tip_centre(hand, f, g) for g in hand.fingers]) for f in frames])  # (F, m, 3)
    starts = np.concatenate([[0.0], np.cumsum([s.path.t[-1] for s in plan.steps[1:]])])
    worst = 0.0
    for i in range(1, len(plan.steps)):
        path = plan.steps[i].path
        for s in np.arange(0.0, path.t[-1], 0.002):
            t = starts[i - 1] + s
            j = int(np.clip(np.searchsorted(pt, t), 1, len(pt) - 1))
            u = (t - pt[j - 1]) / (pt[j] - pt[j - 1])
            replay = (1 - u) * tips[j - 1] + u * tips[j]
            worst = max(worst, float(np.max(np.linalg.norm(replay - hand.tip_positions(_path_at(path, s)[0]),
                                                           axis=1))))
    assert worst <= budget / 2
    links = np.stack([np.stack([T[:3, 3] for T in f.T_palm_link.values()]) for f in frames])
    assert np.max(np.linalg.norm(np.diff(links, axis=0), axis=2)) <= budget + 1e-9


def _overlay(html: str) -> dict:
    data = re.search(r'<script type="application/json" id="rg-data">(.*?)</script>', html).group(1)
    return json.loads(data)


def _label_at(hud: dict, t: float) -> str:
    """The overlay script's rule (replay_overlay._JS): the first step whose time is not before t."""
    i = 0
    while i + 1 < len(hud["times"]) and hud["times"][i] < t - 1e-6:
        i += 1
    return hud["labels"][i]


def _animation(html: str) -> dict:
    """path -> {track name -> [(time s, value)]} of the replay's set_animation command."""
    import umsgpack

    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in re.findall(r'base64,([A-Za-z0-9+/=]+)"', html)]
    anim = next(c for c in cmds if c["type"] == "set_animation")
    return {a["path"]: {t["name"]: [(k["time"] / a["clip"]["fps"], k["value"]) for k in t["keys"]]
                        for t in a["clip"]["tracks"]} for a in anim["animations"]}


def _held(keys: list, t: float):
    """A discrete track's value at t: the last key at or before t."""
    return [v for kt, v in keys if kt <= t + 1e-9][-1]


def test_the_html_overlay_and_tracks_follow_the_motion(motion_plan, models, frames, hand, tmp_path):
    pytest.importorskip("meshcat")
    from regrasp_casadi import viewer

    plan = motion_plan
    path = viewer.write_html(plan, tmp_path / "replay.html", *models)
    html = path.read_text(encoding="utf-8")
    assert path.stat().st_size < 1.5e6
    hud = _overlay(html)
    np.testing.assert_allclose(hud["times"], _expected_step_times(plan, 1.0), atol=1e-9)
    assert hud["duration"] == pytest.approx(frames[-1].time)
    for f in frames[1:]:   # the label shown at a keyframe names the step whose motion plays
        assert _label_at(hud, f.time) == viewer.step_label(plan, f.step)
        if f.phase == "lift":
            assert _label_at(hud, f.time).startswith("gait ") and f.finger in _label_at(hud, f.time)
    anim = _animation(html)
    f = [f for f in frames if f.step == 1 and f.phase == "lift"][-1]    # the index finger lifted
    (tip,) = [s for s in hand.spheres if s.is_tip and s.finger == "index"]
    keys = anim[f"/meshcat/regrasp/hand/{tip.link}"][".position"]
    (value,) = [v for t, v in keys if t == pytest.approx(f.time, abs=1e-4)]
    np.testing.assert_allclose(value, f.T_palm_link[tip.link][:3, 3], atol=1e-6)
    shown = anim["/meshcat/regrasp/contacts/index"][".visible"]
    assert _held(shown, f.time) is False and _held(shown, 0.0) is True
    assert _held(shown, hud["times"][1]) is True and _held(shown, frames[-1].time) is True
    assert "/meshcat/regrasp/contacts/ring" in anim   # ring moves in gait 3: hidden then too
    assert _held(anim["/meshcat/regrasp/contacts/ring"][".visible"], f.time) is True


def test_speed_and_minimum_step_duration(motion_plan, models):
    plan = motion_plan
    for speed in (0.5, 2.0, 4.0):
        times = keyframes.step_times(plan, speed=speed)
        np.testing.assert_allclose(times, _expected_step_times(plan, speed), atol=1e-12)
        fr = keyframes.plan_keyframes(plan, *models, speed=speed)
        assert fr[-1].time == pytest.approx(times[-1], abs=1e-12)
    assert np.min(np.diff(keyframes.step_times(plan, speed=4.0))) == pytest.approx(keyframes.MIN_STEP_SECONDS)
    with pytest.raises(ValueError):
        keyframes.step_times(plan, speed=0.0)


def test_a_plan_without_paths_still_interpolates_its_steps(v1_plan, models):
    fps, sps = 10, 0.5
    fr = keyframes.plan_keyframes(v1_plan, *models, fps=fps, seconds_per_step=sps, speed=3.0)
    assert len(fr) == 1 + (len(v1_plan.steps) - 1) * 5
    at_steps = [f for f in fr if f.alpha == 1.0]
    assert [f.time for f in at_steps] == pytest.approx(sps * np.arange(len(v1_plan.steps)), abs=1e-12)
    np.testing.assert_allclose(keyframes.step_times(v1_plan, sps, speed=3.0), sps * np.arange(6))
    assert all(f.plan_time is None and f.phase is None and f.contacts_visible is None for f in fr)
    mid = next(f for f in fr if f.step == 2 and f.alpha == pytest.approx(0.6))
    s = 0.6 * 0.6 * (3 - 2 * 0.6)    # smoothstep
    q0, q1 = v1_plan.steps[1].q, v1_plan.steps[2].q
    np.testing.assert_allclose(mid.q, q0 + s * (q1 - q0), atol=1e-12)


def test_view_speed_flag(motion_plan, tmp_path, capsys):
    pytest.importorskip("meshcat")
    from regrasp_casadi import cli

    path = motion_plan.save(tmp_path / "plan.json")
    out = tmp_path / "replay.html"
    assert cli.main(["view", str(path), "--html", str(out), "--speed", "2"]) == 0
    hud = _overlay(out.read_text(encoding="utf-8"))
    np.testing.assert_allclose(hud["times"], _expected_step_times(motion_plan, 2.0), atol=1e-9)
    capsys.readouterr()
    assert cli.main(["view", str(path), "--html", str(out), "--speed", "0"]) == cli.EXIT_BAD_INPUT
    assert "--speed" in capsys.readouterr().err
