"""Symbolic (CasADi SX) cost and constraint builders shared by the NLPs.

Each builder takes CasADi expressions and returns CasADi expressions; none of them builds or solves
an NLP. Units are SI (m, rad); the NLPs rescale to centimetres / millimetres themselves.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "cayley_rotation",
    "pose_from_params",
    "to_object_frame",
    "smooth_signed_distances",
    "softplus",
    "rotation_error_sq",
    "substitute_joints",
    "rolling_offset",
]


def cayley_rotation(w: ca.SX) -> ca.SX:
    """Rotation (3, 3) of a Gibbs/Cayley vector `w` (3,): R = I + 2/(1 + wᵀw) (W + W²); SX, MX or DM.

    `w = tan(θ/2) · axis`, so it is smooth at w = 0 (unlike the rotation vector), which keeps IPOPT's
    exact Hessian well behaved for small object rotations.
    """
    W = ca.skew(w)
    return ca.DM.eye(3) + 2.0 / (1.0 + ca.dot(w, w)) * (W + W @ W)


def pose_from_params(R0: ca.SX, t0: ca.SX, dt: ca.SX, w: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Object pose (R_palm_object, t_palm_object) after a move: rotate by cayley(w) about the object's
    origin (palm axes), translate by dt (3,) m: R = C(w) R0, t = t0 + dt."""
    return cayley_rotation(w) @ R0, t0 + dt


def to_object_frame(R_palm_object: ca.SX, t_palm_object: ca.SX, p_palm: ca.SX) -> ca.SX:
    """Points (3, k) in the palm frame → object frame: p_object = Rᵀ (p_palm − t)."""
    k = p_palm.shape[1]
    return R_palm_object.T @ (p_palm - ca.repmat(t_palm_object, 1, k))


def smooth_signed_distances(sd_function: ca.Function, p_object: ca.SX) -> ca.SX:
    """Smooth signed distance (k,) of each column of `p_object` (3, k) to the object, m."""
    k = p_object.shape[1]
    return ca.vertcat(*[sd_function(p_object[:, i]) for i in range(k)])


def softplus(x: ca.SX, tau: float) -> ca.SX:
    """Smooth max(0, x): τ·log(1 + exp(x/τ)), written to avoid overflow for large x."""
    return ca.fmax(x, 0) + tau * ca.log(1 + ca.exp(-ca.fabs(x) / tau))


def rotation_error_sq(R_a: ca.SX, R_b: ca.SX) -> ca.SX:
    """||R_a − R_b||_F² = 2 (3 − tr(R_aᵀ R_b)) = 4 (1 − cos θ) ≈ 2θ² for small angles θ."""
    return ca.sumsqr(R_a - R_b)


def substitute_joints(q_param: ca.SX, indices: NDArray[np.int_], q_sub: ca.SX) -> ca.SX:
    """Full joint vector (n,) equal to `q_param` except at `indices`, where it takes `q_sub`."""
    parts = [q_param[i] for i in range(q_param.shape[0])]
    for j, i in enumerate(indices):
        parts[int(i)] = q_sub[j]
    return ca.vertcat(*parts)


def rolling_offset(R_object_tip: ca.SX, R_object_tip_start: ca.SX, n_object: ca.SX, radius: float) -> ca.SX:
    """Displacement (3,) of a spherical tip's centre, object frame, m, when it rolls without slipping
    from orientation `R_object_tip_start` to `R_object_tip` (3, 3) over a surface of outward normal
    `n_object` (3,): ρ θ × n, θ the rotation vector of R Rₛᵀ (`grasp_metrics.tip_slip` measures the rest
    as slip). θ from the skew part v = vee(R Rₛᵀ − Rₛ Rᵀ)/2 = sin|θ| θ̂ by the series of arcsin,
    v (1 + s/6 + 3 s²/40) with s = |v|² (short of |θ| by 4e-4 rad at 30°, 1e-5 rad at 15°), smooth at
    θ = 0; a reposing turns a tip by less (OPT2's trust region)."""
    R_rel = R_object_tip @ R_object_tip_start.T
    v = 0.5 * ca.vertcat(R_rel[2, 1] - R_rel[1, 2], R_rel[0, 2] - R_rel[2, 0], R_rel[1, 0] - R_rel[0, 1])
    s = ca.dot(v, v)
    theta = v * (1.0 + s / 6.0 + 3.0 * s * s / 40.0)
    return float(radius) * ca.cross(theta, n_object)
