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

__all__ = ["GripForceFeedback"]


class GripForceFeedback:
    """The integral grip-force feedback of one simulation run (see the module docstring).

    Args:
        sim: the compiled model (tip geoms, hand dof addresses); fingers: the plan's fingers (the order of
            the targets and weights); opts: `force_gain` k_F (1/s), `force_limit_offset` (m), `kp`.
    """

    def __init__(self, sim: SimModel, fingers, opts: SimOptions) -> None:
        self.sim, self.fingers = sim, tuple(fingers)
        self.gain, self.kp = float(opts.force_gain), float(opts.kp)
        self.limit = float(opts.force_limit_offset)
        self.R_palm_world = opts.R_world_palm.T
        self.offset = np.zeros((len(self.fingers), len(sim.dof_hand)))
        nv = sim.model.nv
        self._jacp, self._jacr = np.zeros((3, nv)), np.zeros((3, nv))

    def _jacobian(self, data: mujoco.MjData, finger: str) -> NDArray:
        """(3, n) position Jacobian of the finger's tip centre, palm frame, per hand joint."""
        g = self.sim.tip_geom[finger]
        mujoco.mj_jac(self.sim.model, data, self._jacp, self._jacr, data.geom_xpos[g],
                      self.sim.model.geom_bodyid[g])
        return self.R_palm_world @ self._jacp[:, self.sim.dof_hand]

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
        for m, finger in enumerate(self.fingers):
            w = float(holding[m])
            if w <= 0.0 or f_target[m] <= 0.0:
                self.offset[m] *= max(0.0, 1.0 - self.gain * dt)
                continue
            J = self._jacobian(data, finger)
            push = -np.asarray(n_palm[m], float) * max(float(f_target[m] - f_measured[m]), 0.0)
            self.offset[m] += self.gain * dt * w * (J.T @ push) / self.kp
            reach = float(np.linalg.norm(J @ self.offset[m]))
            if reach > self.limit:
                self.offset[m] *= self.limit / reach
        return self.offset.sum(axis=0)
