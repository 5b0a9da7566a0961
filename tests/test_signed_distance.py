"""Tests of regrasp_casadi.signed_distance: the log-sum-exp core and the four smooth distances the NLPs
use (full, coarse clearance, local planes, workspace hull): bounds, derivatives, function names."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from random_shapes import random_hull

from regrasp_casadi import signed_distance
from regrasp_casadi.convex import LOCAL_PIECES, LOCAL_PLANES
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.signed_distance import (
    DEFAULT_TAU,
    function_name,
    hull_signed_distance,
    local_signed_distance,
    smooth_max,
    smooth_min,
)

TAU = DEFAULT_TAU
GRASP_GEN_TAU = 2e-3  # the temperature grasp_gen's NLP uses
HULL_TAU = 2e-3  # InGraspOptions.tau_hull


# ---------------------------------------------------------------- support-function distance
@settings(max_examples=30, deadline=None)
@given(
    ext=st.tuples(*[st.floats(0.01, 0.3)] * 3),
    u=st.tuples(*[st.floats(-1.5, 1.5)] * 3),
)
def test_box_distances_match_closed_form(ext, u):
    obj = ObjectModel.box(ext)
    half = np.asarray(ext) / 2
    p = (np.asarray(u) * half)[None]
    q = np.abs(p[0]) - half
    closed = np.linalg.norm(np.maximum(q, 0.0)) + min(q.max(), 0.0)
    hard = obj.pieces[0].hard_distance(p)[0]
    assert obj.exact_signed_distance(p)[0] == pytest.approx(closed, abs=1e-12)
    if q.max() <= 0:  # inside: the support-function distance is exact
        assert hard == pytest.approx(closed, abs=1e-12)
    else:
        assert hard <= closed + 1e-12
    smooth = obj.signed_distance(p)[0]
    assert hard - 1e-12 <= smooth <= hard + TAU * np.log(len(obj.pieces[0].offsets)) + 1e-12


@settings(max_examples=50, deadline=None)
@given(
    z=st.lists(st.floats(-0.2, 0.2), min_size=1, max_size=40),
    tau=st.floats(1e-5, 1e-2),
)
def test_log_sum_exp_and_smooth_min_bounds(z, tau):
    z = np.asarray(z)
    k = len(z)
    smax = float(smooth_max(ca.DM(z), tau))
    smin = float(smooth_min(ca.DM(z), tau))
    slack = 1e-12 + 1e-12 * np.abs(z).max()
    assert z.max() - slack <= smax <= z.max() + tau * np.log(k) + slack
    assert z.min() - tau * np.log(k) - slack <= smin <= z.min() + slack


def test_multi_piece_smooth_distance_within_stated_bounds(banana_small):
    obj = banana_small
    assert len(obj.pieces) >= 2
    rng = np.random.default_rng(3)
    lo, hi = obj.mesh.bounds
    pts = rng.uniform(lo - 0.02, hi + 0.02, size=(300, 3))
    hard = np.stack([pc.hard_distance(pts) for pc in obj.pieces]).min(axis=0)
    smooth = obj.signed_distance(pts)
    k_max = max(len(pc.offsets) for pc in obj.pieces)
    assert np.all(smooth >= hard - TAU * np.log(len(obj.pieces)) - 1e-12)
    assert np.all(smooth <= hard + TAU * np.log(k_max) + 1e-12)
    # outside the object, the smooth value never exceeds the exact distance by more than the bias bound
    exact = obj.exact_signed_distance(pts)
    assert np.all(smooth[exact > 0] <= exact[exact > 0] + obj.bias_bound + 1e-12)
    assert obj.bias_bound == pytest.approx(TAU * np.log(k_max))


def test_mx_and_sx_functions_agree(banana_small):
    pts = np.random.default_rng(5).uniform(-0.1, 0.1, size=(3, 40))
    sx = banana_small.signed_distance_function().map(40)(pts)
    mx = banana_small.signed_distance_function(symbolic="MX").map(40)(pts)
    np.testing.assert_allclose(np.asarray(mx), np.asarray(sx), atol=1e-14)


# ---------------------------------------------------------------- local planes
def _piece_of(obj: ObjectModel, normals: np.ndarray, offsets: np.ndarray) -> int:
    """Index of the piece whose planes the local set (k, 3), (k,) was taken from."""
    for c, pc in enumerate(obj.pieces):
        rows = (normals[:, None, :] == pc.normals[None]).all(axis=2) & (offsets[:, None] == pc.offsets[None])
        if rows.any(axis=1).all():
            return c
    raise AssertionError("local planes from no single piece")


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), which=st.sampled_from(["hull", "banana"]),
       offset=st.floats(-0.01, 0.03), move=st.tuples(*[st.floats(-0.03, 0.03)] * 3))
def test_local_planes_distance_is_the_hard_distance_where_selected_and_a_lower_bound_elsewhere(
        banana_small, seed, which, offset, move):
    """At the point the planes were selected for, the local-plane distance equals the full model's hard
    distance min_C max_i (n_i·p − h_i) up to the smoothing bias (−τ·log P, +τ·log k: vanishing with τ);
    elsewhere it is a lower bound (+τ·log k) of the hard distance of the pieces it kept (of the whole
    model for a one-piece object, where it is also below the full smooth distance)."""
    obj = banana_small if which == "banana" else ObjectModel.from_trimesh(random_hull(seed), convex=True)
    pts, normals = obj.sample_surface(1, seed=seed)
    p_sel = pts[0] + offset * normals[0]
    x = p_sel + np.asarray(move)
    n_local = min(LOCAL_PIECES, len(obj.pieces))
    N, H = obj.local_planes(p_sel, n_local)
    kept = sorted({_piece_of(obj, N[j], H[j]) for j in range(n_local)})
    hard_full = lambda q: min(float(pc.hard_distance(q[None])[0]) for pc in obj.pieces)  # noqa: E731
    hard_kept = min(float(obj.pieces[c].hard_distance(x[None])[0]) for c in kept)
    p = ca.SX.sym("p", 3)
    N_sym, H_sym = ca.SX.sym("N", N.size), ca.SX.sym("H", H.size)
    for tau in (TAU, 1e-8):
        f = ca.Function("local", [p, N_sym, H_sym], [local_signed_distance(N_sym, H_sym, p, n_local, tau)])
        local = lambda q: float(f(q, N.ravel(), H.ravel()))  # noqa: E731, B023
        at, eps = hard_full(p_sel), 1e-12
        assert at - tau * np.log(n_local) - eps <= local(p_sel) <= at + tau * np.log(LOCAL_PLANES) + eps
        assert local(x) <= hard_kept + tau * np.log(LOCAL_PLANES) + eps
        if len(obj.pieces) == 1 and len(obj.pieces[0].offsets) >= LOCAL_PLANES:
            # no repeated plane: a subset of the full model's terms, so below its smooth value too
            assert local(x) <= float(obj.signed_distance_function(tau)(x)) + eps


# ---------------------------------------------------------------- derivatives
def _special_points(obj: ObjectModel) -> np.ndarray:
    m = obj.mesh
    edges = m.vertices[m.edges_unique].mean(axis=1)
    far = np.array([[1.0, 0.0, 0.0], [0.0, -2.0, 3.0]])
    return np.concatenate([m.vertices[:20], edges[:20], [m.centroid], far])


@pytest.mark.parametrize("which", ["box", "cylinder", "banana"])
def test_gradient_and_hessian_finite_at_vertices_edges_centroid(which, box_object, cylinder_object,
                                                                 banana_small):
    obj = {"box": box_object, "cylinder": cylinder_object, "banana": banana_small}[which]
    p = ca.SX.sym("p", 3)
    d = obj.signed_distance_function()(p)
    H, g = ca.hessian(d, p)
    fgh = ca.Function("fgh", [p], [d, g, H])
    for x in _special_points(obj):
        for out in fgh(x):
            assert np.all(np.isfinite(np.asarray(out))), (which, x)


@pytest.mark.parametrize("which", ["box", "cylinder", "banana"])
def test_gradient_matches_central_differences(which, box_object, cylinder_object, banana_small):
    obj = {"box": box_object, "cylinder": cylinder_object, "banana": banana_small}[which]
    tau = 2e-3  # a larger temperature keeps the curvature small enough for finite differences
    f = obj.signed_distance_function(tau)
    p = ca.SX.sym("p", 3)
    fg = ca.Function("fg", [p], [ca.gradient(f(p), p)])
    rng = np.random.default_rng(0)
    lo, hi = obj.mesh.bounds
    h = 1e-6
    for x in rng.uniform(lo - 0.02, hi + 0.02, size=(20, 3)):
        fd = [(float(f(x + h * e)) - float(f(x - h * e))) / (2 * h) for e in np.eye(3)]
        np.testing.assert_allclose(np.asarray(fg(x)).ravel(), fd, atol=1e-5)


def _assert_gradient_matches_central_differences(d_expr: ca.SX, p: ca.SX, x: np.ndarray, h: float = 1e-7):
    """CasADi's jacobian of the scalar `d_expr` w.r.t. `p` (3,) at `x` against central differences of its
    value (step h, m); the third derivative ≲ 1/τ² bounds the difference error by ≈ h²/(6τ²)."""
    f = ca.Function("f", [p], [d_expr, ca.jacobian(d_expr, p)])
    fd = [(float(f(x + h * e)[0]) - float(f(x - h * e)[0])) / (2 * h) for e in np.eye(3)]
    np.testing.assert_allclose(np.asarray(f(x)[1]).ravel(), fd, atol=2e-6)


_NLP_DISTANCES = ["full", "full_grasp_gen", "coarse", "local", "hull"]


@settings(max_examples=40, deadline=None)
@given(which=st.sampled_from(_NLP_DISTANCES), shape=st.sampled_from(["box", "cylinder", "banana", "hull"]),
       seed=st.integers(0, 10_000), offset=st.floats(-0.005, 0.03))
def test_every_nlp_distance_has_the_gradient_of_its_finite_differences(
        box_object, cylinder_object, banana_small, which, shape, seed, offset):
    """At the temperatures the NLPs use, near the surface (where the tip and link spheres are)."""
    obj = {"box": box_object, "cylinder": cylinder_object, "banana": banana_small}.get(shape) or \
        ObjectModel.from_trimesh(random_hull(seed), convex=True)
    pts, normals = obj.sample_surface(1, seed=seed)
    x = pts[0] + offset * normals[0]
    p = ca.SX.sym("p", 3)
    if which == "full":
        d = obj.signed_distance_function()(p)
    elif which == "full_grasp_gen":
        d = obj.signed_distance_function(GRASP_GEN_TAU)(p)
    elif which == "coarse":
        d = obj.clearance_distance_function(16)(p)
    elif which == "local":
        n_local = min(LOCAL_PIECES, len(obj.pieces))
        N, H = obj.local_planes(x + 0.003, n_local)  # selected near, not at, the point
        d = local_signed_distance(ca.DM(N.ravel()), ca.DM(H.ravel()), p, n_local, TAU)
    else:  # a workspace-hull-like polytope: the object's first piece, scaled up to a 20 cm reach
        pc = obj.pieces[0]
        d = hull_signed_distance(pc.normals, pc.offsets * 4.0, p, HULL_TAU)
        x = 4.0 * x
    _assert_gradient_matches_central_differences(d, p, x)


# ---------------------------------------------------------------- function names
@pytest.mark.parametrize("name", ["sugar-box", "my box", "sügar", "2v", "a__b", "_x_", "-"])
def test_object_names_that_are_not_identifiers_build_distance_functions(name, box_object):
    obj = ObjectModel(name, box_object.mesh, box_object.pieces, box_object.spec)
    x = np.array([0.0, 0.0, 0.1])
    assert float(obj.signed_distance_function()(x)) == float(box_object.signed_distance_function()(x))
    assert float(obj.clearance_distance_function()(x)) == float(box_object.clearance_distance_function()(x))
    assert obj.signed_distance([x])[0] == box_object.signed_distance([x])[0]


@settings(max_examples=100, deadline=None)
@given(parts=st.lists(st.text(max_size=12), min_size=1, max_size=3))
def test_function_name_is_always_a_valid_casadi_name(parts):
    x = ca.SX.sym("x")
    name = function_name(*parts)
    assert ca.Function(name, [x], [x]).name() == name


def test_function_name_keeps_valid_names_and_replaces_the_rest():
    assert function_name("sd", "box") == "sd_box"
    assert function_name("sd", "sugar-box") == "sd_sugar_box"
    assert function_name("sd", "my box") == "sd_my_box"
    assert function_name("sd", "sügar") == "sd_s_gar"
    assert function_name("2v") == "f2v"
    assert signed_distance.function_name("sd_coarse", "004_sugar_box") == "sd_coarse_004_sugar_box"


def test_pieces_distance_function_rejects_an_unknown_symbolic_type(box_object):
    with pytest.raises(ValueError, match="SX"):
        signed_distance.pieces_distance_function("sd", box_object.pieces, TAU, symbolic="DM")
