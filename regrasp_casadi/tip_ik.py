"""Damped least-squares inverse kinematics of fingertip centres (numeric, within the joint limits).

`tip_ik` moves chosen joints so that the tip-sphere centres of chosen fingers reach palm-frame targets:
Newton-like damped least-squares steps on `Hand.tip_jacobian`, a null-space pull towards a reference
posture, joints that a step would push through a limit frozen at it, an optional weight on the error
directions (e.g. "rise along the normal first"). The trajectories (`regrasp_casadi.trajectory`) solve
their lift-off and reposing knots with it.

    >>> q, e = tip_ik(hand, q0, ["index"], p_palm_target[None], hand.finger_joints["index"], q0)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand

__all__ = ["tip_ik", "joints_at_limits", "IK_CONVERGED"]

IK_CONVERGED = 1e-7
"""`tip_ik` iterates until every (weighted) tip error is below this, m (or until it stops making
progress)."""

MAX_STEP = 0.2
"""Largest joint change of one iteration, rad."""


def _dls_step(J: NDArray, e: NDArray, dq_null: NDArray, at_lower: NDArray, at_upper: NDArray,
              damping: float) -> NDArray:
    """Damped least-squares step of the joints (columns of J) towards the tip error e, plus the null-space
    part of dq_null; joints at a limit that the step would push out are frozen (re-solved without them)."""
    free = np.ones(J.shape[1], dtype=bool)
    dq = np.zeros(J.shape[1])
    damping_matrix = damping**2 * np.eye(J.shape[0])
    rhs = np.empty((J.shape[0], 2))
    rhs[:, 0] = e
    for _ in range(3):
        Jf = J[:, free]
        null = dq_null[free]
        rhs[:, 1] = Jf @ null
        x = np.linalg.solve(Jf @ Jf.T + damping_matrix, rhs)
        dq = np.zeros(J.shape[1])
        dq[free] = Jf.T @ (x[:, 0] - x[:, 1]) + null
        out = free & ((at_lower & (dq < 0)) | (at_upper & (dq > 0)))
        if not out.any():
            break
        free &= ~out
        dq[~free] = 0.0
    return dq


def tip_ik(hand: Hand, q_start: NDArray, fingers: Sequence[str], p_palm_targets: NDArray, joints: NDArray,
           q_ref: NDArray, weight: NDArray | None = None, *, damping: float = 1e-4,
           max_iters: int = 40) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Joint angles whose tip centres of `fingers` reach `p_palm_targets` as closely as the limits allow.

    Args:
        hand: the hand (`tip_positions`, `tip_jacobian`, joint limits).
        q_start: (n,) first iterate, rad (clipped into the limits).
        fingers: the fingers whose tips are placed.
        p_palm_targets: (len(fingers), 3) tip-sphere centres to reach, palm frame, m.
        joints: indices into q of the joints that may move.
        q_ref: (n,) the posture the null space is pulled towards, rad.
        weight: (3, 3) weight of every tip's error (the directions that matter most); None: identity.
        damping: λ of (J Jᵀ + λ² I), m.
        max_iters: iteration limit; it also stops below `IK_CONVERGED` or when an iteration makes no
            progress.

    Returns:
        q (n,) within the limits, and the remaining tip errors (len(fingers), 3), m.
    """
    rows = [hand.fingers.index(f) for f in fingers]
    W = np.eye(3) if weight is None else weight
    lo, hi = hand.q_lower[joints], hand.q_upper[joints]
    q = np.clip(q_start, hand.q_lower, hand.q_upper)
    e = p_palm_targets - hand.tip_positions(q)[rows]
    err = float(np.abs(e @ W.T).max())
    for _ in range(max_iters):
        if err <= IK_CONVERGED:
            break
        J = np.concatenate([W @ hand.tip_jacobian(q, f)[:, joints] for f in fingers])
        qj = q[joints]
        dq = _dls_step(J, (e @ W.T).ravel(), q_ref[joints] - qj, qj <= lo + 1e-12, qj >= hi - 1e-12, damping)
        largest = float(np.abs(dq).max())
        if largest > MAX_STEP:
            dq *= MAX_STEP / largest
        q_new = q.copy()
        q_new[joints] = np.minimum(np.maximum(qj + dq, lo), hi)
        e_new = p_palm_targets - hand.tip_positions(q_new)[rows]
        err_new = float(np.abs(e_new @ W.T).max())
        if err_new >= err:
            break  # no progress (joint limits, or the null-space pull at convergence): keep q
        stalled = err_new > 0.8 * err
        q, e, err = q_new, e_new, err_new
        if stalled:
            break
    return q, e


def joints_at_limits(hand: Hand, q: NDArray, joints: NDArray, tol: float = 1e-9) -> list[str]:
    """Names of the joints of `joints` (indices into q) that are at a limit (within `tol`) at q (n,)."""
    return [hand.joint_names[j] for j in joints
            if q[j] <= hand.q_lower[j] + tol or q[j] >= hand.q_upper[j] - tol]
