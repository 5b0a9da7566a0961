"""The joint targets that execute a plan on position-controlled fingers (used by `simulate`).

    >>> t, q, T_palm_object = plan_motion(plan, dt=0.01)         # the plan's nominal motion
    >>> t, q_cmd, T_palm_object = joint_commands(plan, hand, SimOptions(), mass=0.2, p_object_com=c)

Two layers:

* `plan_motion` — the plan's motion as executed: each step follows its path (`PlanStep.path`, the
  trajectory module's lift-off / transit / touch-down and reposing knots, at their time stamps); a step
  without a path moves its joints linearly and its object pose along the geodesic, in max(
  `min_step_duration`, largest joint change / `joint_velocity`). A gait's motion fills the middle
  1 − 2 `unload_fraction` of its step (`step_durations`).
* `joint_commands` — adds what makes position servos hold the object:
  **grip**: every fingertip that touches the object presses on it. With ``grip="balanced"`` (default) the
  contact forces f_k (object frame) are the smallest ones (normal ≥ `grip_force`, inside the friction
  cones shrunk to `grip_friction_fraction` · μ) whose wrench cancels gravity's on the object (a linear
  program; with no force closure the residual is minimised and reported); the finger's targets are offset
  by Jᵀ f / kp, so that the servo pushes with f while the tip sits at the planned contact (the tip is
  commanded (J Jᵀ / kp) f ≈ 1–3 mm into the surface). With ``grip="squeeze"`` each touching tip is commanded
  `squeeze_depth` into the surface along the contact normal (tip Jacobian solved by damped least squares).
  **gait**: the moving finger first hands its load over to the others (the first `unload_fraction` of
  the step), then moves (along its path; without a path its joints along a smoothstep of the linear
  interpolation, its tip raised `lift_height` above the surface in mid-move, a sine profile along the
  contact normal), then takes its load again (the last `unload_fraction`). The other fingers hold the
  planned object pose.

Contact normal of a finger at a step = unit vector from its contact point to its tip-sphere centre
(outward); a finger touches when that distance is within 1 mm of the tip radius.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linprog

from regrasp_casadi.motion import interpolate_knots
from regrasp_casadi.mujoco_model import SimOptions
from regrasp_casadi.stability import tangent_basis
from regrasp_casadi.transforms import interpolate_pose

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import Plan

__all__ = ["plan_motion", "step_durations", "step_end_times", "joint_commands", "Commands", "grip_forces",
           "StepContacts", "step_contacts", "CONTROL_DT"]

CONTROL_DT = 5e-3
"""Period at which the commanded joint targets are computed, s (linearly interpolated in between)."""
_TOUCH_TOL = 1e-3    # m: a planned tip centre within this of tip_radius from its contact touches
_DLS_DAMPING = 1e-3  # m: damping of the least-squares tip-Jacobian solve
_SLACK_WEIGHT = 1e3  # weight of the wrench residual against the normal forces in the grip LP
_TORQUE_FRACTION = 0.8  # share of the actuator torque limit the grip may use (the rest tracks motion)
_TANGENT_WEIGHT = 0.3  # cost of 1 N of tangential force against 1 N of normal force (no needless shear)
_TORQUE_LENGTH = 0.05   # m: torques are divided by it in the LP (comparable with forces)
_JACOBIAN_CHUNK = 512   # configurations per mapped CasADi Jacobian call (building a map costs ∝ its size)


MOVING_FINGER_KINDS = ("gait", "slide")
"""Step kinds that move one finger (`PlanStep.finger`) while the others hold: it hands its load over
first and takes it back at the end; a "gait" lifts it, a "slide" (the certified planner's) keeps it on
the surface pushing along its contact normal (with `SimOptions.slide_drag`, the grip LP also plans
the other fingers to balance its Coulomb kinetic friction μ f_n along its motion, and its residual
says when they cannot)."""


# ------------------------------------------------------------------------------------------ plan motion
def _motion_time(plan: Plan, i: int, joint_velocity: float) -> float:
    """Duration of step i's own motion, s: its path's (`StepPath.duration`), else the largest joint
    change / `joint_velocity`."""
    step = plan.steps[i]
    if getattr(step, "path", None) is not None:
        return float(step.path.duration)
    dq = np.abs(np.asarray(step.q, dtype=float) - np.asarray(plan.steps[i - 1].q, dtype=float))
    return float(dq.max(initial=0.0)) / joint_velocity


def step_durations(plan: Plan, joint_velocity: float = 1.0, min_step_duration: float = 0.2,
                   unload_fraction: float = 0.0, min_handover_time: float = 0.0) -> NDArray:
    """(s,) duration of each step in the execution, s: 0 for step 0, else max(min_step_duration, D) for a
    step that moves no single finger, and for a gait or slide (its load is handed over before and after
    the motion) max(min_step_duration, D / (1 − 2 `unload_fraction`), min_handover_time /
    unload_fraction); D is the step's own motion time: its path's duration, or max_j |q_i,j − q_i−1,j| /
    joint_velocity for a step without a path."""
    out = [0.0]
    for i in range(1, len(plan.steps)):
        d = _motion_time(plan, i, joint_velocity)
        if plan.steps[i].kind in MOVING_FINGER_KINDS:
            d = max(d / (1.0 - 2.0 * unload_fraction),
                    min_handover_time / unload_fraction if unload_fraction > 0 else 0.0)
        out.append(max(min_step_duration, d))
    return np.asarray(out)


def step_end_times(plan: Plan, joint_velocity: float = 1.0, min_step_duration: float = 0.2,
                   unload_fraction: float = 0.0, min_handover_time: float = 0.0) -> NDArray:
    """(s,) time at which each step's motion ends, s (step 0 at 0), `step_durations` summed."""
    return np.cumsum(step_durations(plan, joint_velocity, min_step_duration, unload_fraction,
                                    min_handover_time))


def _segments(t_end: NDArray, t: NDArray) -> tuple[NDArray, NDArray]:
    """For times t (k,): the step i ≥ 1 being moved into and the phase s ∈ [0, 1] within it."""
    if len(t_end) == 1:
        return np.zeros(len(t), dtype=int), np.ones(len(t))
    i = np.clip(np.searchsorted(t_end, t, side="left"), 1, len(t_end) - 1)
    span = np.maximum(t_end[i] - t_end[i - 1], 1e-12)
    return i, np.clip((t - t_end[i - 1]) / span, 0.0, 1.0)


def step_motion(plan: Plan, i: int, u: NDArray) -> tuple[NDArray, NDArray]:
    """The motion of step i ≥ 1 at fractions u (k,) ∈ [0, 1] of it: along its path at time u · duration
    (`motion.interpolate_knots`), else joints linear and the object on the geodesic from step i − 1.

    Returns:
        q (k, n) rad; T_palm_object (k, 4, 4), palm frame.
    """
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    step, prev = plan.steps[i], plan.steps[i - 1]
    path = getattr(step, "path", None)
    if path is not None:
        return interpolate_knots(path.t, path.q, path.T_palm_object, u * path.duration)
    q0, q1 = np.asarray(prev.q, dtype=float), np.asarray(step.q, dtype=float)
    T = np.stack([interpolate_pose(prev.T_palm_object, step.T_palm_object, float(uk)) for uk in u])
    return q0 + u[:, None] * (q1 - q0), T


def plan_motion(plan: Plan, dt: float, joint_velocity: float = 1.0, min_step_duration: float = 0.2,
                unload_fraction: float = 0.0, min_handover_time: float = 0.0):
    """The plan's motion sampled every ``dt`` s, as executed (`step_end_times` gives its timing).

    Step i ends at ``step_end_times(plan, ...)[i]``; in between, `step_motion` (the step's path, else
    joints linear and the object on the geodesic) runs at constant speed, over the whole step, or for a
    gait over its middle 1 − 2 `unload_fraction` (the joints stay before and after: the load hand-over).

    Returns:
        t (k,) s, from 0 to the end of the last step (included); q (k, n) rad; T_palm_object (k, 4, 4).
    """
    t_end = step_end_times(plan, joint_velocity, min_step_duration, unload_fraction, min_handover_time)
    t = np.arange(0.0, t_end[-1], dt)
    if t.size == 0 or t[-1] < t_end[-1] - 1e-12:
        t = np.append(t, t_end[-1])
    seg, s = _segments(t_end, t)
    q = np.empty((len(t), len(plan.steps[0].q)))
    T = np.empty((len(t), 4, 4))
    q[seg == 0], T[seg == 0] = np.asarray(plan.steps[0].q), np.asarray(plan.steps[0].T_palm_object)
    for i in np.unique(seg[seg > 0]):
        rows = seg == i
        u = s[rows]
        if plan.steps[i].kind in MOVING_FINGER_KINDS and unload_fraction > 0:
            u = (u - unload_fraction) / (1.0 - 2.0 * unload_fraction)
        q[rows], T[rows] = step_motion(plan, int(i), u)
    return t, q, T


# ------------------------------------------------------------------------------------------ contacts
@dataclass(frozen=True)
class StepContacts:
    """The planned contacts of one step, rows in ``plan.fingers`` order."""

    touching: NDArray[np.bool_]
    """(m,) the finger's tip sphere touches the object."""
    p_object: NDArray[np.float64]
    """(m, 3) contact points, object frame, m."""
    n_object: NDArray[np.float64]
    """(m, 3) outward unit contact normals, object frame."""
    torque_per_force: NDArray[np.float64]
    """(m, n, 3) joint torques (N·m) per unit tip force on the object (object frame, N): Jᵀ R_palm_object."""


def step_contacts(plan: Plan, hand) -> list[StepContacts]:
    """Per step: the fingers that touch and their contact normals (contact point -> tip centre)."""
    rows = [list(hand.fingers).index(f) for f in plan.fingers]
    out = []
    for step in plan.steps:
        T = np.asarray(step.T_palm_object)
        p_object_tips = (hand.tip_positions(step.q)[rows] - T[:3, 3]) @ T[:3, :3]
        p_contact = np.asarray(step.contacts_object, dtype=float)
        v = p_object_tips - p_contact
        dist = np.linalg.norm(v, axis=1)
        touching = np.abs(dist - hand.tip_radius) < _TOUCH_TOL
        tau = np.stack([hand.tip_jacobian(step.q, f).T @ T[:3, :3] for f in plan.fingers])
        out.append(StepContacts(touching, p_contact, v / np.maximum(dist, 1e-12)[:, None], tau))
    return out


# ------------------------------------------------------------------------------------------ grip forces
def _grip_lp(contacts: StepContacts, idx: NDArray, g_object: NDArray, mass: float, p_object_com: NDArray,
             opts: SimOptions, drag: tuple[int, NDArray] | None = None):
    """Matrices of the grip LP in the variables (c_n, c_1, c_2) per holding finger, then 12 slacks; `drag`
    (row, d (3,)): that finger's normal push −n comes with the tangential force c_n d (kinetic friction)."""
    k = idx.size
    nv = 3 * k + 12
    mu = opts.grip_friction_fraction * opts.friction * np.cos(np.pi / 8)  # octagon inscribed in the cone
    basis = [np.column_stack([-contacts.n_object[j], *tangent_basis(contacts.n_object[j])]) for j in idx]
    if drag is not None and drag[0] in idx:
        basis[int(np.flatnonzero(idx == drag[0])[0])][:, 0] += drag[1]
    A_eq = np.zeros((6, nv))
    ub_rows, ub_rhs = [], []
    for a, j in enumerate(idx):
        r = contacts.p_object[j] - p_object_com
        cross = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
        A_eq[:3, 3 * a:3 * a + 3] = basis[a]
        A_eq[3:, 3 * a:3 * a + 3] = cross @ basis[a] / _TORQUE_LENGTH
        for angle in np.arange(4) * np.pi / 4:  # |a_j · c_t| <= mu c_n
            for sign in (1.0, -1.0):
                row = np.zeros(nv)
                row[3 * a:3 * a + 3] = [-mu, sign * np.cos(angle), sign * np.sin(angle)]
                ub_rows.append(row)
                ub_rhs.append(0.0)
        M = contacts.torque_per_force[j] @ basis[a]  # joint torques per (c_n, c_1, c_2)
        for m_row in M[np.abs(M).max(axis=1) > 0]:  # |torque| <= _TORQUE_FRACTION * force_limit
            for sign in (1.0, -1.0):
                row = np.zeros(nv)
                row[3 * a:3 * a + 3] = sign * m_row
                ub_rows.append(row)
                ub_rhs.append(_TORQUE_FRACTION * opts.force_limit)
    A_eq[:, 3 * k:3 * k + 6] = np.eye(6)
    A_eq[:, 3 * k + 6:] = -np.eye(6)
    b_eq = np.concatenate([-mass * np.asarray(g_object, dtype=float), np.zeros(3)])
    return basis, A_eq, b_eq, np.array(ub_rows), np.array(ub_rhs)


def grip_forces(contacts: StepContacts, holding: NDArray, g_object: NDArray, mass: float,
                p_object_com: NDArray, opts: SimOptions, frictionless: int | None = None, *,
                drag: NDArray | None = None) -> tuple[NDArray, float]:
    """Fingertip forces on the object that hold it against gravity (a linear program).

    For the fingers in ``holding``: minimise Σ normal force + 0.3 Σ |tangential components| + 1000 ·
    |wrench residual|, with normal force ≥ ``opts.grip_force``, the tangential force in an octagonal
    pyramid inscribed in the cone of ``opts.grip_friction_fraction · opts.friction``, and every joint
    torque within 80 % of ``opts.force_limit``.

    Args:
        contacts: the step's contacts (object frame); holding: (m,) bool, fingers that press;
        g_object: (3,) gravity in the object frame, m/s²; mass: kg; p_object_com: (3,) m;
        frictionless: the row of a finger that pushes along its normal only (a sliding finger), or None.
        drag: (3,) object frame, the frictionless finger's kinetic friction per newton of its normal
            force (μ times the unit direction it slides in over the object): its force on the object is
            c_n (−n + drag), which the others must balance; None: none.

    Returns:
        (forces (m, 3) on the object, object frame, N, zero for fingers not holding;
         residual = |Σ f + m g| + |Σ (p − c) × f| / 5 cm, N: 0 when the contacts hold the object).
    """
    idx = np.flatnonzero(holding)
    forces = np.zeros((len(holding), 3))
    if idx.size == 0:
        return forces, float(np.linalg.norm(mass * np.asarray(g_object)))
    k = idx.size
    basis, A_eq, b_eq, A_ub, b_ub = _grip_lp(contacts, idx, g_object, mass, p_object_com, opts,
                                             None if drag is None or frictionless is None
                                             else (frictionless, np.asarray(drag, float)))
    # tangential components split into positive and negative parts: c_t = c_t+ − c_t−, both ≥ 0
    P = np.zeros((3 * k + 12, 5 * k + 12))
    for a in range(k):
        P[3 * a:3 * a + 3, 5 * a:5 * a + 5] = [[1, 0, 0, 0, 0], [0, 1, -1, 0, 0], [0, 0, 0, 1, -1]]
    P[3 * k:, 5 * k:] = np.eye(12)
    cost = np.concatenate([np.tile([1.0, *[_TANGENT_WEIGHT] * 4], k), np.full(12, _SLACK_WEIGHT)])
    bounds = []
    for j in idx:  # a frictionless (sliding) finger pushes along its normal only
        bounds += [(opts.grip_force, None)] + [(0.0, 0.0 if j == frictionless else None)] * 4
    bounds += [(0.0, None)] * 12
    res = linprog(cost, A_ub=A_ub @ P if len(A_ub) else None, b_ub=b_ub if len(A_ub) else None,
                  A_eq=A_eq @ P, b_eq=b_eq, bounds=bounds, method="highs")
    if res.status == 2 and len(A_ub):  # the torque limits exclude even the smallest grip: drop them
        keep = np.flatnonzero(b_ub == 0.0)
        res = linprog(cost, A_ub=A_ub[keep] @ P, b_ub=b_ub[keep], A_eq=A_eq @ P, b_eq=b_eq,
                      bounds=bounds, method="highs")
    if res.status != 0:  # pragma: no cover - feasible by construction (slacks)
        raise RuntimeError(f"grip force LP failed: {res.message}")
    x = P @ res.x
    for a, j in enumerate(idx):
        forces[j] = basis[a] @ x[3 * a:3 * a + 3]
    slack = x[3 * k:3 * k + 6] - x[3 * k + 6:]
    return forces, float(np.linalg.norm(slack[:3]) + np.linalg.norm(slack[3:]))


# ------------------------------------------------------------------------------------------ commands
def _smoothstep(u: float) -> float:
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


@dataclass(frozen=True)
class _Segment:
    """What the fingers do while moving into step i: grip at start / mid (gait) / end, object frame."""

    F0: NDArray
    F_mid: NDArray
    F1: NDArray
    w0: NDArray
    w_mid: NDArray
    w1: NDArray
    gait: int | None  # row of the gait finger


def _plan_segments(plan: Plan, hand, opts: SimOptions, mass: float, p_object_com: NDArray):
    """Per step i: a _Segment for the move into step i (index 0: the settle), and the LP residuals."""
    contacts = step_contacts(plan, hand)
    g_palm = np.asarray(opts.gravity_palm, dtype=float)

    def grip(i: int, holding: NDArray, frictionless: int | None = None, drag=None) -> tuple[NDArray, float]:
        g_object = np.asarray(plan.steps[i].T_palm_object)[:3, :3].T @ g_palm
        if opts.grip == "squeeze":
            return np.zeros((len(holding), 3)), 0.0
        return grip_forces(contacts[i], holding, g_object, mass, p_object_com, opts, frictionless, drag=drag)

    ends = [grip(i, contacts[i].touching) for i in range(len(plan.steps))]
    residual = [r for _, r in ends]
    segments = [_Segment(ends[0][0], ends[0][0], ends[0][0], *(contacts[0].touching,) * 3, None)]
    for i in range(1, len(plan.steps)):
        step, c0, c1 = plan.steps[i], contacts[i - 1], contacts[i]
        moving = step.kind in MOVING_FINGER_KINDS and step.finger
        g = list(plan.fingers).index(step.finger) if moving else None
        w_mid = c0.touching & c1.touching
        if g is not None and step.kind == "slide":  # the slider keeps pushing, along its normal only
            F_mid, r_mid = grip(i - 1, w_mid, frictionless=g, drag=_slide_drag(c0, c1, g, opts))
        elif g is not None:  # a gait: the lifted finger lets go
            w_mid = w_mid.copy()
            w_mid[g] = False
            F_mid, r_mid = grip(i - 1, w_mid)
        else:
            F_mid, r_mid = ends[i][0], 0.0
        residual[i] = max(residual[i], r_mid)
        segments.append(_Segment(ends[i - 1][0], F_mid, ends[i][0], c0.touching, w_mid, c1.touching, g))
    return segments, contacts, residual


def _slide_drag(c0: StepContacts, c1: StepContacts, g: int, opts: SimOptions) -> NDArray | None:
    """(3,) object frame: μ times the unit direction in which finger row g slides over the object from
    contacts c0 to c1 (tangent plane at c0), the kinetic friction its push drags the object with per
    newton of normal force; None when `SimOptions.slide_drag` is off or the finger does not move."""
    n = c0.n_object[g]
    d = c1.p_object[g] - c0.p_object[g]
    d = d - (d @ n) * n
    if not opts.slide_drag or np.linalg.norm(d) < 1e-6:
        return None
    return opts.friction * d / np.linalg.norm(d)


def _phase_weights(seg: _Segment, s: float, opts: SimOptions):
    """(grip forces (m, 3) object frame, squeeze weights (m,), motion phase u, lift phase) at phase s."""
    if seg.gait is None:
        return (1 - s) * seg.F0 + s * seg.F1, np.where(seg.w0 & seg.w1, 1.0, 0.0), s, None
    a = opts.unload_fraction
    if s < a:
        b = s / a
        F, w = (1 - b) * seg.F0 + b * seg.F_mid, (1 - b) * seg.w0 + b * seg.w_mid
    elif s > 1 - a:
        b = (s - 1 + a) / a
        F, w = (1 - b) * seg.F_mid + b * seg.F1, (1 - b) * seg.w_mid + b * seg.w1
    else:
        F, w = seg.F_mid, seg.w_mid.astype(float)
    u = (s - a) / max(1 - 2 * a, 1e-9)
    return F, w, _smoothstep(u), (min(max(u, 0.0), 1.0) if 0.0 < u < 1.0 else None)


def _dls(J: NDArray, dp: NDArray) -> NDArray:
    """(k, n) damped least-squares joint steps Jᵀ (J Jᵀ + λ² I)⁻¹ dp for tip Jacobians J (k, 3, n) and tip
    displacements dp (k, 3) (palm frame, m)."""
    A = J @ np.swapaxes(J, 1, 2) + _DLS_DAMPING**2 * np.eye(3)
    return np.einsum("kji,kj->ki", J, np.linalg.solve(A, dp[:, :, None])[:, :, 0])


def tip_jacobians(hand, fingers, q: NDArray) -> NDArray:
    """(k, m, 3, n) tip-centre Jacobians (palm frame, m/rad) of ``fingers`` at the configurations q (k, n)
    rad: `Hand.tip_jacobian_function` mapped over chunks of `_JACOBIAN_CHUNK` configurations, evaluated
    through preallocated buffers (the same numbers as k calls of `Hand.tip_jacobian`)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    k, n = q.shape
    chunk = max(1, min(k, _JACOBIAN_CHUNK))
    # CasADi is column-major: the input (n, chunk) is q_buf (chunk, n), the output (3, chunk n) out_buf
    q_buf, out_buf = np.zeros((chunk, n)), np.zeros((chunk, n, 3))
    out = np.empty((k, len(fingers), 3, n))
    for m, f in enumerate(fingers):
        buf, evaluate = hand.tip_jacobian_function(f).map(chunk).buffer()
        buf.set_arg(0, memoryview(q_buf))
        buf.set_res(0, memoryview(out_buf))
        for start in range(0, k, chunk):
            stop = min(start + chunk, k)
            q_buf[:stop - start] = q[start:stop]
            evaluate()
            out[start:stop, m] = out_buf[:stop - start].transpose(0, 2, 1)
    return out


def _tick_targets(plan: Plan, opts: SimOptions, segments, contacts, *, q_lin: NDArray, seg_idx: NDArray,
                  phase: NDArray, surface: NDArray | None):
    """Per control tick k: the joints before the grip offsets (k, n) rad, the contact normals (k, m, 3)
    (object frame, not unit), the `_Grip` of every tick stacked (F (k, m, 3), w (k, m), gait row (k,)
    (−1: none), lift phase (k,) (NaN: no lift), surface (k, m) or None)."""
    Q = np.array([st.q for st in plan.steps], dtype=float)
    k_ticks, m = len(q_lin), len(plan.fingers)
    q_cmd, n_object = np.empty_like(q_lin), np.empty((k_ticks, m, 3))
    F, w = np.empty((k_ticks, m, 3)), np.empty((k_ticks, m))
    gait, lift = np.full(k_ticks, -1), np.full(k_ticks, np.nan)
    d = None if surface is None else np.empty((k_ticks, m))
    for k in range(k_ticks):
        i, s = int(seg_idx[k]), float(phase[k])
        F[k], w[k], u, lift_k = _phase_weights(segments[i], s, opts)
        gait[k] = -1 if segments[i].gait is None else segments[i].gait
        if segments[i].gait is None or plan.steps[i].path is not None or plan.steps[i].kind == "slide":
            q_cmd[k] = q_lin[k]  # a gait's path lifts the finger itself; a slide stays on the surface
        else:  # a gait without a path: joints along a smoothstep, the tip lifted along the normal
            q_cmd[k] = Q[i - 1] + u * (Q[i] - Q[i - 1])
            lift[k] = np.nan if lift_k is None else lift_k
        n_object[k] = (1 - s) * contacts[max(i - 1, 0)].n_object + s * contacts[i].n_object
        if d is not None:
            d[k] = (1 - s) * surface[max(i - 1, 0)] + s * surface[i]
    return q_cmd, n_object, _Grip(F, w, gait, lift, d)


def _step0_instants(plan: Plan, seg: _Segment, contacts: StepContacts, surface: NDArray | None):
    """The two instants of the settle at step 0, gripping (its end) and not gripping (its start), both
    surface corrected: (q (2, n) rad, R_palm_object (2, 3, 3), normals (2, m, 3) object frame, `_Grip`)."""
    q = np.repeat(np.asarray(plan.steps[0].q, dtype=float)[None], 2, axis=0)
    R = np.repeat(np.asarray(plan.steps[0].T_palm_object, dtype=float)[None, :3, :3], 2, axis=0)
    n_object = np.repeat(contacts.n_object[None], 2, axis=0)
    grip = _Grip(np.stack([seg.F0, np.zeros_like(seg.F0)]),
                 np.stack([seg.w0.astype(float), np.zeros(len(seg.w0))]), np.full(2, -1), np.full(2, np.nan),
                 None if surface is None else np.repeat(surface[:1], 2, axis=0))
    return q, R, n_object, grip


def joint_commands(plan: Plan, hand, opts: SimOptions, mass: float, p_object_com: NDArray,
                   surface: NDArray | None = None):
    """Joint targets along the plan (every `CONTROL_DT`), grip and gait handling included: the plan's
    motion (`plan_motion`: each step's path when it has one) plus the grip offsets.

    Args:
        plan, hand: the plan and its Hand; opts: `SimOptions` (grip, grip_force, squeeze_depth,
            lift_height, unload_fraction, kp, gravity_palm, friction, timing fields);
        mass: object mass, kg; p_object_com: (3,) centre of mass, object frame, m;
        surface: (s, m) per step and finger, the signed distance (m) of the planned tip from the simulated
            object surface (`_Grip.surface`; linearly interpolated between steps); None: no correction.

    Returns:
        `Commands`: t (k,) s; q_cmd (k, n) rad; T_palm_object (k, 4, 4) planned object pose; q_grip0 (n,)
        the targets that grip at step 0 (the settle's end); residual (s,) grip LP residual per step, N;
        q_start (n,) the hand at step 0 with the surface correction only (the settle's start); holding
        (k, m) each finger's holding weight in [0, 1] (0 while a gait lifts it, ramping over its load
        hand-over), ``plan.fingers`` order; press (k, m) the planned normal force of each finger, N, and
        n_palm (k, m, 3) its outward contact normal, palm frame (the grip-force feedback's targets).
    """
    timing = (opts.joint_velocity, opts.min_step_duration, opts.unload_fraction, opts.min_handover_time)
    t, q_lin, T = plan_motion(plan, CONTROL_DT, *timing)
    seg_idx, phase = _segments(step_end_times(plan, *timing), t)
    segments, contacts, residual = _plan_segments(plan, hand, opts, mass, p_object_com)
    q_cmd, n_object, grip = _tick_targets(plan, opts, segments, contacts, q_lin=q_lin, seg_idx=seg_idx,
                                          phase=phase, surface=surface)
    q0, R0, n0, grip0 = _step0_instants(plan, segments[0], contacts[0], surface)
    q_all = np.vstack([q_cmd, q0])  # one batch: the ticks, then step 0 gripping and not gripping
    grip_all = _Grip(*(None if a is None else np.concatenate([a, b])
                       for a, b in zip(grip, grip0, strict=True)))
    R_all, n_all = np.concatenate([T[:, :3, :3], R0]), np.concatenate([n_object, n0])
    n_unit = n_all / np.maximum(np.linalg.norm(n_all, axis=2, keepdims=True), 1e-12)
    n_palm = np.einsum("kij,kmj->kmi", R_all, n_unit)  # unit contact normals, palm frame
    q_all += _grip_offsets(hand, plan.fingers, opts, q_all, R_all, n_palm, grip_all)
    q_cmd, q_grip0, q_start = q_all[:-2], q_all[-2], q_all[-1]
    press = np.maximum(-np.einsum("kmi,kmi->km", grip.F, n_unit[:-2]), 0.0)  # the planned normal forces, N
    return Commands(t, q_cmd, T, q_grip0, np.asarray(residual), q_start, grip.w, press, n_palm[:-2])


class Commands(NamedTuple):
    """The targets of `joint_commands` (see there)."""

    t: NDArray
    q_cmd: NDArray
    T_palm_object: NDArray
    q_grip0: NDArray
    residual: NDArray
    q_start: NDArray
    holding: NDArray
    press: NDArray | None = None
    """(k, m) each finger's planned normal force on the object ("balanced" grip), N (0: none)."""
    n_palm: NDArray | None = None
    """(k, m, 3) each finger's outward contact normal, palm frame (unit)."""


class _Grip(NamedTuple):
    """What the fingers do at k instants: grip forces F (k, m, 3) on the object (object frame, N), squeeze
    weights w (k, m), the gait finger's row gait (k,) (−1: no gait) and its lift phase in [0, 1] (k,) (NaN:
    no lift)."""

    F: NDArray
    w: NDArray
    gait: NDArray
    lift: NDArray
    surface: NDArray | None = None
    """(k, m) signed distance of each tip from the SIMULATED object surface where the plan has it touch
    (the convex pieces may over-cover the mesh by a few mm), m: the tip target moves by −d along the
    normal (None or 0: no correction)."""


def _grip_offsets(hand, fingers, opts: SimOptions, q: NDArray, R_palm_object: NDArray, n_palm_all: NDArray,
                  grip: _Grip) -> NDArray:
    """(k, n) joint offsets at k instants (joints q (k, n) rad, object rotations R_palm_object (k, 3, 3)):
    surface correction and grip of every finger plus the gait finger's lift; `n_palm_all` (k, m, 3) the
    unit contact normals (palm frame), rows in `fingers` order. A term that does not apply (no
    correction, no force, no squeeze, no lift) adds an exact zero."""
    J_tips = tip_jacobians(hand, fingers, q)
    dq = np.zeros(q.shape)
    R = R_palm_object
    lift = np.nan_to_num(grip.lift, nan=0.0)
    for m in range(len(fingers)):
        J = J_tips[:, m]
        n_palm = n_palm_all[:, m]
        if grip.surface is not None:
            dq += _dls(J, -grip.surface[:, m, None] * n_palm)
        if opts.grip == "balanced":
            dq += np.einsum("kji,kj->ki", J, np.einsum("kij,kj->ki", R, grip.F[:, m])) / opts.kp
        else:  # "squeeze"
            dq += _dls(J, -opts.squeeze_depth * np.maximum(grip.w[:, m], 0.0)[:, None] * n_palm)
        height = np.where(grip.gait == m, opts.lift_height * np.sin(np.pi * lift), 0.0)
        dq += _dls(J, height[:, None] * n_palm)
    return dq
