"""Object-pose feedback for executing a plan in simulation (`simulate` with ``SimOptions.feedback``).

Executed open loop, a plan's object drifts: every reposing turns the fingertips on their contacts, a
rigid tip sphere that turns on a contact whose point stays fixed on the object must slip or drag it, and
the position servos are compliant; 1–5 mm and 1–7° per reposing add up over a plan of 50 steps until the
holding grasps degrade (measured on the shipped problems: every step executed alone is followed, the
whole plan is dropped). A robot closes the loop with an object tracker; here the tracker is exact (the
simulated pose).

Law (palm frame). With T_plan the planned and T_sim the simulated object pose at time t, the rigid
correction E = T_plan · T_sim⁻¹ takes the simulated object onto the plan. Moving every holding tip
centre p_m by the same rigid motion, δ_m = E p_m − p_m, would carry the object along with it (the grasp
is rigid while the contacts stick). An integral law turns δ into joint offsets of the holding fingers:

    Δq_m ← Δq_m + k_I · dt · w_m · J_m⁺ δ_m        (J_m: the tip's position Jacobian, damped pseudo-inverse)

with w_m ∈ [0, 1] the finger's holding weight (0 while a gait lifts it, ramping during its load
hand-over); a finger that does not hold lets its offset decay with the same rate. The offset's tip
displacement J_m Δq_m is capped at `SimOptions.feedback_limit` (anti wind-up).
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.mujoco_model import SimModel, SimOptions

__all__ = ["ObjectPoseFeedback", "TipOffsets", "rigid_tip_corrections"]

_DAMPING = 1e-3  # m: damping of the least-squares solve J⁺ δ


def rigid_tip_corrections(T_plan: NDArray, T_sim: NDArray, p_tips: NDArray) -> NDArray:
    """(m, 3) displacements δ_m = E p_m − p_m, m, that move tip centres p_tips (m, 3) (palm frame, m) by
    the rigid motion E = T_plan · T_sim⁻¹ (4, 4) taking the simulated object pose onto the planned one."""
    E = np.asarray(T_plan, dtype=float) @ np.linalg.inv(np.asarray(T_sim, dtype=float))
    p = np.asarray(p_tips, dtype=float)
    return p @ E[:3, :3].T + E[:3, 3] - p


class TipOffsets:
    """Integral joint offsets of the holding fingertips, the part the simulation's feedback loops share:
    per finger an offset Δq_m (n,) rad that grows by k · dt · w_m · step_m while the finger holds (holding
    weight w_m > 0), decays by (1 − k dt) while it does not, and whose tip displacement J_m Δq_m is capped
    at `limit` (anti wind-up). The tip centres and their position Jacobians come from MuJoCo (`mj_jac`),
    in the palm frame. Subclasses compute the steps (`ObjectPoseFeedback`, `GripForceFeedback`).

    Args:
        sim: the compiled model (tip geoms, hand dof addresses); fingers: the plan's fingers, the order
            of the weights; opts: the palm's orientation; gain: k (1/s); limit: the tip reach cap (m).
    """

    def __init__(self, sim: SimModel, fingers, opts: SimOptions, gain: float, limit: float) -> None:
        self.sim, self.fingers = sim, tuple(fingers)
        self.gain, self.limit = float(gain), float(limit)
        self.R_palm_world = opts.R_world_palm.T
        self.offset = np.zeros((len(self.fingers), len(sim.dof_hand)))
        self._tip_geoms = np.array([sim.tip_geom[f] for f in self.fingers], dtype=int)
        self._jacp = np.zeros((len(self.fingers), 3, sim.model.nv))
        # per finger: (its Jacobian buffer (3, nv), its tip geom, the geom's body), mj_jac's arguments
        self._jac_args = [(self._jacp[m], int(g), int(sim.model.geom_bodyid[g]))
                          for m, g in enumerate(self._tip_geoms)]
        dof = np.asarray(sim.dof_hand)
        contiguous = dof.size and np.array_equal(dof, np.arange(dof[0], dof[0] + dof.size))
        self._dof = slice(int(dof[0]), int(dof[0]) + dof.size) if contiguous else dof  # a view when possible
        self._rotate = not np.array_equal(self.R_palm_world, np.eye(3))  # else palm frame = world frame

    def _tips(self, data: mujoco.MjData, rows: slice | NDArray) -> tuple[NDArray, NDArray]:
        """For the fingers ``rows`` (h of them): (tip centres (h, 3) palm frame, m; position Jacobians
        (h, 3, n) palm frame, m/rad, per hand joint)."""
        model, xpos = self.sim.model, data.geom_xpos
        for jacp, g, body in (self._jac_args if isinstance(rows, slice) else
                              [self._jac_args[m] for m in rows]):
            mujoco.mj_jac(model, data, jacp, None, xpos[g], body)
        p_world, J_world = xpos[self._tip_geoms[rows]], self._jacp[rows][:, :, self._dof]
        if not self._rotate:
            return p_world, J_world
        return p_world @ self.R_palm_world.T, self.R_palm_world @ J_world

    def _holding_rows(self, hold: NDArray, dt: float) -> slice | NDArray | None:
        """Decay the offsets of the fingers not in ``hold`` (m,) bool by (1 − k dt); the rows of those in
        it (a slice when every finger holds: views, no gathers), None when none holds."""
        if hold.all():
            return slice(None)
        self.offset[~hold] *= max(0.0, 1.0 - self.gain * dt)
        return np.flatnonzero(hold) if hold.any() else None

    def _advance(self, rows: slice | NDArray, J: NDArray, step: NDArray, w: NDArray, dt: float,
                 per: float = 1.0) -> NDArray:
        """Add k dt w_m step_m / per (step (h, n), weights w (m,); the result in rad) to the offsets of
        ``rows``, cap each tip reach |J_m Δq_m| (J (h, 3, n)) at `limit`; returns the summed offsets (n,)
        rad."""
        offset = self.offset[rows] + (self.gain * dt * w[rows])[:, None] * step / per
        reach = np.linalg.norm((J @ offset[:, :, None])[:, :, 0], axis=1)
        offset *= (self.limit / np.maximum(reach, self.limit))[:, None]  # tip reach capped (× 1.0 below)
        self.offset[rows] = offset
        return self.offset.sum(axis=0)


class ObjectPoseFeedback(TipOffsets):
    """The integral object-pose feedback of one simulation run (see the module docstring).

    Args:
        sim: the compiled model (tip geoms, hand dof addresses); fingers: the plan's fingers, the order
            of the holding weights; opts: `feedback_gain` k_I (1/s) and `feedback_limit` (m).
    """

    def __init__(self, sim: SimModel, fingers, opts: SimOptions) -> None:
        super().__init__(sim, fingers, opts, opts.feedback_gain, opts.feedback_limit)
        self._damping = _DAMPING**2 * np.eye(3)

    def update(self, data: mujoco.MjData, T_plan: NDArray, T_sim: NDArray, holding: NDArray,
               dt: float) -> NDArray:
        """Advance the integral by dt (s) and return the joint offsets (n,) rad, `hand.joint_names` order.

        Args:
            data: the simulation state (after mj_step: positions and kinematics current);
            T_plan, T_sim: (4, 4) planned and simulated object pose, palm frame;
            holding: (m,) holding weight of each finger in [0, 1], ``fingers`` order.
        """
        w = np.asarray(holding, dtype=float)
        rows = self._holding_rows(w > 0.0, dt)
        if rows is None:
            return self.offset.sum(axis=0)
        p_tips, J = self._tips(data, rows)
        delta = rigid_tip_corrections(T_plan, T_sim, p_tips)  # (h, 3)
        J_T = np.swapaxes(J, 1, 2)
        step = (J_T @ np.linalg.solve(J @ J_T + self._damping, delta[:, :, None]))[:, :, 0]  # J⁺ δ
        return self._advance(rows, J, step, w, dt)
