"""Rigid transforms (transforms.py) as mathematics: group laws, round trips and scipy as the reference.

Rotations are drawn as rotation vectors (hypothesis) and built with scipy, so no property is checked
against the code it tests. Functions that accept CasADi (rot_axis_angle, make_T, inv_T,
transform_points) are checked with numpy, DM and SX inputs.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from regrasp_casadi.transforms import (
    exp_so3,
    interpolate_pose,
    inv_T,
    kabsch,
    log_SO3,
    log_SO3_batch,
    make_T,
    rot_axis_angle,
    rotation_angle,
    rpy_to_R,
    transform_points,
)

PROPERTY = settings(max_examples=60, deadline=None)

_unit = st.floats(-1.0, 1.0, allow_nan=False)
_axes = st.tuples(_unit, _unit, _unit).map(np.array).filter(lambda v: np.linalg.norm(v) > 1e-3).map(
    lambda v: v / np.linalg.norm(v))
_translations = st.tuples(*[st.floats(-0.5, 0.5, allow_nan=False)] * 3).map(np.array)


def _rotvecs(max_angle: float = np.pi - 1e-3):
    """Rotation vectors (3,) rad with angle in [0, max_angle]."""
    return st.builds(lambda a, s: a * s, _axes, st.floats(0.0, max_angle, allow_nan=False))


def _rotations():
    """(3, 3) rotations, built by scipy from a rotation vector (angle in [0, π])."""
    return _rotvecs(np.pi).map(lambda w: Rotation.from_rotvec(w).as_matrix())


def _poses():
    return st.builds(make_T, _rotations(), _translations)


def _dm(x) -> np.ndarray:
    """A CasADi matrix (DM, or SX without free symbols) as a numpy array."""
    return np.asarray(ca.evalf(x) if isinstance(x, ca.SX) else x, dtype=float)


# ------------------------------------------------------------------------------------------- so(3)/SO(3)
@PROPERTY
@given(_rotvecs())
def test_exp_so3_is_scipys_rotation_vector_map(w):
    np.testing.assert_allclose(exp_so3(w), Rotation.from_rotvec(w).as_matrix(), atol=1e-12)


@PROPERTY
@given(_rotvecs())
def test_log_inverts_exp_below_pi(w):
    """log(exp(w)) = w for |w| ∈ [0, π − 1e-3] (the principal branch)."""
    np.testing.assert_allclose(log_SO3(exp_so3(w)), w, atol=1e-8)


@PROPERTY
@given(st.floats(0.0, 1e-6))
def test_log_exp_round_trip_near_identity(angle):
    w = angle * np.array([0.6, -0.8, 0.0])
    np.testing.assert_allclose(log_SO3(exp_so3(w)), w, atol=1e-14)


@pytest.mark.parametrize("gap", [np.pi / 2 + 1e-9, np.pi / 2 - 1e-9, 1e-2, 1e-3, 1e-4, 3e-5, 1e-5, 3e-6,
                                 1.01e-6, 1e-7, 1e-9, 1e-12, 0.0])
def test_exp_of_log_is_the_rotation_near_pi(gap):
    """Near θ = π the rotation vector is ambiguous in sign, but exp(log(R)) must still be R, to rounding
    (on both sides of θ = π/2, where log_SO3 switches from the skew to the symmetric part of R)."""
    rng = np.random.default_rng(7)
    axes = rng.normal(size=(50, 3))
    worst = 0.0
    for axis in axes / np.linalg.norm(axes, axis=1, keepdims=True):
        R = Rotation.from_rotvec((np.pi - gap) * axis).as_matrix()
        w = log_SO3(R)
        assert np.linalg.norm(w) <= np.pi + 1e-12
        worst = max(worst, float(np.max(np.abs(exp_so3(w) - R))))
    assert worst <= 1e-14


@PROPERTY
@given(st.lists(_rotvecs(), min_size=1, max_size=6))
def test_log_batch_is_scipys_rotation_vector_below_pi(ws):
    """Every row is scipy's rotation vector of its matrix (angles in [0, π − 1e-3]: unique), on both sides
    of π/2 where the axis comes from the skew or the symmetric part."""
    R = Rotation.from_rotvec(np.array(ws)).as_matrix()
    np.testing.assert_allclose(log_SO3_batch(R), Rotation.from_matrix(R).as_rotvec(), atol=1e-9)


def test_log_batch_near_pi_and_identity_gives_back_the_rotation():
    """At angles within 1e-12 of π and of 0 (and exactly 0), exp of each row is its matrix to rounding."""
    rng = np.random.default_rng(8)
    axes = rng.normal(size=(40, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([np.pi - np.array([1e-12, 1e-9, 1e-6, 0.0]), [1e-12, 1e-7, 0.0, np.pi / 2]])
    R = Rotation.from_rotvec(np.repeat(axes, len(angles), axis=0) * np.tile(angles, len(axes))[:, None]
                             ).as_matrix()
    w = log_SO3_batch(R)
    assert np.all(np.linalg.norm(w, axis=1) <= np.pi + 1e-12)
    assert max(float(np.max(np.abs(exp_so3(wi) - Ri))) for wi, Ri in zip(w, R, strict=True)) <= 1e-14


@PROPERTY
@given(_rotations(), _rotations())
def test_rotation_angle_is_symmetric_and_the_norm_of_log(R_a, R_b):
    angle = rotation_angle(R_a, R_b)
    assert angle == pytest.approx(rotation_angle(R_b, R_a), abs=1e-12)
    reference = Rotation.from_matrix(R_a.T @ R_b).magnitude()
    assert angle == pytest.approx(reference, abs=1e-7)
    assume(angle < np.pi - 1e-3)  # log's norm is ill-conditioned at π (see the near-π test)
    assert np.linalg.norm(log_SO3(R_a.T @ R_b)) == pytest.approx(angle, abs=1e-7)


def test_rotation_angle_golden_values():
    assert rotation_angle(np.eye(3), np.eye(3)) == 0.0
    assert rotation_angle(np.eye(3), rot_axis_angle([0, 0, 1], np.pi / 2)) == pytest.approx(np.pi / 2)
    assert rotation_angle(np.eye(3), np.diag([1.0, -1.0, -1.0])) == pytest.approx(np.pi)


@PROPERTY
@given(_axes, st.floats(-2 * np.pi, 2 * np.pi))
def test_rot_axis_angle_numpy_dm_and_sx(axis, angle):
    expected = Rotation.from_rotvec(angle * axis).as_matrix()
    np.testing.assert_allclose(rot_axis_angle(axis, angle), expected, atol=1e-12)
    np.testing.assert_allclose(_dm(rot_axis_angle(axis, ca.DM(angle))), expected, atol=1e-12)
    a = ca.SX.sym("a")
    f = ca.Function("R", [a], [rot_axis_angle(axis, a)])
    np.testing.assert_allclose(_dm(f(angle)), expected, atol=1e-12)


# ---------------------------------------------------------------------------------------- roll-pitch-yaw
@PROPERTY
@given(st.floats(-np.pi, np.pi), st.floats(-np.pi / 2, np.pi / 2), st.floats(-np.pi, np.pi))
def test_rpy_is_urdf_fixed_axis_convention(roll, pitch, yaw):
    """URDF rpy: about the fixed x, then y, then z axes: R = Rz(yaw) Ry(pitch) Rx(roll) (scipy "xyz",
    lower case = extrinsic)."""
    expected = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()
    np.testing.assert_allclose(rpy_to_R(roll, pitch, yaw), expected, atol=1e-12)
    Rx = Rotation.from_rotvec([roll, 0, 0]).as_matrix()
    Ry = Rotation.from_rotvec([0, pitch, 0]).as_matrix()
    Rz = Rotation.from_rotvec([0, 0, yaw]).as_matrix()
    np.testing.assert_allclose(rpy_to_R(roll, pitch, yaw), Rz @ Ry @ Rx, atol=1e-12)


def test_rpy_golden_values():
    # yaw π/2 maps x to y; pitch π/2 maps x to −z; roll π/2 maps y to z
    np.testing.assert_allclose(rpy_to_R(0, 0, np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rpy_to_R(0, np.pi / 2, 0) @ [1, 0, 0], [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(rpy_to_R(np.pi / 2, 0, 0) @ [0, 1, 0], [0, 0, 1], atol=1e-15)


# ----------------------------------------------------------------------------------------------- SE(3)
_T_sym = ca.SX.sym("T", 4, 4)
_INV_T_SX = ca.Function("inv_T", [_T_sym], [inv_T(_T_sym)])


_R_sym, _p_sym, _pts_sym = ca.SX.sym("R", 3, 3), ca.SX.sym("p", 3), ca.SX.sym("pts", 3, 7)
_TRANSFORM_SX = ca.Function("transform", [_R_sym, _p_sym, _pts_sym],
                            [transform_points(make_T(_R_sym, _p_sym), _pts_sym)])


@PROPERTY
@given(_poses())
def test_inv_T_is_the_inverse_numpy_dm_and_sx(T):
    np.testing.assert_allclose(inv_T(T) @ T, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(T @ inv_T(T), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(inv_T(T), np.linalg.inv(T), atol=1e-12)
    np.testing.assert_allclose(_dm(inv_T(ca.DM(T))), np.linalg.inv(T), atol=1e-12)
    np.testing.assert_allclose(_dm(_INV_T_SX(T)), np.linalg.inv(T), atol=1e-12)


@PROPERTY
@given(_rotations(), _translations, st.integers(0, 2 ** 32 - 1))
def test_make_T_and_transform_points_are_the_homogeneous_product(R, p, seed):
    T = make_T(R, p)
    assert T.shape == (4, 4)
    np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    pts_b = np.random.default_rng(seed).normal(size=(7, 3))
    homogeneous = np.hstack([pts_b, np.ones((7, 1))])
    expected = (T @ homogeneous.T).T[:, :3]
    np.testing.assert_allclose(transform_points(T, pts_b), expected, atol=1e-12)
    # CasADi: points are columns (3, n); DM inputs and SX symbols
    np.testing.assert_allclose(_dm(make_T(ca.DM(R), ca.DM(p))), T, atol=0)
    np.testing.assert_allclose(_dm(transform_points(ca.DM(T), ca.DM(pts_b.T))).T, expected, atol=1e-12)
    np.testing.assert_allclose(_dm(_TRANSFORM_SX(R, p, pts_b.T)).T, expected, atol=1e-12)


@PROPERTY
@given(_poses(), _poses(), st.integers(0, 2 ** 32 - 1))
def test_transform_points_composes(T_a_b, T_b_c, seed):
    pts_c = np.random.default_rng(seed).normal(size=(5, 3))
    np.testing.assert_allclose(transform_points(T_a_b @ T_b_c, pts_c),
                               transform_points(T_a_b, transform_points(T_b_c, pts_c)), atol=1e-12)


# ---------------------------------------------------------------------------------------------- Kabsch
def _spread_points(seed: int, n: int) -> np.ndarray:
    pts = np.random.default_rng(seed).normal(size=(n, 3)) * 0.05
    s = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    assume(s[-1] > 1e-3)  # not (nearly) coplanar: the rigid transform is unique
    return pts


@PROPERTY
@given(_poses(), st.integers(0, 2 ** 32 - 1), st.integers(4, 12))
def test_kabsch_recovers_an_exact_rigid_transform(T, seed, n):
    src = _spread_points(seed, n)
    T_est = kabsch(src, transform_points(T, src))
    np.testing.assert_allclose(T_est, T, atol=1e-10)
    assert np.linalg.det(T_est[:3, :3]) == pytest.approx(1.0, abs=1e-12)


@PROPERTY
@given(_poses(), st.integers(0, 2 ** 32 - 1), st.integers(4, 12), st.floats(1e-4, 1e-2))
def test_kabsch_with_noise_fits_no_worse_than_the_truth(T, seed, n, noise):
    src = _spread_points(seed, n)
    dst = transform_points(T, src) + np.random.default_rng(seed + 1).normal(size=(n, 3)) * noise
    T_est = kabsch(src, dst)

    def sse(T_):
        return float(np.sum((transform_points(T_, src) - dst) ** 2))

    assert sse(T_est) <= sse(T) * (1 + 1e-9) + 1e-18
    R_est = T_est[:3, :3]
    np.testing.assert_allclose(R_est.T @ R_est, np.eye(3), atol=1e-12)
    assert np.linalg.det(R_est) == pytest.approx(1.0, abs=1e-12)


def test_kabsch_returns_a_rotation_for_mirrored_data():
    """Points mirrored through a plane: the best proper rotation, never a reflection."""
    src = np.random.default_rng(3).normal(size=(8, 3)) * 0.05
    dst = src * [1.0, 1.0, -1.0]
    R = kabsch(src, dst)[:3, :3]
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


# ----------------------------------------------------------------------------------------- interpolation
@PROPERTY
@given(_poses(), _poses(), st.floats(0.0, 1.0))
def test_interpolate_pose_is_the_geodesic(T_a, T_b, s):
    total = rotation_angle(T_a[:3, :3], T_b[:3, :3])
    assume(total < np.pi - 1e-3)  # the geodesic is unique
    np.testing.assert_allclose(interpolate_pose(T_a, T_b, 0.0), T_a, atol=1e-12)
    np.testing.assert_allclose(interpolate_pose(T_a, T_b, 1.0), T_b, atol=1e-8)
    T_s = interpolate_pose(T_a, T_b, s)
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([T_a[:3, :3], T_b[:3, :3]])))
    np.testing.assert_allclose(T_s[:3, :3], slerp([s]).as_matrix()[0], atol=1e-8)
    np.testing.assert_allclose(T_s[:3, 3], (1 - s) * T_a[:3, 3] + s * T_b[:3, 3], atol=1e-12)
    # constant speed along the geodesic: the angles from either end add up to the whole
    assert rotation_angle(T_a[:3, :3], T_s[:3, :3]) == pytest.approx(s * total, abs=1e-7)
    assert rotation_angle(T_s[:3, :3], T_b[:3, :3]) == pytest.approx((1 - s) * total, abs=1e-7)


def test_interpolate_pose_midpoint_golden():
    T_a = make_T(np.eye(3), [0.0, 0.0, 0.0])
    T_b = make_T(rot_axis_angle([0, 0, 1], np.pi / 2), [0.2, 0.0, -0.1])
    mid = interpolate_pose(T_a, T_b, 0.5)
    np.testing.assert_allclose(mid, make_T(rot_axis_angle([0, 0, 1], np.pi / 4), [0.1, 0.0, -0.05]),
                               atol=1e-12)
