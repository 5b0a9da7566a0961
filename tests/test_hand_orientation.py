"""The hand's orientation for gravity-certified regrasps (`hand_orientation`): the opposing finger, the
supporting gravity, and a certified plan that moves the thumb where force closure cannot."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from regrasp_casadi.hand_orientation import opposing_finger, supporting_gravity
from regrasp_casadi.problem import RegraspProblem

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"


@pytest.fixture(scope="module")
def box_shift():
    return RegraspProblem.load(PROBLEMS / "box_shift.yaml")


def test_the_thumb_opposes_three_fingers_on_the_box(box_shift):
    """box_shift's initial grasp: index, middle and ring on the box's +y face, the thumb on −y (the
    contacts' coordinates against the box's half extent, 0.035 m)."""
    g0 = box_shift.grasp0
    y = np.asarray(g0.contacts_object)[:, 1]
    np.testing.assert_allclose(np.abs(y), 0.035, atol=1e-4)
    assert opposing_finger(g0) == "thumb"
    assert y[list(box_shift.hand.fingers).index("thumb")] < 0 < y[:3].min()


def test_supporting_gravity_presses_the_box_onto_the_fingers(box_shift):
    """In the object frame the supporting gravity points along +y, into the fingers' face (their pushes,
    along −y, carry the weight), with magnitude g; `finger` and `g` are checked."""
    g0 = box_shift.grasp0
    g_palm = supporting_gravity(g0, g=9.81)
    g_object = np.asarray(g0.T_palm_object)[:3, :3].T @ g_palm
    np.testing.assert_allclose(g_object, [0.0, 9.81, 0.0], atol=1e-9)
    with pytest.raises(ValueError, match="pinky"):
        supporting_gravity(g0, finger="pinky")
    with pytest.raises(ValueError, match="positive"):
        supporting_gravity(g0, g=0.0)


@pytest.mark.slow  # 24 s in the default run (2026-12-03): over the suite's 10-minute budget
def test_supporting_gravity_lets_the_certified_planner_move_the_thumb(box_shift):
    """With force closure the thumb cannot leave its contact (it alone opposes the other three); with the
    gravity certificate and the supporting gravity, the plan converges, `verify` (its own tolerances and
    certificate) passes, and the thumb reaches its goal contact 31 mm away."""
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.verify import verify

    g0, goal = box_shift.grasp0, box_shift.grasp_goal
    thumb = list(box_shift.hand.fingers).index("thumb")
    start = float(np.linalg.norm(g0.contacts_object[thumb] - goal.contacts_object[thumb]))
    plan = plan_regrasp(g0, goal, stability="gravity", gravity_palm=tuple(supporting_gravity(g0)),
                        object_mass=box_shift.object_mass)
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok
    assert start > 0.03 and plan.steps[-1].contact_error[thumb] <= plan.options["zeta"]


def test_the_stall_hint_names_a_lone_opposing_thumb(box_shift):
    """`pinned_opposer_hint`: the thumb 20 mm from its goal, alone on the −y face, gets the hint; no hint
    once it is within ζ, nor when another finger shares its face (it could take over)."""
    from types import SimpleNamespace

    from regrasp_casadi.hand_orientation import pinned_opposer_hint

    fingers = list(box_shift.hand.fingers)
    contacts = np.array(box_shift.grasp0.contacts_object)
    thumb = fingers.index("thumb")
    error = np.zeros(len(fingers))
    error[thumb] = 0.02
    step = SimpleNamespace(contacts_object=contacts, contact_error=error)
    hint = pinned_opposer_hint(box_shift.obj, fingers, step, 0.004)
    assert "the thumb (20.0 mm from its goal) alone opposes" in hint and "supporting_gravity" in hint
    arrived = SimpleNamespace(contacts_object=contacts, contact_error=np.full(len(fingers), 0.003))
    assert pinned_opposer_hint(box_shift.obj, fingers, arrived, 0.004) == ""
    shared = contacts.copy()
    shared[fingers.index("ring")] = contacts[thumb] + [0.0, 0.0, 0.03]  # the ring on the thumb's face
    ring_sd = box_shift.obj.exact_signed_distance(shared[fingers.index("ring")][None])[0]
    assert ring_sd == pytest.approx(0.0, abs=1e-9)  # still on the surface
    step = SimpleNamespace(contacts_object=shared, contact_error=error)
    assert pinned_opposer_hint(box_shift.obj, fingers, step, 0.004) == ""


@pytest.mark.slow  # a 26-31 s plan: the default run stays within its 10 minutes (measured 590 s with it)
def test_a_load_share_keeps_every_holding_finger_pressing():
    """`HoldingOptions.min_load_share`: in every certified step of a gravity plan of box_rotate (supporting
    gravity, μ 0.4, ≤ 3 N per finger), each holding finger's normal force in the stored certificate is at
    least share · m g / k (k holding fingers), recomputed here from the forces and the exact contact
    normals of the plan's tip positions; verify (its own certificate) passes."""
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.verify import verify

    problem = RegraspProblem.load(PROBLEMS / "box_rotate.yaml")
    g0, share = problem.grasp0, 0.5
    g_palm = supporting_gravity(g0)
    mass = problem.object_mass or problem.obj.mesh.volume * 500.0
    plan = plan_regrasp(g0, problem.grasp_goal, stability="gravity", gravity_palm=tuple(g_palm),
                        object_mass=problem.object_mass, mu=0.4, max_normal_force=3.0, min_load_share=share)
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok
    fingers, checked = list(plan.fingers), 0
    for step in plan.steps:
        if step.kind == "slide":  # the slider's certificate normal is tilted by its drag
            continue
        T = np.asarray(step.T_palm_object)
        tips = (problem.hand.tip_positions(step.q) - T[:3, 3]) @ T[:3, :3]
        contacts, _ = problem.obj.closest_points(tips)
        normals = (tips - contacts) / np.linalg.norm(tips - contacts, axis=1, keepdims=True)
        holding = [f != step.finger for f in fingers] if step.kind == "gait" else [True] * len(fingers)
        forces = np.asarray(step.certificate["forces"], float)
        pressing = -np.sum(forces * normals, axis=1)[holding]
        assert step.certificate["ok"]
        assert pressing.min() >= share * mass * np.linalg.norm(g_palm) / sum(holding) - 1e-5, step.kind
        checked += step.kind == "gait"
    assert checked > 0


def test_a_slide_held_only_by_its_drag_is_refused_with_the_drag_range():
    """On the flat tool under the supporting gravity, the index finger's slide (along a tangent of its
    contact) is held only because its kinetic friction μ_k f_n drags the tool the right way: pushing along
    its normal alone (no drag, as at the slide's start and end) the others cannot hold the tool.
    `HoldingOptions.slide_drag_range` certifies the slide for every drag from none to μ_k f_n, so it is
    refused there, and its certificate is the frictionless slide's, recomputed by `certify_step`."""
    from regrasp_casadi.certificates import certify_step
    from regrasp_casadi.holding import Holding, HoldingOptions
    from regrasp_casadi.stability import tangent_basis

    problem = RegraspProblem.load(PROBLEMS / "flat_tool_regrasp.yaml")
    g0 = problem.grasp0
    g_palm = supporting_gravity(g0)
    q, T = g0.q, np.asarray(g0.T_palm_object)
    plain, ranged = (Holding(problem.hand, problem.obj, "gravity",  # no joint torque bound: the drag alone
                             HoldingOptions(mu=0.4, slide_drag_range=r, max_joint_torque=None),
                             problem.object_mass, g_palm) for r in (False, True))
    contacts, normals = plain.contacts(q, T)
    k = list(problem.hand.fingers).index("index")
    t1, t2 = tangent_basis(normals[k])
    direction = np.cos(np.pi / 4) * t1 + np.sin(np.pi / 4) * t2
    assert plain.certified(plain.slide(q, T, "index", direction))
    cert = ranged.slide(q, T, "index", direction)
    assert not ranged.certified(cert)
    sliding = np.arange(len(contacts)) == k
    mass = problem.object_mass or problem.obj.mesh.volume * 500.0
    still = certify_step(contacts, normals, np.ones(len(contacts), bool), "gravity", 0.4, mass,
                         T[:3, :3].T @ g_palm, center=problem.obj.mesh.center_mass, sliding=sliding)
    assert cert.margin == pytest.approx(still.margin, abs=1e-6) and still.margin < 1.0


@pytest.mark.parametrize("tau_max", [None, 0.56, 0.01])
def test_gravity_certificate_keeps_the_joint_torques_within_the_bound(tau_max):
    """The flat tool's grasp0 under the supporting gravity: the certificate's forces, mapped to joint
    torques by finite differences of the tips' forward kinematics (τ = Jᵀ R f, independent of the
    CasADi Jacobian), stay within `max_joint_torque`. Without a bound the least-norm forces need up to
    0.021 N·m (measured), so 0.56 N·m changes nothing, and 0.01 N·m holds at most about half the weight
    of the 0.049 kg tool (mesh volume × 500 kg/m³): not certified."""
    from regrasp_casadi.holding import Holding, HoldingOptions

    problem = RegraspProblem.load(PROBLEMS / "flat_tool_regrasp.yaml")
    g0, hand = problem.grasp0, problem.hand
    q, T = np.asarray(g0.q, float), np.asarray(g0.T_palm_object)
    holding = Holding(hand, problem.obj, "gravity", HoldingOptions(mu=0.4, max_joint_torque=tau_max),
                      problem.object_mass, supporting_gravity(g0))
    cert = holding.grasp(q, T)
    J = np.zeros((len(hand.fingers), 3, hand.n_joints))
    for j in range(hand.n_joints):  # central differences of the tip centres, palm frame
        dq = np.zeros(hand.n_joints)
        dq[j] = 1e-6
        J[:, :, j] = (hand.tip_positions(q + dq) - hand.tip_positions(q - dq)) / 2e-6
    if tau_max == 0.01:
        assert not cert.ok and cert.margin < 1.0
        return
    assert cert.ok, cert.detail
    tau = np.einsum("fdj,fd->fj", J, cert.forces @ T[:3, :3].T)  # forces on the object, palm frame
    if tau_max is None:
        assert np.max(np.abs(tau)) > 0.01
        return
    assert np.max(np.abs(tau)) <= tau_max + 1e-6
    maps = holding.torque_maps(q, T)  # the certificate's own map: each finger's joints, object frame
    for i, f in enumerate(hand.fingers):
        idx = hand.finger_joints[f]
        np.testing.assert_allclose(maps[i, :len(idx)] @ cert.forces[i], tau[i, idx], atol=1e-7)
