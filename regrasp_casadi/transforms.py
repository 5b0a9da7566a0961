"""Rigid transforms (SE(3)/SO(3)) that work on numpy arrays and CasADi SX alike.

Conventions: `T_a_b` is a (4, 4) homogeneous transform mapping coordinates in frame b to frame a;
`R_a_b` its (3, 3) rotation; `p_a` a point in frame a. Roll-pitch-yaw follows URDF: fixed axes,
R = Rz(yaw) @ Ry(pitch) @ Rx(roll).

    >>> T_palm_object = make_T(rpy_to_R(0.1, 0.0, 0.2), [0.1, 0.0, 0.05])
    >>> p_palm = transform_points(T_palm_object, p_object)
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "rot_axis_angle",
    "rpy_to_R",
    "make_T",
    "inv_T",
    "transform_points",
    "kabsch",
    "rotation_angle",
    "log_SO3",
    "log_SO3_batch",
    "exp_so3",
    "interpolate_pose",
]


def _is_symbolic(*xs) -> bool:
    return any(isinstance(x, (ca.SX, ca.MX, ca.DM)) for x in xs)


def rot_axis_angle(axis: ArrayLike, angle):
    """Rotation matrix (3, 3) about a unit `axis` (3,) by `angle` (rad); `angle` may be a CasADi scalar.

    Rodrigues' formula R = I + sin(a) K + (1 - cos(a)) K², with K the cross-product matrix of `axis`.
    """
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    if _is_symbolic(angle):
        return ca.DM(np.eye(3)) + ca.sin(angle) * ca.DM(K) + (1 - ca.cos(angle)) * ca.DM(K @ K)
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)


def rpy_to_R(roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    """URDF fixed-axis roll-pitch-yaw (rad) to a (3, 3) rotation: Rz(yaw) @ Ry(pitch) @ Rx(roll)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def make_T(R, p):
    """Homogeneous (4, 4) transform from rotation (3, 3) and translation (3,); numpy or CasADi."""
    if _is_symbolic(R, p):
        T = ca.SX.eye(4) if not isinstance(R, ca.MX) else ca.MX.eye(4)
        T[:3, :3] = R
        T[:3, 3] = p
        return T
    T = np.eye(4)
    T[:3, :3] = np.asarray(R, dtype=float)
    T[:3, 3] = np.asarray(p, dtype=float).reshape(3)
    return T


def inv_T(T):
    """Inverse of a rigid (4, 4) transform: [R p; 0 1]⁻¹ = [Rᵀ −Rᵀp; 0 1]."""
    if _is_symbolic(T):
        R = T[:3, :3]
        p = T[:3, 3]
        return make_T(R.T, -R.T @ p)
    T = np.asarray(T, dtype=float)
    R, p = T[:3, :3], T[:3, 3]
    return make_T(R.T, -R.T @ p)


def transform_points(T_a_b, p_b):
    """Map points (n, 3) (numpy) or (3, n) (CasADi) from frame b to frame a."""
    if _is_symbolic(T_a_b, p_b):
        return T_a_b[:3, :3] @ p_b + ca.repmat(T_a_b[:3, 3], 1, p_b.shape[1])
    T_a_b = np.asarray(T_a_b, dtype=float)
    p_b = np.asarray(p_b, dtype=float)
    return p_b @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def kabsch(p_src: ArrayLike, p_dst: ArrayLike) -> NDArray[np.float64]:
    """Least-squares rigid transform (4, 4) mapping points `p_src` (n, 3) onto `p_dst` (n, 3).

    Minimises Σ_i ||R p_src_i + t − p_dst_i||² over R ∈ SO(3), t ∈ R³ (Besl & McKay 1992, by SVD of
    the cross-covariance, with the reflection fix).
    """
    p_src = np.asarray(p_src, dtype=float)
    p_dst = np.asarray(p_dst, dtype=float)
    c_src, c_dst = p_src.mean(axis=0), p_dst.mean(axis=0)
    H = (p_src - c_src).T @ (p_dst - c_dst)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    D = np.diag([1.0, 1.0, d if d != 0 else 1.0])
    R = Vt.T @ D @ U.T
    return make_T(R, c_dst - R @ c_src)


def rotation_angle(R_a: ArrayLike, R_b: ArrayLike) -> float:
    """Geodesic angle (rad) between two rotations (3, 3): arccos((tr(R_aᵀ R_b) − 1) / 2)."""
    c = (np.trace(np.asarray(R_a).T @ np.asarray(R_b)) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def exp_so3(w: ArrayLike) -> NDArray[np.float64]:
    """Rotation (3, 3) of the rotation vector `w` (3,), rad (axis times angle)."""
    w = np.asarray(w, dtype=float)
    a = np.linalg.norm(w)
    if a < 1e-15:
        return np.eye(3)
    return rot_axis_angle(w / a, a)


def log_SO3(R: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector (3,) of a rotation (3, 3), rad; inverse of `exp_so3` for angles in [0, π) (at π,
    one of the two opposite vectors).

    With w = vee(R − Rᵀ) = 2 sin θ a: θ = atan2(‖w‖ / 2, (tr R − 1) / 2) (accurate over [0, π], unlike
    arccos of the trace near 0 and π) and, for θ ≤ π/2, a = w / ‖w‖. Above π/2, as w vanishes towards π
    (a from w would err by ~1e-16 / sin θ), the axis comes from the symmetric part
    (R + Rᵀ) / 2 = cos θ I + (1 − cos θ) a aᵀ (the column of a aᵀ with the largest diagonal entry) and
    only its sign from w.
    """
    R = np.asarray(R, dtype=float)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])  # 2 sin θ · axis
    sin_theta, cos_theta = 0.5 * float(np.linalg.norm(w)), 0.5 * (float(np.trace(R)) - 1.0)
    theta = float(np.arctan2(sin_theta, cos_theta))
    if cos_theta >= 0.0:
        return 0.5 * w if sin_theta == 0.0 else (0.5 * theta / sin_theta) * w
    aaT = (0.5 * (R + R.T) - cos_theta * np.eye(3)) / (1.0 - cos_theta)  # axis · axisᵀ
    j = int(np.argmax(np.diag(aaT)))
    axis = aaT[:, j] / np.linalg.norm(aaT[:, j])
    return theta * (-axis if axis @ w < 0.0 else axis)


def log_SO3_batch(R: ArrayLike) -> NDArray[np.float64]:
    """Rotation vectors (k, 3), rad, of rotations (k, 3, 3): `log_SO3` of each, vectorised (the same
    formulas: θ = atan2(‖w‖ / 2, (tr R − 1) / 2) with w = vee(R − Rᵀ); the axis from w where
    cos θ ≥ 0, from the symmetric part beyond π/2)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    w = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    sin_theta = 0.5 * np.sqrt(np.einsum("ij,ij->i", w, w))
    cos_theta = 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0)
    theta = np.arctan2(sin_theta, cos_theta)
    turning = sin_theta > 0.0
    out = 0.5 * w
    out[turning] *= (theta[turning] / sin_theta[turning])[:, None]
    wide = cos_theta < 0.0
    if np.any(wide):
        Rw, cw = R[wide], cos_theta[wide]
        sym = 0.5 * (Rw + np.transpose(Rw, (0, 2, 1))) - cw[:, None, None] * np.eye(3)
        aaT = sym / (1.0 - cw)[:, None, None]  # axis · axisᵀ
        j = np.argmax(np.diagonal(aaT, axis1=1, axis2=2), axis=1)
        axis = aaT[np.arange(len(j)), :, j]
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        flip = np.einsum("ij,ij->i", axis, w[wide]) < 0.0
        axis[flip] *= -1.0
        out[wide] = theta[wide][:, None] * axis
    return out


def interpolate_pose(T_a: ArrayLike, T_b: ArrayLike, s: float) -> NDArray[np.float64]:
    """The pose (4, 4) a fraction `s` ∈ [0, 1] of the way from `T_a` to `T_b`: translation linear,
    rotation along the geodesic (R_a exp(s log(R_aᵀ R_b)))."""
    T_a, T_b = np.asarray(T_a, dtype=float), np.asarray(T_b, dtype=float)
    w = log_SO3(T_a[:3, :3].T @ T_b[:3, :3])
    return make_T(T_a[:3, :3] @ exp_so3(s * w), T_a[:3, 3] + s * (T_b[:3, 3] - T_a[:3, 3]))
