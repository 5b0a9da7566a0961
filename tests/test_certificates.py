"""Stability certificates (force closure, gravity hold) against closed forms and against each other.

Conventions: contacts and outward normals in the object frame; a contact force on the object is
f = −a n + tangential, a ∈ [0, F_max] and ‖tangential‖ ≤ μ a.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import twofinger as tf

from regrasp_casadi.certificates import (
    GRAVITY,
    Certificate,
    GravityHold,
    certify_step,
    force_closure_certificate,
    force_closure_lp_margin,
    gravity_certificate,
    object_mass,
    step_certificates,
)
from regrasp_casadi.plan import Plan, PlanStep
from regrasp_casadi.stability import force_closure_quality, primitive_wrenches

TETRA = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float) / np.sqrt(3)
# four pinch contacts on the x = ±3 cm faces of a box, spread along y and z
PINCHES = np.array([[0.03, 0.02, 0.02], [0.03, -0.02, -0.02], [-0.03, 0.02, -0.02], [-0.03, -0.02, 0.02]])
PINCH_NORMALS = np.sign(PINCHES[:, :1]) * np.array([[1.0, 0.0, 0.0]])


def _antipodal(theta: float):
    """Contacts at x = ±3 cm whose (parallel, opposite) normals are tilted by theta from the x axis."""
    n1 = np.array([np.cos(theta), 0.0, np.sin(theta)])
    return np.array([[0.03, 0.0, 0.0], [-0.03, 0.0, 0.0]]), np.array([n1, -n1])


def _triangle_on_bottom(h: float = 0.02, r: float = 0.02):
    """Three contacts in an equilateral triangle (circumradius r) on the face z = −h, outward normal −z."""
    phi = 2 * np.pi * np.arange(3) / 3
    c = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(3, -h)])
    return c, np.tile([0.0, 0.0, -1.0], (3, 1))


# ------------------------------------------------------------------------------------ force closure
@pytest.mark.parametrize("theta", [0.0, 0.3, 0.6])
def test_two_antipodal_point_contacts_are_never_force_closure(theta):
    # point contacts cannot resist a torque about the line through them, inside or outside the cones
    c, n = _antipodal(theta)
    cert = force_closure_certificate(c, n, mu=0.5, center=np.zeros(3), length=0.03)
    assert not cert.ok
    assert cert.margin <= 0.0
    assert force_closure_lp_margin(primitive_wrenches(c, n, 0.5, np.zeros(3), 0.03)) < 1e-9


def test_contacts_on_one_face_are_not_force_closure():
    c, n = _triangle_on_bottom()
    cert = force_closure_certificate(c, n, mu=0.5, center=np.zeros(3), length=0.03)
    assert not cert.ok and cert.margin <= 0.0


@pytest.mark.parametrize("contacts, normals", [(0.03 * TETRA, TETRA), (PINCHES, PINCH_NORMALS)])
def test_four_frictional_contacts_are_force_closure_and_lose_it_without_friction(contacts, normals):
    cert = force_closure_certificate(contacts, normals, mu=0.5, center=np.zeros(3), length=0.03)
    assert cert.ok and cert.margin > 0.01
    # frictionless, four contacts never are (a 3-D object needs at least seven); sliding = frictionless
    assert not force_closure_certificate(contacts, normals, mu=0.0, center=np.zeros(3), length=0.03).ok
    slide_all = force_closure_certificate(contacts, normals, 0.5, np.zeros(3), 0.03, sliding=np.ones(4, bool))
    assert not slide_all.ok


def test_lp_margin_agrees_with_and_brackets_ferrari_canny_on_random_grasps():
    # the LP's s = min over the 12 ± unit wrench directions satisfies s/√6 ≤ ε ≤ s inside, s = 0 outside
    rng = np.random.default_rng(7)
    positives = negatives = 0
    for _ in range(80):
        m = int(rng.integers(3, 6))
        n = rng.normal(size=(m, 3))
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        c = 0.03 * n + 0.003 * rng.normal(size=(m, 3))
        mu = rng.uniform(0.2, 0.9, m)
        sliding = rng.random(m) < 0.2
        eps = force_closure_quality(c, n, np.where(sliding, 0.0, mu), np.zeros(3), 0.03)
        s = force_closure_lp_margin(primitive_wrenches(c, n, np.where(sliding, 0.0, mu), np.zeros(3), 0.03))
        cert = force_closure_certificate(c, n, mu, np.zeros(3), 0.03, sliding=sliding)
        assert cert.margin == eps
        if abs(eps) > 1e-6:
            assert cert.ok == (eps > 0)
        if eps > 1e-6:
            positives += 1
            assert s / np.sqrt(6) - 1e-7 <= eps <= s + 1e-7
        elif eps < -1e-6:
            negatives += 1
            assert s < 1e-6
    assert positives >= 10 and negatives >= 10


# ------------------------------------------------------------------------------------ gravity hold
@pytest.mark.parametrize("theta", [0.0, 0.2, 0.45, 0.6])
@pytest.mark.parametrize("f_max", [10.0, 25.0])
def test_antipodal_pinch_holds_a_tangential_weight_by_the_closed_form(theta, f_max):
    # weight m g along y ⊥ the tilt plane: f_i = ∓P x̂ + (m g/2) ŷ with normal force P cos θ, tangential
    # √(P² sin²θ + (m g/2)²) ≤ μ P cos θ  ⇒  largest scale s = 2 F √(μ² − tan²θ) / (m g) (0 if tan θ ≥ μ)
    mass, mu = 2.0, 0.5
    c, n = _antipodal(theta)
    hold = GravityHold(c, n, weight=np.array([0.0, -mass * GRAVITY, 0.0]), center=np.zeros(3), mu=mu,
                       max_normal_force=f_max)
    cert = gravity_certificate(hold, solver="socp")
    s = 2 * f_max * np.sqrt(max(mu**2 - np.tan(theta) ** 2, 0.0)) / (mass * GRAVITY)
    assert cert.margin == pytest.approx(s, abs=1e-6)
    assert cert.ok == (s >= 1.0)
    if theta == 0.0:  # 2 kg needs m g / (2 μ) = 19.6 N per finger: not with 10 N, with 25 N
        assert cert.ok == (f_max == 25.0)
    if np.tan(theta) >= mu:  # the line of the contacts outside the cones: no squeeze holds anything
        assert not cert.ok and cert.margin == pytest.approx(0.0, abs=1e-6)


def test_antipodal_least_norm_forces_are_the_closed_form():
    mass, mu = 2.0, 0.5
    c, n = _antipodal(0.0)
    cert = gravity_certificate(GravityHold(c, n, np.array([0.0, -mass * GRAVITY, 0.0]), np.zeros(3), mu,
                                           25.0))
    a = mass * GRAVITY / (2 * mu)  # 19.62 N: the least squeeze that carries m g / 2 by friction
    np.testing.assert_allclose(cert.forces, [[-a, mass * GRAVITY / 2, 0.0], [a, mass * GRAVITY / 2, 0.0]],
                               atol=1e-5)


@pytest.mark.parametrize("tau_max, solvers",
                         [(0.05, ("socp", "lp")), (0.2, ("socp", "lp")), (1.0, ("socp",))])
def test_joint_torque_bounds_the_pinch_by_the_closed_form(tau_max, solvers):
    """The pinch of a 0.2 kg weight along y (normals ±x), each finger with two joints: τ₁ = L f_y (the
    lever of the carried weight, L = 10 cm) and τ₂ = L₂ f_x (the squeeze's, L₂ = 2 cm). Each finger carries
    s m g / 2 along y and squeezes at least that / μ, so the largest scale is
    s = min(2 τ / (L m g), 2 μ τ / (L₂ m g), 2 μ F / (m g)); held iff s ≥ 1, the forces' torques within τ."""
    mass, mu, f_max, L, L2 = 0.2, 0.5, 10.0, 0.1, 0.02
    c, n = _antipodal(0.0)
    maps = np.array([[[0.0, L, 0.0], [L2, 0.0, 0.0]]] * 2)
    hold = GravityHold(c, n, weight=np.array([0.0, -mass * GRAVITY, 0.0]), center=np.zeros(3), mu=mu,
                       max_normal_force=f_max, torque_maps=maps, max_joint_torque=tau_max)
    mg = mass * GRAVITY
    s = min(2 * tau_max / (L * mg), 2 * mu * tau_max / (L2 * mg), 2 * mu * f_max / mg)
    for solver in solvers:
        cert = gravity_certificate(hold, solver=solver)
        assert cert.margin == pytest.approx(s, rel=1e-5), solver
        assert cert.ok == (s >= 1.0)
        if cert.ok:
            assert np.max(np.abs(hold.joint_torques(cert.forces))) <= tau_max + 1e-7
            assert hold.violation(cert.forces) <= 1e-6
    # without the bound the friction and the normal-force bound alone decide
    free = gravity_certificate(GravityHold(c, n, hold.weight, np.zeros(3), mu, f_max), solver="socp")
    assert free.margin == pytest.approx(2 * mu * f_max / mg, rel=1e-5)


def test_three_contacts_under_the_object_carry_a_third_each():
    mass = 0.3
    c, n = _triangle_on_bottom(h=0.02)
    cert = gravity_certificate(GravityHold(c, n, np.array([0.0, 0.0, -mass * GRAVITY]), np.zeros(3), 0.5,
                                           10.0))
    assert cert.ok
    np.testing.assert_allclose(cert.forces, np.tile([0.0, 0.0, mass * GRAVITY / 3], (3, 1)), atol=1e-6)
    assert cert.margin == pytest.approx(3 * 10.0 / (mass * GRAVITY), rel=1e-6)
    # the fingers cannot pull: a weight away from them, or along the face, cannot be held
    for w in ([0.0, 0.0, mass * GRAVITY], [mass * GRAVITY, 0.0, 0.0]):
        away = gravity_certificate(GravityHold(c, n, np.array(w), np.zeros(3), 0.5, 10.0))
        assert not away.ok and away.forces is None and away.margin == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("solver", ["socp", "lp"])
def test_least_normal_force_rejects_a_support_that_tips_over_one_finger(solver):
    # centre of mass in the contact plane at barycentric (0.6, 0.3, 0.1) of the three contacts: statics
    # alone fixes the normal forces at λ_i m g (tangential forces in the plane make no torque about
    # in-plane axes), so a least normal force f_min holds iff f_min ≤ 0.1 m g; the weight scale does not
    # depend on it
    mass = 0.2
    c, n = _triangle_on_bottom(h=0.0)
    lam = np.array([0.6, 0.3, 0.1])
    weight = np.array([0.0, 0.0, -mass * GRAVITY])
    plain = gravity_certificate(GravityHold(c, n, weight, lam @ c, 0.5, 10.0), solver=solver)
    assert plain.ok
    np.testing.assert_allclose(-plain.forces @ n[0], lam * mass * GRAVITY, atol=1e-5)
    low = gravity_certificate(GravityHold(c, n, weight, lam @ c, 0.5, 10.0, min_normal_force=0.09 * mass
                                          * GRAVITY), solver=solver)
    assert low.ok and low.margin == pytest.approx(plain.margin, rel=1e-6)
    np.testing.assert_allclose(-low.forces @ n[0], lam * mass * GRAVITY, atol=1e-5)
    f_min = 0.11 * mass * GRAVITY
    high = gravity_certificate(GravityHold(c, n, weight, lam @ c, 0.5, 10.0, min_normal_force=f_min),
                               solver=solver)
    assert not high.ok and high.forces is None and high.margin == pytest.approx(plain.margin, rel=1e-6)
    assert f"not with every normal force ≥ {f_min:g} N" in high.detail
    # the plain forces violate the stricter hold by the missing 0.01 m g on the third finger
    assert GravityHold(c, n, weight, lam @ c, 0.5, 10.0, min_normal_force=f_min).violation(
        plain.forces) == pytest.approx(0.01 * mass * GRAVITY, abs=1e-5)


@pytest.mark.parametrize("alpha", [0.0, 0.3, 0.6])
@pytest.mark.parametrize("mu, sliding", [(0.5, False), (0.5, True), (0.8, False)])
def test_tray_holds_a_tilted_weight_iff_tan_alpha_within_mu(alpha, mu, sliding):
    # centre of mass in the contact plane: normal forces m g cos α / 3 each, total friction capacity μ Σ a,
    # so the largest scale is 3 F / (m g cos α) if tan α ≤ μ_effective (0 when the fingers slide) else 0
    mass, f_max = 0.5, 10.0
    c, n = _triangle_on_bottom(h=0.0)
    weight = mass * GRAVITY * np.array([np.sin(alpha), 0.0, -np.cos(alpha)])
    cert = gravity_certificate(GravityHold(c, n, weight, np.zeros(3), mu, f_max, np.full(3, sliding)))
    mu_eff = 0.0 if sliding else mu
    s = 3 * f_max / (mass * GRAVITY * np.cos(alpha)) if np.tan(alpha) <= mu_eff else 0.0
    assert cert.margin == pytest.approx(s, abs=1e-6)
    assert cert.ok == (s >= 1.0)


def test_a_sliding_contact_adds_no_tangential_force():
    mass = 0.1
    c, n = 0.03 * TETRA, TETRA
    rng = np.random.default_rng(1)
    for _ in range(5):
        g = rng.normal(size=3)
        g *= GRAVITY / np.linalg.norm(g)
        sliding = np.array([True, False, False, False])
        hold = GravityHold(c, n, mass * g, np.zeros(3), 0.8, 10.0, sliding)
        cert = gravity_certificate(hold)
        assert cert.ok
        f0 = cert.forces[0]
        assert np.linalg.norm(f0 - np.dot(f0, n[0]) * n[0]) <= 1e-9
        assert np.dot(f0, n[0]) <= 1e-9  # pushes, never pulls
        assert hold.violation(cert.forces) < 1e-6


def test_linearised_lp_fallback_is_bracketed_by_the_exact_cones():
    # 8 edges on the cone: the inscribed polygon has inradius μ cos(π/8), so
    # SOCP(μ cos π/8) ≤ LP(μ) ≤ SOCP(μ) for the largest holdable scale
    rng = np.random.default_rng(2)
    checked = 0
    for _ in range(20):
        n = rng.normal(size=(3, 3))
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        c, com = 0.03 * n, 0.005 * rng.normal(size=3)
        weight = 0.2 * GRAVITY * rng.normal(size=3) / np.sqrt(3)
        hold = GravityHold(c, n, weight, com, 0.6, 10.0)
        lp = gravity_certificate(hold, solver="lp")
        hi = gravity_certificate(hold, solver="socp")
        lo = gravity_certificate(GravityHold(c, n, weight, com, 0.6 * np.cos(np.pi / 8), 10.0), solver="socp")
        assert lo.margin - 1e-6 <= lp.margin <= hi.margin + 1e-6
        checked += lp.margin > 1e-3
        if lp.ok:
            assert hold.violation(lp.forces) < 1e-6
    assert checked >= 5


def test_socp_forces_are_a_checkable_certificate():
    rng = np.random.default_rng(4)
    held = 0
    for _ in range(20):
        n = rng.normal(size=(4, 3))
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        c, com = 0.03 * n, 0.003 * rng.normal(size=3)
        weight = 0.3 * GRAVITY * rng.normal(size=3) / np.sqrt(3)
        hold = GravityHold(c, n, weight, com, 0.5, 10.0)
        cert = gravity_certificate(hold)
        if cert.ok:
            held += 1
            assert cert.margin >= 1.0
            assert hold.violation(cert.forces) < 1e-6
            # the same forces do not hold twice the weight
            assert GravityHold(c, n, 2 * weight, com, 0.5, 10.0).violation(cert.forces) > 1.0
    assert held >= 5


# ------------------------------------------------------------------------------------ mass, records, steps
def test_object_mass_from_mesh_volume_or_given():
    box = tf.make_box()  # 0.06 × 0.04 × 0.04 m
    assert object_mass(box.mesh) == pytest.approx(0.06 * 0.04 * 0.04 * 500.0, rel=1e-9)
    assert object_mass(box.mesh, density=1000.0) == pytest.approx(0.096, rel=1e-9)
    assert object_mass(box.mesh, mass=0.514) == 0.514
    with pytest.raises(ValueError, match="mass"):
        object_mass(box.mesh, mass=0.0)


def test_certificate_round_trips_through_strict_json():
    c, n = _antipodal(0.0)
    held = gravity_certificate(GravityHold(c, n, np.array([0.0, -2 * GRAVITY, 0.0]), np.zeros(3), 0.5,
                                           25.0))
    nan = Certificate("force_closure", False, float("nan"), None, "solver failed")
    for cert in (held, nan, force_closure_certificate(PINCHES, PINCH_NORMALS, 0.5)):
        text = json.dumps(cert.to_dict(), allow_nan=False)
        assert Certificate.from_dict(json.loads(text)) == cert


def test_certify_step_holds_with_the_masked_fingers_only():
    c, n = np.vstack([PINCHES, [[0.0, 0.05, 0.0]]]), np.vstack([PINCH_NORMALS, [[0.0, 1.0, 0.0]]])
    mask = np.array([True, True, True, True, False])
    g = np.array([0.0, 0.0, -GRAVITY])
    cert = certify_step(c, n, mask, "gravity", 0.5, 0.2, g, center=np.zeros(3))
    assert cert.ok and cert.forces.shape == (5, 3)
    assert np.all(cert.forces[4] == 0.0)
    assert GravityHold(c[:4], n[:4], 0.2 * g, np.zeros(3)).violation(cert.forces[:4]) < 1e-6
    # the fifth contact alone pushes along −y and cannot hold anything
    alone = certify_step(c, n, ~mask, "gravity", 0.5, 0.2, g, center=np.zeros(3))
    assert not alone.ok
    assert certify_step(c, n, mask, "force_closure", 0.5).ok
    assert not certify_step(c, n, ~mask, "force_closure", 0.5).ok
    with pytest.raises(ValueError, match="mass"):
        certify_step(c, n, mask, "gravity", 0.5)


def _twofinger_plan(hand, obj):
    """initial pinch → gait of the left finger (−5 mm along its axis) → final; box contacts clipped."""
    half = np.array(tf.BOX_EXTENTS) / 2
    q0, q1 = np.zeros(hand.n_joints), np.zeros(hand.n_joints)
    q1[hand.joint_names.index("left_slide")] = -0.005
    steps = []
    for kind, finger, q in [("initial", None, q0), ("gait", "left", q1), ("final", None, q1)]:
        T = tf.box_pose()
        c = np.clip((hand.tip_positions(q) - T[:3, 3]) @ T[:3, :3], -half, half)
        steps.append(PlanStep(kind, finger, q, T, c, np.zeros(2), "", 0.0))
    return Plan(steps=tuple(steps), goal_contacts_object=steps[-1].contacts_object,
                goal_T_palm_object=tf.box_pose(), fingers=tuple(hand.fingers), hand_spec=hand.spec(),
                object_spec=obj.spec, method="svd", status="converged", status_detail="", iterations=1,
                iteration_errors=np.zeros(2), timing={"total": 0.0}, options={})


def test_step_certificates_of_a_two_finger_pinch(tmp_path):
    # the box (48 g at 500 kg/m³) is pinched along x at its centre's height; gravity along −z of the palm
    # is tangential to both contacts: held iff F ≥ m g / (2 μ), scale 2 μ F / (m g); a lone finger cannot
    hand, obj = tf.make_hand(tmp_path), tf.make_box()
    plan = _twofinger_plan(hand, obj)
    grav = step_certificates(plan, obj, "gravity", 0.5, hand=hand)
    m_g = object_mass(obj.mesh) * GRAVITY
    assert [cert.ok for cert in grav] == [True, False, True]
    assert grav[0].margin == pytest.approx(2 * 0.5 * 10.0 / m_g, rel=1e-6)
    np.testing.assert_allclose(grav[0].forces[:, 2], [m_g / 2, m_g / 2], atol=1e-6)
    fc = step_certificates(plan, None, "force_closure", 0.5)  # models rebuilt from the plan's specs
    assert not any(cert.ok for cert in fc)  # two point contacts never are
