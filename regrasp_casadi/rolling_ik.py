"""Inverse kinematics of fingertips that roll: the tip centres' targets move with the tips' rotation.

A reposing's path (`repose_trajectory`) holds every tip where it rolls to as it turns: its centre at
p(q) = p_from + ρ θ(q) × n + offset (object frame), θ(q) the rotation vector of the tip link's rotation
since the path's start (`grasp_metrics.rolling_displacement`). The target depends on the joints, so
`rolling_tip_ik` solves tip(q) = T p(q) with the Jacobian of that whole residual, the rolling-contact
Jacobian J_p + ρ R [n]× J_l⁻¹(θ) Rᵀ J_ω (tip centre and tip-link angular velocity, palm frame; J_l the
left Jacobian of SO(3)), rather than moving fixed targets to where the last solution rolled them. The
error and that Jacobian (its exact derivative) come from one CasADi function per hand
(`_residual_function`), evaluated through preallocated buffers.

Why (issue 12, mug seed 1): a finger stretched to the edge of its reach (the thumb with its distal joint
straight) has a tip-centre Jacobian J_p of rank 2, and the tip-centre IK's solutions of a path then
branch like √s from its start; the targets moved by the roll of the last solution (a fixed-point
iteration) picked either branch from knot to knot ("jumps" of 1–22 mm, tips sliding 1–2.9 mm). The
rolling-contact Jacobian is of full rank there (σ_min 0.003 against 0 m/rad), and its knots follow one
smooth curve.

    >>> q, e = rolling_tip_ik(hand, q0, T, roll, joints, q_ref)
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.tip_ik import IK_CONVERGED, MAX_STEP, _dls_step
from regrasp_casadi.transforms import log_SO3_batch

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand

__all__ = ["Rolling", "rolling_tip_ik"]

BACKTRACKS = 6
"""Halvings of a step that does not reduce the tip error before `rolling_tip_ik` stops."""


@dataclass(frozen=True)
class Rolling:
    """Where every tip of `hand.fingers` is held as it turns (object frame, m): at
    p_from + ρ θ × n + offset, θ the rotation vector of R_object_tip R_fromᵀ.

    p_from: (m, 3) tip centres at the start; R_from: (m, 3, 3) tip-link rotations at the start;
    normals: (m, 3) unit normals the tips roll over; offset: (m, 3) the slide added; radius: ρ, m."""

    p_from: NDArray[np.float64]
    R_from: NDArray[np.float64]
    normals: NDArray[np.float64]
    offset: NDArray[np.float64]
    radius: float

    def targets(self, R_object_tips: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(m, 3) tip centres, object frame, m, for tip-link rotations (m, 3, 3) (object frame), and the
        rotation vectors θ (m, 3), rad."""
        theta = log_SO3_batch(R_object_tips @ np.transpose(self.R_from, (0, 2, 1)))
        return self.p_from + self.radius * np.cross(theta, self.normals) + self.offset, theta


_TINY = 1e-30
"""Added to ‖v‖² in the symbolic log of SO(3) (v = sin θ · axis): its square root and θ/sin θ stay
differentiable at θ = 0 (no rotation, every path's first knot); θ changes by < 1e-15 rad."""


def _residual_function(hand: Hand) -> ca.Function:
    """The rolling tips' error and its Jacobian in one call, exact (CasADi, `cse`; built once per hand, by
    its `_ResidualBuffers`):
    (q (n,), R (3, 3) and t (3,) of T_palm_object, p_from (3, m), R_from (3, 3m) side by side, normals
    (3, m), offset (3, m), ρ) -> e (3, m) = T p(q) − tip(q), palm frame, m, and J (3m, n) = −de/dq, with
    p(q) = p_from + ρ θ(q) × n + offset (object frame), θ(q) = log(Rᵀ R_tip(q) R_fromᵀ) (`Rolling`)."""
    m = len(hand.fingers)
    q, R, t = ca.SX.sym("q", hand.n_joints), ca.SX.sym("R", 3, 3), ca.SX.sym("t", 3)
    p_from, R_from = ca.SX.sym("p_from", 3, m), ca.SX.sym("R_from", 3, 3 * m)
    normals, offset, radius = ca.SX.sym("normals", 3, m), ca.SX.sym("offset", 3, m), ca.SX.sym("radius")
    R_tips, p_tips = hand.tip_rotations_function()(q), hand.tip_positions_function()(q)
    errors = []
    for i in range(m):
        M = R.T @ R_tips[:, 3 * i : 3 * i + 3] @ R_from[:, 3 * i : 3 * i + 3].T  # turned since the start
        v = 0.5 * ca.vertcat(M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1])  # sin θ · axis
        sin_theta = ca.sqrt(ca.dot(v, v) + _TINY)
        theta = v * ca.atan2(sin_theta, 0.5 * (ca.trace(M) - 1.0)) / sin_theta
        p_object = p_from[:, i] + radius * ca.cross(theta, normals[:, i]) + offset[:, i]
        errors.append(R @ p_object + t - p_tips[:, i])
    e = ca.horzcat(*errors)
    J = -ca.jacobian(ca.vec(e), q)
    names = ["q", "R", "t", "p_from", "R_from", "normals", "offset", "radius"]
    return ca.Function("rolling_residual", [q, R, t, p_from, R_from, normals, offset, radius],
                       [e, ca.densify(J)], names, ["e", "J"], {"cse": True})


class _ResidualBuffers:
    """`_residual_function` evaluated through preallocated CasADi buffers (a plain call converts its eight
    arguments each time: 0.23 against 0.05 ms here). Each array is its argument or result transposed
    (CasADi is column-major). Not thread-safe, as `Hand._eval`."""

    def __init__(self, hand: Hand) -> None:
        m, n = len(hand.fingers), hand.n_joints
        self.args = [np.zeros(n), np.zeros((3, 3)), np.zeros(3), np.zeros((m, 3)), np.zeros((3 * m, 3)),
                     np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(1)]
        self.e, self.J = np.zeros((m, 3)), np.zeros((n, 3 * m))
        self._fn = _residual_function(hand)  # (held: the buffer evaluates it)
        self._buf, self._evaluate = self._fn.buffer()
        for i, arg in enumerate(self.args):
            self._buf.set_arg(i, memoryview(arg))
        self._buf.set_res(0, memoryview(self.e))
        self._buf.set_res(1, memoryview(self.J))

    def __call__(self, q: NDArray, T: NDArray, roll: Rolling) -> tuple[NDArray, NDArray]:
        """e (m, 3) and J (3m, n) (copies) at joints q (n,) and object pose T (4, 4) for `roll`."""
        a = self.args
        a[0][:], a[1][:], a[2][:] = q, T[:3, :3].T, T[:3, 3]
        a[3][:], a[4][:] = roll.p_from, np.transpose(roll.R_from, (0, 2, 1)).reshape(-1, 3)
        a[5][:], a[6][:], a[7][0] = roll.normals, roll.offset, roll.radius
        self._evaluate()
        return self.e.copy(), self.J.T.copy()


_BUFFERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Hand -> its `_ResidualBuffers`."""


def _residual(hand: Hand, q: NDArray, T: NDArray, roll: Rolling, rows: list[int], joints: NDArray
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The tips' errors e (len(rows), 3), palm frame, m, and J (3 len(rows), len(joints)) = −de/dq: the
    tip-centre Jacobian plus ρ [n]× R J_l⁻¹(θ) Rᵀ J_ω (module docstring), as the exact derivative of e
    (`_residual_function`)."""
    buffers = _BUFFERS.get(hand)
    if buffers is None:
        buffers = _BUFFERS[hand] = _ResidualBuffers(hand)
    e, J = buffers(q, T, roll)
    return e[rows], J.reshape(len(hand.fingers), 3, -1)[rows][:, :, joints].reshape(-1, len(joints))


def rolling_tip_ik(hand: Hand, q_start: NDArray, T_palm_object: NDArray, roll: Rolling, joints: NDArray,
                   q_ref: NDArray, fingers: list[str] | None = None, *, damping: float = 1e-4,
                   max_iters: int = 40) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Joints whose tips of `fingers` (None: all) are where `roll` holds them at object pose T_palm_object.

    Damped least squares on the rolling-contact Jacobian (module docstring), the null space pulled
    towards q_ref, joints pushed through a limit frozen at it (as `tip_ik.tip_ik`); a step that does not
    reduce the largest tip error is halved up to `BACKTRACKS` times, then the iteration stops.

    Args:
        hand: the hand. q_start: (n,) first iterate, rad (clipped into the limits).
        T_palm_object: (4, 4) the object's pose, palm frame, m.
        roll: the tips' rolling targets (object frame). joints: indices into q that may move.
        q_ref: (n,) the posture the null space is pulled towards, rad.
        damping: λ of (J Jᵀ + λ² I), m. max_iters: iteration limit.

    Returns:
        q (n,) within the limits, and the remaining tip errors (len(fingers), 3), palm frame, m.
    """
    rows = [hand.fingers.index(f) for f in (fingers or hand.fingers)]
    T = np.asarray(T_palm_object, dtype=float)
    lo, hi = hand.q_lower[joints], hand.q_upper[joints]
    q = np.clip(np.asarray(q_start, dtype=float), hand.q_lower, hand.q_upper)
    e, J = _residual(hand, q, T, roll, rows, joints)
    err = float(np.abs(e).max())
    for _ in range(max_iters):
        if err <= IK_CONVERGED:
            break
        qj = q[joints]
        dq = _dls_step(J, e.ravel(), q_ref[joints] - qj, qj <= lo + 1e-12, qj >= hi - 1e-12, damping)
        dq *= min(1.0, MAX_STEP / max(float(np.abs(dq).max()), 1e-300))
        for _ in range(BACKTRACKS + 1):
            q_new = q.copy()
            q_new[joints] = np.minimum(np.maximum(qj + dq, lo), hi)
            e_new, J_new = _residual(hand, q_new, T, roll, rows, joints)
            err_new = float(np.abs(e_new).max())
            if err_new < err:
                break
            dq *= 0.5
        else:
            break  # no progress (joint limits, or the null-space pull at convergence): keep q
        q, e, J, err = q_new, e_new, J_new, err_new
    return q, e
