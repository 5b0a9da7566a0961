"""Grip-force feedback for executing a plan in simulation (`simulate` with ``SimOptions.force_gain``).

The "balanced" grip (`sim_control.grip_forces`) gives every holding fingertip the normal force f*_m that,
with the others, holds the object against gravity; the servos realise it as a joint-target offset
Jᵀ f / kp, exact only while the tip sits where the plan has it. Over a plan the tips drift against the
simulated surface (the object-pose feedback moves them, reposings roll them) and the forces with them:
measured on box_shift's gravity plan, every step executed alone is held (0.0 mm), but in sequence the
ring finger's force fell to 0.45 N and a later gait of the ring dropped the box. A robot with joint-torque
or tactile sensing closes this loop; here the sensor is MuJoCo's contact force.

Law (palm frame). With f_m the measured normal force of finger m's tip on the object, n_m its outward
contact normal, J_m its tip's position Jacobian and w_m ∈ [0, 1] its holding weight (0 while a gait
lifts it), an integral law adds to the finger's joint targets

    Δq_m ← Δq_m + k_F · dt · w_m · J_mᵀ (−n_m) max(f*_m − f_m, 0) / kp,

the torque offset that pushes the tip into the surface with the missing force, integrated at the rate k_F
(`SimOptions.force_gain`, 1/s). One-sided: a finger pressing harder than planned keeps its offset (the
grip never loosens below the plan's while the finger holds; a two-sided law, tried first, let the fingers
relax where the object needed them and dropped box_shift's plan earlier, at 13.8 s instead of 23.6 s).
A finger that does not hold (a gait lifts it) lets its offset decay at the same rate; the offset's tip
displacement J_m Δq_m is capped at `SimOptions.force_limit_offset` (anti wind-up).
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.mujoco_model import SimModel, SimOptions
from regrasp_casadi.sim_feedback import TipOffsets

__all__ = ["GripForceFeedback"]


class GripForceFeedback(TipOffsets):
    """The integral grip-force feedback of one simulation run (see the module docstring; the integral,
    its decay and its cap are `sim_feedback.TipOffsets`').

    Args:
        sim: the compiled model (tip geoms, hand dof addresses); fingers: the plan's fingers (the order of
            the targets and weights); opts: `force_gain` k_F (1/s), `force_limit_offset` (m), `kp`.
    """

    def __init__(self, sim: SimModel, fingers, opts: SimOptions) -> None:
        super().__init__(sim, fingers, opts, opts.force_gain, opts.force_limit_offset)
        self.kp = float(opts.kp)

    def update(self, data: mujoco.MjData, f_measured: NDArray, f_target: NDArray, n_palm: NDArray,
               holding: NDArray, dt: float) -> NDArray:
        """Advance the integral by dt (s) and return the joint offsets (n,) rad, `hand.joint_names` order.

        Args:
            data: the simulation state (after mj_step: kinematics current);
            f_measured, f_target: (m,) measured and planned normal force of each tip on the object, N
                (a finger short of f_target is pushed in; one at or above it keeps its offset);
            n_palm: (m, 3) outward contact normals, palm frame (unit);
            holding: (m,) holding weight of each finger in [0, 1]; all in ``fingers`` order.
        """
        w, f_target = np.asarray(holding, dtype=float), np.asarray(f_target, dtype=float)
        rows = self._holding_rows((w > 0.0) & (f_target > 0.0), dt)
        if rows is None:
            return self.offset.sum(axis=0)
        _, J = self._tips(data, rows)
        short = np.maximum(f_target - np.asarray(f_measured, dtype=float), 0.0)[rows]  # N
        push = -np.asarray(n_palm, dtype=float)[rows] * short[:, None]  # (h, 3) palm frame, N
        torque = (np.swapaxes(J, 1, 2) @ push[:, :, None])[:, :, 0]  # Jᵀ (−n) max(f* − f, 0), N·m
        return self._advance(rows, J, torque, w, dt, per=self.kp)  # the offset that adds that torque
