"""The replay of a simulated plan (`simulate.SimReport`) as one self-contained HTML file (Meshcat, offline).

    >>> report = simulate(plan, options=SimOptions(gravity_palm=(0, 0, -9.81)))
    >>> write_sim_html(report, plan, "sim.html")

The scene is the plan viewer's (`viewer`: the hand's shapes, the object mesh with the desired contacts as
blue rings, the HTML overlay with the step label, a progress bar and the legend), posed by what MuJoCo
simulated: the hand at the recorded joint angles, the object at its recorded pose, both in the palm
frame, every `SimOptions.record_dt` (the report's ``series``; subsampled to at most `fps` frames per
second of simulated time). The object pose the plan wants at the same instant is drawn as a ghost (a
transparent green copy of the object mesh, `GHOST_COLOR`): where the two part, the simulation leaves
the plan. The replay plays in simulated time (1 s of replay = 1 s simulated), settle and hold included.

The report must hold the simulated motion: ``series["q"]``, ``series["T_palm_object"]`` and
``series["T_palm_object_plan"]`` (every `simulate` report does).
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.files import atomic_write_text
from regrasp_casadi.keyframes import Keyframe
from regrasp_casadi.meshcat_html import RecordingWindow, import_meshcat
from regrasp_casadi.problem import plan_models
from regrasp_casadi.replay_overlay import LegendEntry, overlay_html
from regrasp_casadi.viewer import (
    LEGEND_HINT,
    OBJECT_COLOR,
    _add_hand_geometry,
    _add_object,
    _transform_tracks,
    legend_entries,
    stage_scene,
    step_label,
)

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import Plan
    from regrasp_casadi.simulate import SimReport

__all__ = ["GHOST_COLOR", "GHOST_OPACITY", "sim_frames", "sim_html", "write_sim_html"]

logger = logging.getLogger(__name__)

GHOST_COLOR = 0x009E73    # Okabe-Ito bluish green: the planned object pose
GHOST_OPACITY = 0.35


def sim_frames(report: SimReport, plan: Plan, hand, fps: float = 25.0) -> tuple[NDArray, list[Keyframe],
                                                                                NDArray]:
    """The recorded samples shown in the replay and their keyframes.

    Args:
        report: a `simulate` report (its ``series``: "t" (k,) s, "q" (k, n) rad, "T_palm_object" and
            "T_palm_object_plan" (k, 4, 4), palm frame).
        plan, hand: the simulated plan and its Hand (links posed by ``hand.fk`` at the recorded q).
        fps: largest number of frames per second of simulated time (> 0); every ``stride``-th sample is
            kept, the last one always.

    Returns:
        (indices (f,) of the kept samples in ``report.series``, f keyframes (time = simulated time, s;
        contacts = the plan's contacts of the step being executed, carried by the simulated object),
        planned object poses (f, 4, 4), palm frame).

    Raises:
        ValueError: fps ≤ 0, or the report has no recorded motion.
    """
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    series = report.series
    if any(k not in series or len(series[k]) == 0 for k in ("t", "q", "T_palm_object",
                                                            "T_palm_object_plan")):
        raise ValueError("the report has no recorded motion (series q / T_palm_object / T_palm_object_plan)")
    t = np.asarray(series["t"], dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    stride = max(1, int(np.ceil(1.0 / (fps * dt) - 1e-9)))
    idx = np.arange(0, len(t), stride)
    if idx[-1] != len(t) - 1:
        idx = np.append(idx, len(t) - 1)
    ends = np.array([r.time for r in report.steps[:len(plan.steps)]])
    contacts = np.asarray([s.contacts_object for s in plan.steps], dtype=float)
    frames = []
    for j in idx:
        i = int(min(np.searchsorted(ends, t[j] - 1e-9), len(plan.steps) - 1))
        q = np.asarray(series["q"][j], dtype=float)
        T = np.asarray(series["T_palm_object"][j], dtype=float)
        step = plan.steps[i]
        frames.append(Keyframe(
            time=float(t[j]), step=i, alpha=1.0, kind=step.kind, finger=step.finger, q=q,
            T_palm_link={n: np.asarray(M, dtype=float) for n, M in hand.fk(q).items()},
            T_palm_object=T, p_palm_contacts=contacts[i] @ T[:3, :3].T + T[:3, 3]))
    return idx, frames, np.asarray(series["T_palm_object_plan"], dtype=float)[idx]


def _labels(report: SimReport, plan: Plan) -> tuple[list[str], list[float]]:
    """Overlay labels and their end times: the settle at step 0, each step, the final hold."""
    labels = [("settle: " if i == 0 else "") + step_label(plan, i) for i in range(len(plan.steps))]
    times = [r.time for r in report.steps[:len(plan.steps)]]
    labels.append(f"hold {report.steps[-1].time - times[-1]:.1f} s")
    times.append(report.steps[-1].time)
    return labels, times


def _verdict_line(report: SimReport) -> str:
    if report.dropped:
        return f"simulated: dropped at {report.drop_time:.2f} s"
    last = report.steps[-1]
    return (f"simulated: {report.status} · max {report.max_deviation_mm:.1f} mm / "
            f"{report.max_deviation_deg:.1f}° · final {last.deviation_mm:.1f} mm / {last.deviation_deg:.1f}°")


def sim_html(report: SimReport, plan: Plan, hand=None, obj=None, fps: float = 25.0) -> str:
    """The self-contained HTML replay of a simulation (see the module docstring) as a string."""
    import meshcat.animation as mca
    import meshcat.geometry as g

    meshcat = import_meshcat()
    hand, obj = plan_models(plan, hand, obj)
    _, frames, T_plan = sim_frames(report, plan, hand, fps)
    window = RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    # framed on the hand and the planned object poses (a dropped object may fly far)
    framing = [dataclasses.replace(f, T_palm_object=T) for f, T in zip(frames, T_plan, strict=True)]
    root, _, _ = stage_scene(vis, framing, hand, obj)
    _add_hand_geometry(root["hand"], hand)
    _add_object(root["object"], plan, obj)
    shaded = obj.mesh.smooth_shaded
    root["ghost"].set_object(
        g.TriangularMeshGeometry(np.asarray(shaded.vertices), np.asarray(shaded.faces)),
        g.MeshPhongMaterial(color=GHOST_COLOR, opacity=GHOST_OPACITY, transparent=True, depthWrite=False))
    last = frames[-1]  # the static scene: the end of the simulation
    for link, T in last.T_palm_link.items():
        root["hand"][link].set_transform(T)
    root["object"].set_transform(last.T_palm_object)
    root["ghost"].set_transform(T_plan[-1])
    anim = mca.Animation(default_framerate=fps)
    keys = [f.time * fps for f in frames]
    for link in last.T_palm_link:
        _transform_tracks(anim, root["hand"][link].path, keys,
                          np.stack([f.T_palm_link[link] for f in frames]), fps)
    _transform_tracks(anim, root["object"].path, keys, np.stack([f.T_palm_object for f in frames]), fps)
    _transform_tracks(anim, root["ghost"].path, keys, T_plan, fps)
    vis.set_animation(anim, play=True, repetitions=1)
    labels, times = _labels(report, plan)
    legend = [e for e in legend_entries(plan, hand, obj) if e.text != "current contact"]
    legend = [LegendEntry(e.swatch, e.color, "simulated " + e.text) if e.color == OBJECT_COLOR else e
              for e in legend] + [LegendEntry("block", GHOST_COLOR, "planned object pose")]
    window.overlay = overlay_html(f"{obj.name} · {_verdict_line(report)}", labels, times, legend,
                                  hint=LEGEND_HINT)
    title = (f"regrasp simulation: {obj.name}, {len(plan.steps)} steps, {report.status}"
             ).replace("&", "&amp;").replace("<", "&lt;")
    return vis.static_html().replace("<title>MeshCat</title>", f"<title>{title}</title>", 1)


def write_sim_html(report: SimReport, plan: Plan, path: str | Path, hand=None, obj=None,
                   fps: float = 25.0) -> Path:
    """Write the simulation replay (`sim_html`) to ``path`` (parent folders created); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, sim_html(report, plan, hand, obj, fps=fps))
    logger.info("wrote %s (%.0f kB)", path, path.stat().st_size / 1e3)
    return path
