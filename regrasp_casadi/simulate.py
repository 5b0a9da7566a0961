"""Execute a plan in physics (MuJoCo) and measure whether the hand really holds the object.

    >>> report = simulate(plan, options=SimOptions(gravity_palm=(0, 0, -9.81)))
    >>> print(report.summary())       # held / deviating / dropped, deviations in mm and degrees

The model (`regrasp_casadi.mujoco_model`) is built from the project's own hand and object data. The run:

1. **Settle** (`SimOptions.settle_time`): the hand at the plan's first joints, the object at its planned
   pose; every fingertip that touches the object is commanded into the surface so that the position
   servos press and the fingers grip (`SimOptions.grip`: "balanced" contact forces that cancel gravity's
   wrench, or a uniform `squeeze_depth` of 2 mm along the contact normal; see `sim_control`). Grip and
   gravity ramp in over the first 60 % of the settle.
2. **Track** the plan's motion (`sim_control.plan_motion`: each step's path, `PlanStep.path`, at its time
   stamps; a step without a path: joints linearly interpolated in max(`min_step_duration`, largest
   joint change / `joint_velocity`)), the grip kept on every holding finger. The finger moved by a gait
   step hands its load over, follows its path (lift-off, transit, touch-down; without a path its tip is
   raised `lift_height` above the surface in mid-move) and lands again, while the others hold the
   planned object pose. The loop is closed on the object's pose (`SimOptions.feedback`, default
   "object_pose", `sim_feedback`): the holding tips move by the rigid correction that takes the simulated
   object onto the plan, integrated; "none" executes open loop. A second loop keeps each holding tip's
   normal force at least at the grip's (`SimOptions.force_gain`, default 3/s, 0: off;
   `sim_grip_feedback`, MuJoCo's contact forces as the sensor).
3. **Hold** the last step for `hold_time`.

Deviation = distance (mm) between the simulated and planned positions of the object's centre of mass,
and the angle (degrees) between the simulated and planned orientations, both in the palm frame, at the
end of every step. The object is **dropped** when a deviation exceeds `drop_distance` (2 cm) at any time,
or fewer than `min_fingers` (2) fingers touch it at a step end; the plan is **followed** ("held") when it
is not dropped, every step-end deviation is within `tol_position` / `tol_rotation` (5 mm / 5°), and
every fingertip is within `tol_tip_drift` (5 mm) of where the plan has it on the object (tip centres in
the object frame, `StepRecord.tip_drift_mm`): an object kept at its pose by fingers that slipped to other
places on it, or whose slide did not happen, is not the plan executed.

Cost: per physics step (`timestep`) only the joint targets are written and MuJoCo steps; the targets of
the whole run are computed before it (`joint_commands`, every `CONTROL_DT`, one batch), the feedback
updates every `CONTROL_DT`, the time series every `record_dt`. Wall time on the shipped plans:
benchmarks/simulate_time.py (0.8-3.2 s for 14-82 s simulated on two shared cores at load ~1).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.mujoco_model import SimModel, SimOptions, build_model
from regrasp_casadi.sim_control import CONTROL_DT, joint_commands, plan_motion, step_durations, step_end_times
from regrasp_casadi.sim_feedback import ObjectPoseFeedback
from regrasp_casadi.sim_grip_feedback import GripForceFeedback
from regrasp_casadi.transforms import inv_T, rotation_angle, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import Plan

__all__ = ["SimOptions", "SimReport", "StepRecord", "simulate", "plan_motion", "step_durations"]

_MOTION_SERIES = ("q", "T_palm_object", "T_palm_object_plan")


# ------------------------------------------------------------------------------------------ report
@dataclass(frozen=True)
class StepRecord:
    """The simulated state at the end of one plan step (or of the final hold)."""

    step: int
    """Plan step index (len(plan.steps) for the end of the final hold)."""
    kind: str
    """Plan step kind ("initial", "gait", "repose", "final") or "hold"."""
    finger: str | None
    """Finger moved by a gait step."""
    time: float
    """Simulated time, s (0 = start of the settle)."""
    deviation_mm: float
    """Distance between simulated and planned object centre of mass, palm frame, mm."""
    deviation_deg: float
    """Angle between simulated and planned object orientation, degrees."""
    fingers_touching: tuple[str, ...]
    """Fingers with at least one contact with the object at the step end or in the `touch_window`
    before it (a finger bouncing off for a few ms at that instant still holds)."""
    tip_normal_force: dict[str, float]
    """finger -> normal force of its fingertip sphere's contacts with the object, N."""
    other_normal_force: float
    """Sum of the normal forces of the other hand geoms (links, palm) on the object, N."""
    grip_residual: float
    """Wrench the planned holding contacts cannot balance ("balanced" grip LP, worst over the step's
    phases), N (torques counted at 5 cm); > 0 means the planned grasp cannot hold against gravity
    with `grip_force` pressing (e.g. three fingers on one face)."""
    tip_drift_mm: dict[str, float] = field(default_factory=dict)
    """finger -> distance between its simulated and planned tip centre in the OBJECT frame, mm: how far
    the finger is from where the plan has it on the object (a contact the fingers slipped off, a slide
    that did not happen), whatever the object's own deviation."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        d = dict(self.__dict__)
        d["fingers_touching"] = list(self.fingers_touching)
        return d


@dataclass(frozen=True)
class SimReport:
    """Result of `simulate`: per-step deviations and contact forces, the verdict and timings."""

    status: str
    """"held" (followed within tolerance), "deviating" (not dropped, beyond tolerance) or "dropped"."""
    detail: str
    """Why it is not held ("" when held)."""
    steps: tuple[StepRecord, ...]
    """One record per plan step end, then one for the end of the final hold."""
    max_deviation_mm: float
    """Largest step-end position deviation, mm."""
    max_deviation_deg: float
    """Largest step-end rotation deviation, degrees."""
    max_tip_drift_mm: float
    """Largest step-end tip drift (`StepRecord.tip_drift_mm`) of any finger, mm."""
    dropped: bool
    """Deviation above `drop_distance` at any time, or fewer than `min_fingers` touching at a step end."""
    drop_time: float | None
    """Simulated time of the drop, s (None if not dropped)."""
    sim_time: float
    """Simulated duration, s."""
    wall_time: float
    """Wall-clock time of the whole call (model build included), s."""
    object_mass: float
    """Object mass used, kg."""
    options: dict
    """`SimOptions` used (`SimOptions.to_dict()`)."""
    series: dict = field(default_factory=dict)
    """Time series every `record_dt`: "t" (k,) s, "deviation_mm" (k,), "deviation_deg" (k,),
    "n_touching" (k,) fingers touching, "tip_normal_force" (k, m) N in `hand.fingers` order,
    "other_normal_force" (k,) N, and the simulated motion: "q" (k, n) rad, "T_palm_object" (k, 4, 4)
    palm frame, with the plan's object pose at the same instants "T_palm_object_plan" (k, 4, 4)."""

    @property
    def held(self) -> bool:
        """True when the plan is followed within the tolerances (status "held")."""
        return self.status == "held"

    def summary(self) -> str:
        """One line: verdict, max and final deviation (before the drop, for a dropped object), simulated
        and wall time."""
        g_palm = tuple(self.options.get("gravity_palm", ()))
        g = "gravity off" if not any(g_palm) else (
            "gravity " + " ".join(f"{v:g}" for v in g_palm) + " m/s^2 in the palm frame")
        if self.dropped:
            before = [r for r in self.steps if r.time < self.drop_time - 1e-9]
            text = f"simulate: dropped at t = {self.drop_time:.2f} s"
            if before:
                text += (f"; before it max deviation {max(r.deviation_mm for r in before):.2f} mm / "
                         f"{max(r.deviation_deg for r in before):.2f} deg")
        else:
            last = self.steps[-1]
            text = (f"simulate: {self.status}; max deviation {self.max_deviation_mm:.2f} mm / "
                    f"{self.max_deviation_deg:.2f} deg, final {last.deviation_mm:.2f} mm / "
                    f"{last.deviation_deg:.2f} deg, max tip drift {self.max_tip_drift_mm:.2f} mm")
        text += (f"; {len(self.steps) - 1} steps, {self.sim_time:.2f} s simulated in {self.wall_time:.2f} s"
                 f" ({g})")
        return text + (f" [{self.detail}]" if self.detail else "")

    def to_dict(self, motion: bool = False) -> dict[str, Any]:
        """JSON-ready dict of every field (``held`` included); the series' simulated motion ("q",
        "T_palm_object", "T_palm_object_plan") only with ``motion=True``."""
        d = {k: v for k, v in self.__dict__.items() if k not in ("steps", "series")}
        d["held"] = self.held
        d["steps"] = [s.to_dict() for s in self.steps]
        d["series"] = {k: np.asarray(v).tolist() for k, v in self.series.items()
                       if motion or k not in _MOTION_SERIES}
        return d


# ------------------------------------------------------------------------------------------ simulation
class _Probe:
    """Reads the object pose error and the hand-object contacts from MjData."""

    def __init__(self, sim: SimModel, hand, opts: SimOptions) -> None:
        self.sim, self.fingers = sim, tuple(hand.fingers)
        R = opts.R_world_palm
        self.T_palm_world = np.eye(4)
        self.T_palm_world[:3, :3] = R.T
        self._force = np.zeros(6)
        ngeom = sim.model.ngeom
        self._is_object = np.zeros(ngeom, dtype=bool)
        self._is_object[list(sim.object_geoms)] = True
        self._finger_row = np.full(ngeom, -2)  # per geom: its finger row; −1 hand, no finger; −2 not hand
        for g, finger in sim.geom_finger.items():
            self._finger_row[g] = self.fingers.index(finger) if finger in self.fingers else -1
        self._is_tip = np.zeros(ngeom, dtype=bool)
        self._is_tip[list(sim.tip_geom.values())] = True

    def T_palm_object(self, data: mujoco.MjData) -> NDArray:
        T = np.eye(4)
        T[:3, :3] = data.xmat[self.sim.object_body].reshape(3, 3)
        T[:3, 3] = data.xpos[self.sim.object_body]
        return self.T_palm_world @ T

    def p_object_tip(self, data: mujoco.MjData) -> NDArray:
        """(m, 3) the simulated tip-sphere centres in the simulated object's frame, m, ``fingers`` order."""
        T_object_world = inv_T(self.T_palm_object(data)) @ self.T_palm_world
        return transform_points(T_object_world, data.geom_xpos[[self.sim.tip_geom[f] for f in self.fingers]])

    def deviation(self, data: mujoco.MjData, T_plan: NDArray, T_sim: NDArray | None = None
                  ) -> tuple[float, float]:
        """(position error mm of the centre of mass, rotation error degrees) against ``T_plan``; ``T_sim``
        the simulated pose (4, 4), palm frame, when already read (else read from ``data``)."""
        T = self.T_palm_object(data) if T_sim is None else T_sim
        com = self.sim.p_object_com
        dp = (T[:3, :3] @ com + T[:3, 3]) - (T_plan[:3, :3] @ com + T_plan[:3, 3])
        return float(np.linalg.norm(dp) * 1e3), float(np.degrees(rotation_angle(T_plan[:3, :3], T[:3, :3])))

    def _hand_object_contacts(self, data: mujoco.MjData) -> tuple[NDArray, NDArray]:
        """(indices (c,) in ``data.contact`` of the hand-object contacts, the hand geom of each (c,))."""
        geom = data.contact.geom[:data.ncon]
        on_object_1 = self._is_object[geom[:, 0]]
        hand_geom = np.where(on_object_1, geom[:, 1], geom[:, 0])
        keep = (on_object_1 | self._is_object[geom[:, 1]]) & (self._finger_row[hand_geom] > -2)
        return np.flatnonzero(keep), hand_geom[keep]

    def touching(self, data: mujoco.MjData) -> set[str]:
        """Fingers with at least one contact with the object."""
        rows = self._finger_row[self._hand_object_contacts(data)[1]]
        return {self.fingers[r] for r in rows[rows >= 0]}

    def contacts(self, model: mujoco.MjModel, data: mujoco.MjData):
        """(fingers touching, finger -> tip normal force N, other hand normal force N)."""
        touching, tip_force, other = set(), dict.fromkeys(self.fingers, 0.0), 0.0
        for i, g in zip(*self._hand_object_contacts(data), strict=True):
            mujoco.mj_contactForce(model, data, int(i), self._force)
            row = self._finger_row[g]
            if row >= 0:
                touching.add(self.fingers[row])
            if row >= 0 and self._is_tip[g]:
                tip_force[self.fingers[row]] += float(self._force[0])
            else:
                other += float(self._force[0])
        return tuple(f for f in self.fingers if f in touching), tip_force, other


def _record(probe: _Probe, model, data, T_plan, *, step: int, kind: str, finger, residual: float,
            recent: set[str], p_object_tip_plan: NDArray) -> StepRecord:
    """The step-end record; `recent`: fingers that touched the object within the touch window;
    `p_object_tip_plan` (m, 3) the step's planned tip centres, object frame, m."""
    dev_mm, dev_deg = probe.deviation(data, T_plan)
    touching, tip_force, other = probe.contacts(model, data)
    touching = tuple(f for f in probe.fingers if f in recent or f in touching)
    drift = np.linalg.norm(probe.p_object_tip(data) - p_object_tip_plan, axis=1) * 1e3
    return StepRecord(step, kind, finger, float(data.time), dev_mm, dev_deg, touching, tip_force, other,
                      float(residual), {f: float(d) for f, d in zip(probe.fingers, drift, strict=True)})


def _place(sim: SimModel, data: mujoco.MjData, q0: NDArray, T_palm_object: NDArray,
           opts: SimOptions) -> None:
    """Hand joints at q0, object at T_palm_object (palm frame) in the world frame (qpos only)."""
    data.qpos[sim.qpos_hand] = q0
    R_world_object = opts.R_world_palm @ T_palm_object[:3, :3]
    p_world_object = opts.R_world_palm @ T_palm_object[:3, 3]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, R_world_object.reshape(9))
    data.qpos[sim.qpos_object:sim.qpos_object + 3] = p_world_object
    data.qpos[sim.qpos_object + 3:sim.qpos_object + 7] = quat


def _initial_state(sim: SimModel, data: mujoco.MjData, q0: NDArray, T_palm_object: NDArray,
                   opts: SimOptions) -> None:
    """Hand at q0 (at rest), object at its planned pose in the world frame."""
    _place(sim, data, q0, T_palm_object, opts)
    data.qvel[:] = 0.0
    data.ctrl[sim.actuator] = q0
    mujoco.mj_forward(sim.model, data)


def surface_distances(sim: SimModel, plan: Plan, hand, opts: SimOptions) -> NDArray:
    """(s, m) per step and finger (``plan.fingers`` order): how far the tip sphere is from the SIMULATED
    object (its convex pieces, MuJoCo's signed distance, m; < 0 inside) minus how far the plan has it
    from the mesh, at the step's planned q and object pose; 0 for a finger the plan has not touching."""
    from regrasp_casadi.sim_control import step_contacts

    model, data = sim.model, mujoco.MjData(sim.model)
    rows = [list(hand.fingers).index(f) for f in plan.fingers]
    out = np.zeros((len(plan.steps), len(plan.fingers)))
    for i, (step, contacts) in enumerate(zip(plan.steps, step_contacts(plan, hand), strict=True)):
        T = np.asarray(step.T_palm_object, dtype=float)
        _place(sim, data, step.q, T, opts)
        mujoco.mj_kinematics(model, data)
        tips = hand.tip_positions(step.q)[rows]
        for m, f in enumerate(plan.fingers):
            if not contacts.touching[m]:
                continue
            p_palm_contact = T[:3, :3] @ contacts.p_object[m] + T[:3, 3]
            planned = np.linalg.norm(tips[m] - p_palm_contact) - hand.tip_radius
            d = min(mujoco.mj_geomDistance(model, data, sim.tip_geom[f], g, 0.02, None)
                    for g in sim.object_geoms)
            out[i, m] = d - planned
    return out


def _timeline(sim: SimModel, plan: Plan, hand, opts: SimOptions):
    """Targets at every simulation step: (q_cmd (N, n), planned T (N, 4, 4), holding weights (N, m),
    step-end sim indices, settle length, grip residual per step, the hand's start q (n,), and the grip
    targets (planned normal forces (N, m), N; outward contact normals (N, m, 3), palm frame))."""
    surface = surface_distances(sim, plan, hand, opts) if opts.surface_correction else None
    cmd = joint_commands(plan, hand, opts, sim.object_mass, sim.p_object_com, surface)
    t, q_cmd, T, q_grip0, residual, q0, holding = cmd[:7]
    dt = opts.timestep
    n_settle = int(round(opts.settle_time / dt))
    n_hold = int(round(opts.hold_time / dt))
    t_sim = np.arange(int(round(t[-1] / dt)) + 1) * dt
    Q = np.column_stack([np.interp(t_sim, t, q_cmd[:, j]) for j in range(q_cmd.shape[1])])
    idx = np.clip(np.searchsorted(t, t_sim), 0, len(t) - 1)
    ramp = np.clip(np.arange(n_settle) / max(0.6 * n_settle, 1), 0.0, 1.0)[:, None]
    Q = np.vstack([q0 + ramp * (q_grip0 - q0), Q, np.repeat(Q[-1:], n_hold, axis=0)])
    # velocity feed-forward: the servo force kp (ctrl − q) − kv q̇ − damping q̇ then has no lag on a ramp
    Q = Q + (opts.kv + opts.joint_damping) / opts.kp * np.gradient(Q, dt, axis=0)
    T_ref = np.concatenate([np.repeat(T[:1], n_settle, 0), T[idx], np.repeat(T[-1:], n_hold, 0)])
    W, press, n_palm = (np.concatenate([np.repeat(a[:1], n_settle, 0), a[idx], np.repeat(a[-1:], n_hold, 0)])
                        for a in (holding, cmd.press, cmd.n_palm))
    t_end = step_end_times(plan, opts.joint_velocity, opts.min_step_duration, opts.unload_fraction,
                           opts.min_handover_time)
    ends = n_settle + np.rint(t_end / dt).astype(int)
    return Q, T_ref, W, ends, n_settle, residual, q0, (press, n_palm)


def _sample(series: dict[str, list], probe: _Probe, data: mujoco.MjData, T_plan: NDArray) -> float:
    """Append one sample of every time series (`SimReport.series`) at the current state, the planned
    object pose ``T_plan`` (4, 4) palm frame; returns its position deviation, mm."""
    T_sim = probe.T_palm_object(data)
    dev_mm, dev_deg = probe.deviation(data, T_plan, T_sim)
    touching, tip_force, other = probe.contacts(probe.sim.model, data)
    sample = {"t": float(data.time), "deviation_mm": dev_mm, "deviation_deg": dev_deg,
              "n_touching": len(touching), "tip_normal_force": [tip_force[f] for f in probe.fingers],
              "other_normal_force": other, "q": data.qpos[probe.sim.qpos_hand].copy(), "T_palm_object": T_sim,
              "T_palm_object_plan": np.asarray(T_plan, dtype=float)}
    for key, value in sample.items():
        series[key].append(value)
    return dev_mm


def _run(sim: SimModel, plan: Plan, hand, opts: SimOptions):
    """Step the simulation along the timeline; returns (step records, series, drop time or None).

    Per physics step only the joint targets are set (the timeline's, plus the feedback's offset, which
    changes every `CONTROL_DT`); the feedback, the touch window's contact reads, the step-end records and
    the time series' samples run at their own instants."""
    model, data = sim.model, mujoco.MjData(sim.model)
    Q, T_ref, W, ends, n_settle, residual, q_start, (press, n_palm) = _timeline(sim, plan, hand, opts)
    feedback = ObjectPoseFeedback(sim, plan.fingers, opts) if opts.feedback == "object_pose" else None
    force = GripForceFeedback(sim, plan.fingers, opts) if opts.force_gain > 0 and opts.grip == "balanced" \
        else None
    pose_offset, force_offset = np.zeros(Q.shape[1]), np.zeros(Q.shape[1])
    every_control = max(int(round(CONTROL_DT / opts.timestep)), 1)
    offset = np.zeros(Q.shape[1])
    gravity = np.array(model.opt.gravity)
    _initial_state(sim, data, q_start, plan.steps[0].T_palm_object, opts)
    probe = _Probe(sim, hand, opts)
    every = max(int(round(opts.record_dt / opts.timestep)), 1)
    step_at = {int(k): i for i, k in enumerate(ends)}
    series: dict[str, list] = {k: [] for k in ("t", "deviation_mm", "deviation_deg", "n_touching",
                                               "tip_normal_force", "other_normal_force", *_MOTION_SERIES)}
    window = max(1, int(round(opts.touch_window / opts.timestep)))
    watch = {e - j for e in [*step_at, len(Q)] for j in range(1, window)}  # sim steps just before an end
    records, drop_time, recent = [], None, set()
    tips_plan = [transform_points(inv_T(st.T_palm_object), np.asarray(hand.tip_positions(st.q), dtype=float))
                 for st in plan.steps]  # (m, 3) per step, object frame, m
    direct = np.array_equal(sim.actuator, np.arange(model.nu))  # actuator ids in joint order: no gather
    for k in range(len(Q)):
        if k <= n_settle:
            model.opt.gravity[:] = gravity * min(1.0, k / max(0.6 * n_settle, 1))
        if direct:
            np.add(Q[k], offset, out=data.ctrl)
        else:
            data.ctrl[sim.actuator] = Q[k] + offset
        mujoco.mj_step(model, data)
        if (k + 1) % every_control == 0 and (feedback is not None or force is not None):
            dt_control = every_control * opts.timestep
            if feedback is not None:
                pose_offset = feedback.update(data, T_ref[k], probe.T_palm_object(data), W[k], dt_control)
            if force is not None:
                f_tip = probe.contacts(model, data)[1]
                force_offset = force.update(data, np.array([f_tip[f] for f in plan.fingers]), press[k],
                                            n_palm[k], W[k], dt_control)
            offset = pose_offset + force_offset
        if k + 1 in watch:
            recent.update(probe.touching(data))
        if k + 1 in step_at:
            i = step_at[k + 1]
            st = plan.steps[i]
            records.append(_record(probe, model, data, st.T_palm_object, step=i, kind=st.kind,
                                   finger=st.finger, residual=residual[i], recent=recent,
                                   p_object_tip_plan=tips_plan[i]))
            recent = set()
        if (k + 1) % every == 0 or k + 1 == len(Q):
            dev_mm = _sample(series, probe, data, T_ref[k])
            if drop_time is None and dev_mm > opts.drop_distance * 1e3:
                drop_time = float(data.time)
    model.opt.gravity[:] = gravity
    records.append(_record(probe, model, data, plan.steps[-1].T_palm_object, step=len(plan.steps),
                           kind="hold", finger=None, residual=residual[-1], recent=recent,
                           p_object_tip_plan=tips_plan[-1]))
    return records, series, drop_time


def _verdict(records: list[StepRecord], drop_time: float | None, opts: SimOptions):
    """(status, detail, dropped, drop time) from the step records and the first over-deviation time."""
    few = next((r for r in records if len(r.fingers_touching) < opts.min_fingers), None)
    if few is not None and (drop_time is None or few.time < drop_time):
        return ("dropped", f"{len(few.fingers_touching)} finger(s) touching the object at the end of step "
                f"{few.step} (t = {few.time:.2f} s)", True, few.time)
    if drop_time is not None:
        return ("dropped", f"object more than {opts.drop_distance * 1e3:.0f} mm from the plan at "
                f"t = {drop_time:.2f} s", True, drop_time)
    worst = max(records, key=lambda r: r.deviation_mm)
    worst_r = max(records, key=lambda r: r.deviation_deg)
    if worst.deviation_mm > opts.tol_position * 1e3 or worst_r.deviation_deg > opts.tol_rotation:
        return ("deviating", f"step {worst.step}: {worst.deviation_mm:.2f} mm, step {worst_r.step}: "
                f"{worst_r.deviation_deg:.2f} deg (tolerance {opts.tol_position * 1e3:g} mm / "
                f"{opts.tol_rotation:g} deg)", False, None)
    drift = max(records, key=lambda r: max(r.tip_drift_mm.values(), default=0.0))
    finger, mm = max(drift.tip_drift_mm.items(), key=lambda kv: kv[1], default=(None, 0.0))
    if mm > opts.tol_tip_drift * 1e3:
        return ("deviating", f"step {drift.step}: the {finger} tip {mm:.2f} mm from its planned place on the "
                f"object (tolerance {opts.tol_tip_drift * 1e3:g} mm)", False, None)
    return "held", "", False, None


def simulate(plan: Plan, hand=None, obj=None, options: SimOptions | None = None) -> SimReport:
    """Execute ``plan`` in MuJoCo and report how closely the object follows it.

    Args:
        plan: a Plan (its steps' q, T_palm_object, contacts_object, kind, finger are used).
        hand, obj: the plan's Hand and ObjectModel (default: rebuilt from the plan's specs).
        options: physics and execution constants (default `SimOptions()`: gravity off). Without an
            `object_mass`, the plan's ``options["object_mass"]`` (the problem's `object.mass`) when it has
            one, else the mesh volume × `object_density`.

    Returns:
        SimReport: per-step deviation (mm, degrees) and contact normal forces, verdict, timings.
    """
    t0 = time.perf_counter()
    opts = options or SimOptions()
    planned_mass = (plan.options or {}).get("object_mass")
    if opts.object_mass is None and planned_mass is not None:  # the problem's object.mass
        opts = dataclasses.replace(opts, object_mass=float(planned_mass))
    if hand is None or obj is None:
        from regrasp_casadi.problem import plan_models

        hand, obj = plan_models(plan, hand, obj)
    sim = build_model(hand, obj, opts)
    records, series, drop_time = _run(sim, plan, hand, opts)
    status, detail, dropped, drop_t = _verdict(records, drop_time, opts)
    return SimReport(
        status=status, detail=detail, steps=tuple(records),
        max_deviation_mm=max(r.deviation_mm for r in records),
        max_deviation_deg=max(r.deviation_deg for r in records),
        max_tip_drift_mm=max(max(r.tip_drift_mm.values(), default=0.0) for r in records),
        dropped=dropped, drop_time=drop_t, sim_time=float(len(series["t"]) and series["t"][-1]),
        wall_time=time.perf_counter() - t0, object_mass=sim.object_mass, options=opts.to_dict(),
        series={k: np.asarray(v) for k, v in series.items()},
    )
