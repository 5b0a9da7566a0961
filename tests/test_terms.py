"""The symbolic NLP building blocks (terms.py) as mathematics, checked against scipy, closed forms and
finite differences. (The signed-distance builders are tested with the distance core.)"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from regrasp_casadi import terms
from regrasp_casadi.transforms import inv_T, make_T, transform_points

PROPERTY = settings(max_examples=60, deadline=None)

_vec3 = st.tuples(*[st.floats(-3.0, 3.0, allow_nan=False)] * 3).map(np.array)
_small3 = st.tuples(*[st.floats(-0.2, 0.2, allow_nan=False)] * 3).map(np.array)
_rotations = st.tuples(*[st.floats(-np.pi, np.pi, allow_nan=False)] * 3).map(
    lambda v: Rotation.from_rotvec(v).as_matrix())

# symbolic functions, built once
_w = ca.SX.sym("w", 3)
_CAYLEY = ca.Function("cayley", [_w], [terms.cayley_rotation(_w)])
_R0, _t0, _dt = ca.SX.sym("R0", 3, 3), ca.SX.sym("t0", 3), ca.SX.sym("dt", 3)
_POSE = ca.Function("pose", [_R0, _t0, _dt, _w], list(terms.pose_from_params(_R0, _t0, _dt, _w)))
_p_palm = ca.SX.sym("p_palm", 3, 5)
_TO_OBJECT = ca.Function("to_object", [_R0, _t0, _p_palm], [terms.to_object_frame(_R0, _t0, _p_palm)])
_Ra, _Rb = ca.SX.sym("Ra", 3, 3), ca.SX.sym("Rb", 3, 3)
_ROT_ERR = ca.Function("rot_err", [_Ra, _Rb], [terms.rotation_error_sq(_Ra, _Rb)])


def _softplus_functions(tau: float) -> tuple[ca.Function, ca.Function]:
    x = ca.SX.sym("x")
    y = terms.softplus(x, tau)
    return ca.Function("softplus", [x], [y]), ca.Function("dsoftplus", [x], [ca.gradient(y, x)])


_TAUS = (1e-3, 0.01, 1.0)
_SOFTPLUS = {tau: _softplus_functions(tau) for tau in _TAUS}


def _np(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


# ------------------------------------------------------------------------------------------------ Cayley
@PROPERTY
@given(_vec3)
def test_cayley_rotation_is_a_rotation_by_twice_atan(w):
    """C(w) is a proper rotation by θ = 2·atan(|w|) about w/|w| (the Gibbs vector w = tan(θ/2)·axis)."""
    R = _np(_CAYLEY(w))
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    norm = np.linalg.norm(w)
    expected = np.eye(3) if norm == 0 else Rotation.from_rotvec(2 * np.arctan(norm) * w / norm).as_matrix()
    np.testing.assert_allclose(R, expected, atol=1e-12)
    # the DM path gives the same matrix
    np.testing.assert_allclose(_np(terms.cayley_rotation(ca.DM(w))), R, atol=1e-15)


def test_cayley_golden_values():
    np.testing.assert_array_equal(_np(_CAYLEY([0, 0, 0])), np.eye(3))
    # w = tan(π/4)·z = z: a quarter turn about z maps x to y
    np.testing.assert_allclose(_np(_CAYLEY([0, 0, 1])) @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_cayley_is_smooth_at_zero_with_the_rotation_vector_derivative():
    """dC/dw at 0 is 2·skew(e_i): the first-order rotation by 2w (central differences agree)."""
    J = _np(ca.Function("J", [_w], [ca.jacobian(ca.vec(terms.cayley_rotation(_w)), _w)])(np.zeros(3)))
    h = 1e-6
    for i in range(3):
        e = np.eye(3)[i]
        fd = (_np(_CAYLEY(h * e)) - _np(_CAYLEY(-h * e))) / (2 * h)
        np.testing.assert_allclose(J[:, i].reshape(3, 3, order="F"), fd, atol=1e-9)
        np.testing.assert_allclose(fd, 2 * np.cross(np.eye(3), e), atol=1e-9)  # 2·skew(e) (rows: e_k × e)


# --------------------------------------------------------------------------------------- pose and frames
@PROPERTY
@given(_rotations, _small3, _small3, _vec3, st.integers(0, 2 ** 32 - 1))
def test_pose_from_params_rotates_about_the_object_origin_then_translates(R0, t0, dt, w, seed):
    """A point fixed on the object moves as p' = C(w)(p − t0) + t0 + dt in the palm frame."""
    R, t = (_np(v) for v in _POSE(R0, t0, dt, w))
    norm = np.linalg.norm(w)
    C = np.eye(3) if norm == 0 else Rotation.from_rotvec(2 * np.arctan(norm) * w / norm).as_matrix()
    p_object = np.random.default_rng(seed).normal(size=(6, 3)) * 0.05
    p_palm_before = transform_points(make_T(R0, t0), p_object)
    p_palm_after = transform_points(make_T(R, t.ravel()), p_object)
    np.testing.assert_allclose(p_palm_after, (p_palm_before - t0) @ C.T + t0 + dt, atol=1e-12)


@PROPERTY
@given(_rotations, _small3, st.integers(0, 2 ** 32 - 1))
def test_to_object_frame_is_the_inverse_transform(R, t, seed):
    p_palm = np.random.default_rng(seed).normal(size=(5, 3)) * 0.1
    p_object = _np(_TO_OBJECT(R, t, p_palm.T)).T
    np.testing.assert_allclose(p_object, transform_points(inv_T(make_T(R, t)), p_palm), atol=1e-12)
    np.testing.assert_allclose(transform_points(make_T(R, t), p_object), p_palm, atol=1e-12)


@PROPERTY
@given(_rotations, _rotations)
def test_rotation_error_sq_is_4_one_minus_cos(R_a, R_b):
    theta = Rotation.from_matrix(R_a.T @ R_b).magnitude()
    assert float(_ROT_ERR(R_a, R_b)) == pytest.approx(4 * (1 - np.cos(theta)), abs=1e-11)


# ---------------------------------------------------------------------------------------------- softplus
@PROPERTY
@given(st.sampled_from(_TAUS), st.floats(-50.0, 50.0, allow_nan=False))
def test_softplus_bounds(tau, x):
    """max(0, x) ≤ τ·log(1 + exp(x/τ)) ≤ max(0, x) + τ·log 2, and it equals the closed form."""
    f, _ = _SOFTPLUS[tau]
    y = float(f(x))
    assert np.isfinite(y)
    assert y >= max(0.0, x)
    assert y <= max(0.0, x) + tau * np.log(2) + 1e-15
    assert y == pytest.approx(tau * np.logaddexp(0.0, x / tau), rel=1e-12, abs=1e-15)


def test_softplus_at_zero_and_far_out():
    for tau in _TAUS:
        f, df = _SOFTPLUS[tau]
        assert float(f(0.0)) == pytest.approx(tau * np.log(2), rel=1e-15)
        assert float(df(0.0)) == 0.5  # the kinks of max and |·| cancel: the logistic at 0
        assert float(f(1e4)) == 1e4  # no overflow: exp(1e7) is never formed
        assert 0.0 <= float(f(-1e4)) < 1e-300


@PROPERTY
@given(st.sampled_from(_TAUS), st.floats(-1.0, 1.0, allow_nan=False))
def test_softplus_derivative_is_the_logistic_and_matches_finite_differences(tau, x_over_tau):
    x = tau * x_over_tau * 10  # |x/τ| ≤ 10: where the derivative is not flat
    f, df = _SOFTPLUS[tau]
    h = 1e-5 * tau
    fd = (float(f(x + h)) - float(f(x - h))) / (2 * h)
    assert float(df(x)) == pytest.approx(1 / (1 + np.exp(-x / tau)), abs=1e-12)
    assert float(df(x)) == pytest.approx(fd, abs=1e-7)


# ------------------------------------------------------------------------------------- joint substitution
@PROPERTY
@given(st.integers(1, 16).flatmap(lambda n: st.tuples(
    st.just(n), st.lists(st.integers(0, n - 1), unique=True, max_size=n))))
def test_substitute_joints_replaces_exactly_the_indices(n_and_indices):
    n, indices = n_and_indices
    indices = np.asarray(indices, dtype=int)
    q_param = ca.SX.sym("q", n)
    q_sub = ca.SX.sym("s", indices.size)
    q_full = terms.substitute_joints(q_param, indices, q_sub)
    f = ca.Function("sub", [q_param, q_sub], [q_full, ca.jacobian(q_full, q_sub)])
    rng = np.random.default_rng(n)
    q, s = rng.normal(size=n), rng.normal(size=indices.size)
    value, J = (_np(v) for v in f(q, s))
    expected = q.copy()
    expected[indices] = s
    np.testing.assert_array_equal(value.ravel(), expected)
    selection = np.zeros((n, indices.size))
    selection[indices, np.arange(indices.size)] = 1.0
    np.testing.assert_array_equal(J, selection)
