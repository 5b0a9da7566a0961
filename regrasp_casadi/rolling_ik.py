"""Inverse kinematics of fingertips that roll: the tip centres' targets move with the tips' rotation.

A reposing's path (`repose_trajectory`) holds every tip where it rolls to as it turns: its centre at
p(q) = p_from + ρ θ(q) × n + offset (object frame), θ(q) the rotation vector of the tip link's rotation
since the path's start (`grasp_metrics.rolling_displacement`). The target depends on the joints, so
`rolling_tip_ik` solves tip(q) = T p(q) with the Jacobian of that whole residual, the rolling-contact
Jacobian J_p + ρ R [n]× J_l⁻¹(θ) Rᵀ J_ω (tip centre and tip-link angular velocity, palm frame; J_l the
left Jacobian of SO(3)), rather than moving fixed targets to where the last solution rolled them.

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

__all__ = ["Rolling", "rolling_tip_ik", "tip_angular_jacobian"]

_OMEGA_JACOBIANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Hand -> its `_omega_jacobian_function`, built once per hand."""

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


def _omega_jacobian_function(hand: Hand) -> ca.Function:
    """q (n,) -> (3m, n) d ω_tip / d q of every tip link (palm frame, rows 3i..3i+2 the tip of
    ``hand.fingers[i]``), exact: column j is vee(∂R/∂q_j Rᵀ), from the symbolic tip-link rotations R(q)."""
    fn = _OMEGA_JACOBIANS.get(hand)
    if fn is None:
        q = ca.SX.sym("q", hand.n_joints)
        R_tips = hand.tip_rotations_function()(q)  # (3, 3m), the tip links side by side
        rows = []
        for i in range(len(hand.fingers)):
            R = R_tips[:, 3 * i : 3 * i + 3]
            dR = [ca.jacobian(R[:, c], q) for c in range(3)]  # dR[c][a, j] = ∂R[a, c] / ∂q_j

            def skew(a: int, b: int) -> ca.SX:  # (∂R/∂q Rᵀ)[a, b] for every joint, (1, n)
                return sum(dR[c][a, :] * R[b, c] for c in range(3))  # noqa: B023 (used at once)

            rows += [skew(2, 1), skew(0, 2), skew(1, 0)]
        fn = ca.Function("J_omega_tips", [q], [ca.densify(ca.vertcat(*rows))], ["q"], ["J_omega_tips"],
                         {"cse": True})
        _OMEGA_JACOBIANS[hand] = fn
    return fn


def tip_angular_jacobian(hand: Hand, q: NDArray, joints: NDArray) -> NDArray[np.float64]:
    """(m, 3, len(joints)) d ω_tip / d q_joints of every tip link, palm frame, rad/rad: exact (the
    derivatives of the symbolic tip-link rotations, `_omega_jacobian_function`)."""
    J = np.asarray(_omega_jacobian_function(hand)(np.asarray(q, dtype=float)), dtype=float)
    return J.reshape(len(hand.fingers), 3, -1)[:, :, joints]


def _inv_left_jacobian(theta: NDArray) -> NDArray[np.float64]:
    """(m, 3, 3) J_l⁻¹(θ) of SO(3) for rotation vectors θ (m, 3): dθ = J_l⁻¹ δ when R → exp(δ) R."""
    out = np.empty((len(theta), 3, 3))
    for i, t in enumerate(np.asarray(theta, dtype=float)):
        a = float(np.linalg.norm(t))
        K = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
        c = 1.0 / 12.0 if a < 1e-6 else (1.0 - 0.5 * a * np.sin(a) / (1.0 - np.cos(a))) / a**2
        out[i] = np.eye(3) - 0.5 * K + c * (K @ K)
    return out


def _residual(hand: Hand, q: NDArray, T: NDArray, roll: Rolling, rows: list[int], joints: NDArray
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The tips' errors e (len(rows), 3), palm frame, m, and J (3 len(rows), len(joints)) = −de/dq."""
    R = T[:3, :3]
    p_object, theta = roll.targets(R.T @ hand.tip_rotations(q))
    e = (p_object @ R.T + T[:3, 3] - hand.tip_positions(q))[rows]
    n_palm = (roll.normals @ R.T)[rows]
    N = np.zeros((len(rows), 3, 3))  # [n]× per tip, palm frame
    N[:, 0, 1], N[:, 0, 2], N[:, 1, 2] = -n_palm[:, 2], n_palm[:, 1], -n_palm[:, 0]
    N -= np.transpose(N, (0, 2, 1))
    turn = R @ _inv_left_jacobian(theta[rows]) @ R.T  # d θ_palm / d ω_palm
    J_omega = tip_angular_jacobian(hand, q, joints)[rows]
    J = hand.tips_jacobian(q)[rows][:, :, joints] + roll.radius * (N @ turn @ J_omega)
    return e, J.reshape(-1, len(joints))


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
