"""`regrasp simulate --html`: the replay holds the simulated motion (the report's record) and the plan's
object pose as a ghost."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sim_plans import BOX_SHIFT, GRAVITY_DOWN, lifted, make_plan

from regrasp_casadi.simulate import SimOptions, simulate
from regrasp_casadi.transforms import rotation_angle

pytest.importorskip("meshcat")


@pytest.fixture(scope="module")
def dropped_run(hand):
    """grasp0 of the box, then a gait lifting the thumb under gravity: the box falls, so the simulated
    and planned poses part (0.5 s settle, 0.2 s gait, 0.3 s hold)."""
    from regrasp_casadi import RegraspProblem

    problem = RegraspProblem.load(BOX_SHIFT)
    g0 = problem.grasp0
    q1 = lifted(hand, problem.obj, g0.q, g0.T_palm_object, "thumb")
    plan = make_plan(hand, problem.obj, [("initial", None, g0.q, g0.T_palm_object),
                                         ("gait", "thumb", q1, g0.T_palm_object)])
    report = simulate(plan, hand, problem.obj, SimOptions(gravity_palm=GRAVITY_DOWN, hold_time=0.3))
    assert report.dropped, report.summary()
    return plan, problem, report


def _animation(html: str) -> dict:
    """path -> {track name -> [(time s, value)]} of the replay's set_animation command."""
    import umsgpack

    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in re.findall(r'base64,([A-Za-z0-9+/=]+)"', html)]
    anim = next(c for c in cmds if c["type"] == "set_animation")
    out = {}
    for a in anim["animations"]:
        fps = a["clip"]["fps"]
        out[a["path"]] = {t["name"]: [(k["time"] / fps, np.array(k["value"], dtype=float)) for k in t["keys"]]
                          for t in a["clip"]["tracks"]}
    return out


def _at(series_t: np.ndarray, t: float) -> int:
    j = int(np.argmin(np.abs(series_t - t)))
    assert abs(series_t[j] - t) < 1e-4, (t, series_t[j])
    return j


def test_html_replays_the_recorded_object_poses(dropped_run, tmp_path):
    """Every object key of the embedded animation equals the report's recorded pose at its time (float32
    precision), the ghost's keys equal the recorded planned poses, the keys span the whole simulation at
    ≤ 25 frames/s, and the simulated box ends more than 2 cm from the ghost."""
    from regrasp_casadi.sim_replay import write_sim_html

    plan, problem, report = dropped_run
    html = write_sim_html(report, plan, tmp_path / "sim.html", problem.hand, problem.obj, fps=25).read_text()
    assert "<script src=" not in html and "planned object pose" in html
    anim = _animation(html)
    t = np.asarray(report.series["t"])
    for node, key in (("object", "T_palm_object"), ("ghost", "T_palm_object_plan")):
        tracks = anim[f"/meshcat/regrasp/{node}"]
        pos, quat = tracks[".position"], tracks[".quaternion"]
        assert pos[-1][0] == pytest.approx(t[-1], abs=1e-6)
        for time, value in pos:
            np.testing.assert_allclose(value, report.series[key][_at(t, time)][:3, 3], atol=1e-6)
        for time, value in quat:
            R = Rotation.from_quat(value / np.linalg.norm(value)).as_matrix()
            assert rotation_angle(R, report.series[key][_at(t, time)][:3, :3]) < 1e-5
    object_pos = anim["/meshcat/regrasp/object"][".position"]
    assert len(object_pos) >= 0.9 * 25 * t[-1]       # the falling box moves at every kept sample
    assert np.diff([k[0] for k in object_pos])[:-1].min() >= 1 / 25 - 1e-6  # the last: the end
    # the ghost is the plan: the box's planned pose at every step (it never moves in this plan)
    for _, value in anim["/meshcat/regrasp/ghost"][".position"]:
        np.testing.assert_allclose(value, plan.steps[0].T_palm_object[:3, 3], atol=1e-6)
    assert np.linalg.norm(object_pos[-1][1] - plan.steps[-1].T_palm_object[:3, 3]) > 0.02
    # the index fingertip link follows the recorded joints (hand FK of series q)
    tip = anim["/meshcat/regrasp/hand/" + problem.hand.tip_links["index"]][".position"]
    time, value = tip[len(tip) // 2]
    q = report.series["q"][_at(t, time)]
    np.testing.assert_allclose(value, problem.hand.fk(q)[problem.hand.tip_links["index"]][:3, 3], atol=1e-6)


def test_cli_writes_the_html(dropped_run, tmp_path, capsys):
    from regrasp_casadi import cli

    plan, _, _ = dropped_run
    plan.save(tmp_path / "plan.json")
    out = tmp_path / "out" / "sim.html"
    assert cli.main(["simulate", str(tmp_path / "plan.json"), "--gravity", "0", "0", "-9.81",
                     "--html", str(out)]) == cli.EXIT_FAILED
    assert f"wrote {out}" in capsys.readouterr().out
    anim = _animation(out.read_text())
    assert {"/meshcat/regrasp/object", "/meshcat/regrasp/ghost"} <= set(anim)
    assert cli.main(["simulate", str(tmp_path / "plan.json"), "--html", str(tmp_path)]) == cli.EXIT_BAD_INPUT
