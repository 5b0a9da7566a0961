"""Damped least-squares inverse kinematics of fingertip centres (numeric, within the joint limits).

`tip_ik` moves chosen joints so that the tip-sphere centres of chosen fingers reach palm-frame targets:
Newton-like damped least-squares steps on `Hand.tip_jacobian`, a null-space pull towards a reference
posture, joints that a step would push through a limit frozen at it, an optional weight on the error
directions (e.g. "rise along the normal first"). The trajectories (`regrasp_casadi.trajectory`) solve
their lift-off and reposing knots with it.

`tip_object_ik` solves a reposing knot whose tips `tip_ik` cannot reach (a finger held at two joint
limits has fewer than three free joints): the object's pose becomes an unknown too, so the object
follows the hand, and the tips reach their places on the object exactly with the smallest change of
the pose (the joints and the pose pulled towards their references in the null space).

    >>> q, e = tip_ik(hand, q0, ["index"], p_palm_target[None], hand.finger_joints["index"], q0)
    >>> q, T, e = tip_object_ik(hand, q, T_ref, hand.fingers, p_object_tips, joints, q_ref=q_ref,
    ...               T_ref=T_ref)
"""

from __future__ import annotations

import functools
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.transforms import exp_so3, log_SO3

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand

__all__ = ["tip_ik", "finger_reach_ik", "tip_object_ik", "joints_at_limits", "IK_CONVERGED"]

IK_CONVERGED = 1e-7
"""`tip_ik` iterates until every (weighted) tip error is below this, m (or until it stops making
progress)."""

MAX_STEP = 0.2
"""Largest joint change of one iteration, rad."""

OBJECT_STEP = 0.01
"""`tip_object_ik`: the object's translation per unit of its unknowns, m (0.01: a millimetre of object
motion costs as much as 0.1 rad of a joint, which moves a tip about 5 mm: the joints move first)."""

JOINT_PULL = 0.01
"""`tip_object_ik`: weight of the joints' pull towards q_ref against the pose's towards T_ref (in the
scaled unknowns): small, so that the object does not move to bring the joints closer to q_ref, only
where the tips need it (knots either side of where the joints alone stop reaching stay close)."""

OBJECT_LEVER = 0.05
"""`tip_object_ik`: a radian of object rotation counts like this much translation, m."""


@functools.lru_cache(maxsize=64)
def _damping_matrix(rows: int, damping: float) -> NDArray[np.float64]:
    """λ² I (rows, rows), read-only (built once per size and λ)."""
    out = damping**2 * np.eye(rows)
    out.flags.writeable = False
    return out


def _dls_step(J: NDArray, e: NDArray, dq_null: NDArray, at_lower: NDArray, at_upper: NDArray,
              damping: float) -> NDArray:
    """Damped least-squares step of the joints (columns of J) towards the tip error e, plus the null-space
    part of dq_null; joints at a limit that the step would push out are frozen (re-solved without them)."""
    free = np.ones(J.shape[1], dtype=bool)
    dq = np.zeros(J.shape[1])
    damping_matrix = _damping_matrix(J.shape[0], damping)
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
        J = (W @ hand.tips_jacobian(q)[rows][:, :, joints]).reshape(-1, len(joints))
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


def _reach_iks(hand: Hand, q: NDArray, finger: str, p_palm_target: NDArray,
               q_seeds: Sequence[NDArray | None] = ()) -> Iterator[tuple[NDArray, NDArray]]:
    """`tip_ik` of one finger's tip centre to `p_palm_target` (3,), palm frame, m, from several starts, in
    this order (lazily): q (n,) itself, q with that finger's joints taken from each of `q_seeds` ((n,) rad
    each; None skipped, e.g. the goal grasp's joints), and q with them at the middle of their ranges; the
    other fingers' joints stay as in q, and each start pulls its null space towards itself.

    A local IK from q alone stops where a joint limit or the finger's posture blocks it (measured: the
    generated cup pair of seed 0, SD: the ring's IK from its joints ended 47.9 mm from a goal that the
    goal grasp's joints reach exactly, with the object at the desired pose).

    Yields:
        (q (n,) within the limits, the tip error (3,), palm frame, m) per start.
    """
    q = np.asarray(q, dtype=float)
    joints = np.asarray(hand.finger_joints[finger])
    target = np.asarray(p_palm_target, dtype=float)[None]
    for seed in (q, *q_seeds, hand.q_mid()):
        if seed is None:
            continue
        start = q.copy()
        start[joints] = np.asarray(seed, dtype=float)[joints]
        q_end, e = tip_ik(hand, start, [finger], target, joints, start)
        yield q_end, e[0]


def finger_reach_ik(hand: Hand, q: NDArray, finger: str, p_palm_target: NDArray,
                    q_seeds: Sequence[NDArray | None] = (), *, tol: float = 1e-3
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The first of `_reach_iks` whose tip ends within `tol` (m) of `p_palm_target`, so a goal the
    finger's own joints reach gives the IK from them (the nearest posture); else the one ending closest
    (the first on a tie). Returns q (n,) and the tip error (3,), palm frame, m."""
    best: tuple[float, NDArray, NDArray] | None = None
    for q_end, e in _reach_iks(hand, q, finger, p_palm_target, q_seeds):
        err = float(np.linalg.norm(e))
        if best is None or err < best[0]:
            best = (err, q_end, e)
        if err <= tol:
            break
    assert best is not None
    return best[1], best[2]


def tip_object_ik(hand: Hand, q_start: NDArray, T_start: NDArray, fingers: Sequence[str],
                  p_object_targets: NDArray, joints: NDArray, *, q_ref: NDArray, T_ref: NDArray,
                  damping: float = 1e-4, max_iters: int = 40
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Joint angles and object pose whose tip centres of `fingers` are at `p_object_targets` on the object.

    Damped least squares on the joints and a twist (v, ω) of the object, palm frame (the object's
    points p move by v + ω × (p − t), t its origin), scaled by `OBJECT_STEP` and `OBJECT_LEVER`;
    the null space pulls the pose towards T_ref and, `JOINT_PULL` times as strongly, the joints
    towards q_ref.

    Args:
        hand: the hand (`tip_positions`, `tip_jacobian`, joint limits).
        q_start: (n,) first iterate, rad (clipped into the limits).
        T_start: (4, 4) first iterate of the object pose in the palm frame (m).
        fingers: the fingers whose tips are placed.
        p_object_targets: (len(fingers), 3) tip-sphere centres to reach, object frame, m.
        joints: indices into q of the joints that may move.
        q_ref, T_ref: (n,) rad and (4, 4): the posture and pose the null space is pulled towards.
        damping, max_iters: as in `tip_ik`.

    Returns:
        q (n,) within the limits, the object pose T (4, 4) in the palm frame, and the remaining tip
        errors (len(fingers), 3), palm frame, m.
    """
    rows = [hand.fingers.index(f) for f in fingers]
    lo, hi = hand.q_lower[joints], hand.q_upper[joints]
    c, c_rot = OBJECT_STEP, OBJECT_STEP / OBJECT_LEVER
    P = np.asarray(p_object_targets, dtype=float)
    q, T = np.clip(q_start, hand.q_lower, hand.q_upper), np.array(T_start, dtype=float)

    def error(q: NDArray, T: NDArray) -> NDArray:
        return P @ T[:3, :3].T + T[:3, 3] - hand.tip_positions(q)[rows]

    e = error(q, T)
    err = float(np.abs(e).max())
    free_obj = np.zeros(6, dtype=bool)
    for _ in range(max_iters):
        if err <= IK_CONVERGED:
            break
        r = P @ T[:3, :3].T  # targets relative to the object's origin, palm frame
        J_obj = np.concatenate([np.hstack([-c * np.eye(3), c_rot * _skew(ri)]) for ri in r])
        J = np.hstack([hand.tips_jacobian(q)[rows][:, :, joints].reshape(-1, len(joints)), J_obj])
        qj = q[joints]
        pull = np.concatenate([JOINT_PULL * (q_ref[joints] - qj), (T_ref[:3, 3] - T[:3, 3]) / c,
                               log_SO3(T_ref[:3, :3] @ T[:3, :3].T) / c_rot])
        dx = _dls_step(J, e.ravel(), pull, np.concatenate([qj <= lo + 1e-12, free_obj]),
                       np.concatenate([qj >= hi - 1e-12, free_obj]), damping)
        largest = float(np.abs(dx).max())
        if largest > MAX_STEP:
            dx *= MAX_STEP / largest
        q_new, T_new = q.copy(), T.copy()
        q_new[joints] = np.minimum(np.maximum(qj + dx[: len(joints)], lo), hi)
        T_new[:3, 3] += c * dx[-6:-3]
        T_new[:3, :3] = exp_so3(c_rot * dx[-3:]) @ T[:3, :3]
        e_new = error(q_new, T_new)
        err_new = float(np.abs(e_new).max())
        if err_new >= err:
            break
        stalled = err_new > 0.8 * err
        q, T, e, err = q_new, T_new, e_new, err_new
        if stalled:
            break
    return q, T, e


def _skew(v: NDArray) -> NDArray[np.float64]:
    """(3, 3) matrix of the cross product v × ·."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def joints_at_limits(hand: Hand, q: NDArray, joints: NDArray, tol: float = 1e-9) -> list[str]:
    """Names of the joints of `joints` (indices into q) that are at a limit (within `tol`) at q (n,)."""
    return [hand.joint_names[j] for j in joints
            if q[j] <= hand.q_lower[j] + tol or q[j] >= hand.q_upper[j] - tol]
