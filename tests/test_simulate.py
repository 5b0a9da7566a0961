"""`regrasp simulate`: the MuJoCo model against the project's kinematics, the grip forces against statics,
and executed grasps and plans against physical expectations (held, dropped, followed)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation
from sim_plans import BOX_SHIFT, GRAVITY_DOWN, lifted, make_plan

from regrasp_casadi.mujoco_model import OBJECT_BODY, SimOptions, build_model
from regrasp_casadi.sim_control import (
    CONTROL_DT,
    grip_forces,
    joint_commands,
    plan_motion,
    step_contacts,
    step_end_times,
)
from regrasp_casadi.simulate import simulate
from regrasp_casadi.transforms import log_SO3


@pytest.fixture(scope="module")
def box_problem():
    from regrasp_casadi import RegraspProblem

    return RegraspProblem.load(BOX_SHIFT)


# ------------------------------------------------------------------------------------------ the model
def test_model_kinematics_equal_the_project_fk(hand, box_problem):
    """MuJoCo's own forward kinematics (mj_kinematics) of the MjSpec model vs the project's CasADi FK:
    every body pose, every joint axis (from FK finite differences), every collision sphere, the limits."""
    palm_wxyz = (np.cos(0.4), np.sin(0.4) * 0.6, 0.0, np.sin(0.4) * 0.8)
    sim = build_model(hand, box_problem.obj, SimOptions(palm_wxyz=palm_wxyz))
    model, data = sim.model, mujoco.MjData(sim.model)
    R_world_palm = SimOptions(palm_wxyz=palm_wxyz).R_world_palm
    labels = hand.sphere_labels(None, include_tip=True)
    radii = hand.sphere_radii(None, include_tip=True)
    np.testing.assert_array_equal(model.jnt_range[[model.joint(n).id for n in hand.joint_names]],
                                  np.column_stack([hand.q_lower, hand.q_upper]))
    rng = np.random.default_rng(0)
    for q in rng.uniform(hand.q_lower, hand.q_upper, size=(3, hand.n_joints)):
        data.qpos[sim.qpos_hand] = q
        mujoco.mj_kinematics(model, data)
        fk = hand.fk(q)
        for link, body in sim.body_link.items():
            np.testing.assert_allclose(data.xpos[body], R_world_palm @ fk[link][:3, 3], atol=1e-6)
            np.testing.assert_allclose(data.xmat[body].reshape(3, 3), R_world_palm @ fk[link][:3, :3],
                                       atol=1e-6)
        for i, name in enumerate(hand.joint_names):
            h = 1e-5
            dq = np.zeros(hand.n_joints)
            dq[i] = h
            child = model.body(model.jnt_bodyid[model.joint(name).id]).name
            R_plus, R_minus = hand.fk(q + dq)[child][:3, :3], hand.fk(q - dq)[child][:3, :3]
            axis_palm = log_SO3(R_plus @ R_minus.T) / (2 * h)
            np.testing.assert_allclose(data.xaxis[model.joint(name).id], R_world_palm @ axis_palm, atol=1e-6)
        p_palm_spheres = hand.sphere_centers(q, None, include_tip=True)
        for label, p, r in zip(labels, p_palm_spheres, radii, strict=True):
            g = model.geom(("tip:" if label.endswith("#tip") else "sphere:") + label).id
            np.testing.assert_allclose(data.geom_xpos[g], R_world_palm @ p, atol=1e-6)
            assert model.geom_size[g, 0] == pytest.approx(r, abs=1e-12)


def test_object_body_mass_inertia_and_geometry(box_problem):
    """Box 0.05 × 0.07 × 0.12 m at 500 kg/m³: mass and principal inertia against the closed-form box
    formulas; the compiled convex mesh sits where the piece's vertices are (object frame)."""
    obj = box_problem.obj
    sim = build_model(box_problem.hand, obj, SimOptions())
    model, data = sim.model, mujoco.MjData(sim.model)
    a, b, c = 0.05, 0.07, 0.12
    m = a * b * c * 500.0
    body = model.body(OBJECT_BODY).id
    assert model.body_mass[body] == pytest.approx(m, rel=1e-9)
    expected = m / 12.0 * np.array([b**2 + c**2, a**2 + c**2, a**2 + b**2])
    np.testing.assert_allclose(np.sort(model.body_inertia[body]), np.sort(expected), rtol=1e-6)
    heavier = build_model(box_problem.hand, obj, SimOptions(object_mass=0.5))
    assert heavier.model.body_mass[body] == pytest.approx(0.5)
    mujoco.mj_forward(model, data)  # object at the world origin: body frame = object frame
    geoms = sorted(sim.object_geoms)
    assert len(geoms) == len(obj.pieces)
    for g, piece in zip(geoms, obj.pieces, strict=True):
        mesh = model.geom_dataid[g]
        v = model.mesh_vert[model.mesh_vertadr[mesh]:model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]]
        v_object = v @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        dist = np.linalg.norm(v_object[:, None] - np.asarray(piece.vertices)[None], axis=2)
        assert dist.min(axis=1).max() < 1e-6 and dist.min(axis=0).max() < 1e-6


def test_sim_options_reject_bad_values():
    with pytest.raises(ValueError, match="integrator"):
        SimOptions(integrator="verlet")
    with pytest.raises(ValueError, match="grip"):
        SimOptions(grip="magnets")
    with pytest.raises(ValueError, match="kp"):
        SimOptions(kp=0.0)


# ------------------------------------------------------------------------------------------ the motion
def test_plan_motion_passes_through_the_steps_at_the_joint_speed(hand, box_problem):
    g0 = box_problem.grasp0
    q1 = lifted(hand, box_problem.obj, g0.q, g0.T_palm_object, "index", 0.01)
    plan = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object),
                                         ("gait", "index", q1, g0.T_palm_object),
                                         ("gait", "index", g0.q, g0.T_palm_object)])
    dt = 1e-3
    t, q, T = plan_motion(plan, dt, joint_velocity=1.0, min_step_duration=0.2)
    t_end = step_end_times(plan, 1.0, 0.2)
    assert t[-1] == pytest.approx(t_end[-1]) and t_end[1] - t_end[0] >= 0.2 - 1e-12
    for i, te in enumerate(t_end):
        k = int(np.argmin(np.abs(t - te)))
        np.testing.assert_allclose(q[k], plan.steps[i].q, atol=1.0 * dt + 1e-12)
    assert np.abs(np.diff(q, axis=0)).max() / dt <= 1.0 + 1e-9
    np.testing.assert_allclose(T, np.broadcast_to(g0.T_palm_object, T.shape), atol=1e-12)


# ------------------------------------------------------------------------------------------ grip forces
def test_grip_forces_balance_gravity_within_the_cones(hand, box_problem):
    """Statics of the LP's forces: Σf = −m g and Σ (p − c) × f = 0, normal ≥ grip_force, |f_t| ≤ μ f_n;
    the three fingers on one face (thumb lifted) cannot balance anything (residual > 0)."""
    g0 = box_problem.grasp0
    plan = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object)])
    contacts = step_contacts(plan, hand)[0]
    opts = SimOptions()
    mass, com = 0.21, np.zeros(3)
    g_object = g0.T_palm_object[:3, :3].T @ np.array(GRAVITY_DOWN)
    F, residual = grip_forces(contacts, contacts.touching, g_object, mass, com, opts)
    assert contacts.touching.all() and residual < 1e-6
    np.testing.assert_allclose(F.sum(axis=0), -mass * g_object, atol=1e-6)
    np.testing.assert_allclose(np.cross(contacts.p_object - com, F).sum(axis=0), 0.0, atol=1e-6)
    f_n = -np.einsum("ij,ij->i", F, contacts.n_object)
    f_t = np.linalg.norm(F + f_n[:, None] * contacts.n_object, axis=1)
    assert (f_n >= opts.grip_force - 1e-9).all()
    assert (f_t <= opts.grip_friction_fraction * opts.friction * f_n + 1e-9).all()
    # a sliding thumb (frictionless, as a slide step's certificate has it) pushes along its normal only
    k = list(plan.fingers).index("thumb")
    F_s, residual_s = grip_forces(contacts, contacts.touching, g_object, mass, com, opts, frictionless=k)
    np.testing.assert_allclose(np.cross(F_s[k], contacts.n_object[k]), 0.0, atol=1e-9)
    assert -F_s[k] @ contacts.n_object[k] >= opts.grip_force - 1e-9
    assert residual_s >= residual - 1e-9   # taking a finger's friction away cannot help the balance
    one_face = np.array([f != "thumb" for f in plan.fingers])
    _, residual_one_face = grip_forces(contacts, one_face, np.zeros(3), mass, com, opts)
    assert residual_one_face > opts.grip_force  # three ≥ 1 N pushes on one face, nothing opposes them


def test_a_sliding_fingers_kinetic_friction_is_balanced_or_reported(hand, box_problem):
    """A sliding thumb's force on the box is f_n (−n + μ ŝ) (its kinetic friction drags the box along its
    motion ŝ); the LP's forces balance the wrench up to the residual it reports (statics recomputed
    here); dragged at the full μ = 0.5 along the face, the three fingers opposite (friction 0.8 μ) cannot
    hold the box against it."""
    g0 = box_problem.grasp0
    plan = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object)])
    contacts = step_contacts(plan, hand)[0]
    opts, com = SimOptions(), np.zeros(3)
    k = list(plan.fingers).index("thumb")
    n = contacts.n_object[k]
    s = np.cross(n, [0.0, 0.0, 1.0])
    s /= np.linalg.norm(s)
    for mu in (0.1, 0.5):
        F, residual = grip_forces(contacts, contacts.touching, np.zeros(3), 0.2, com, opts, frictionless=k,
                                  drag=mu * s)
        np.testing.assert_allclose(np.cross(F[k], -n + mu * s), 0.0, atol=1e-9)
        assert -F[k] @ n >= opts.grip_force - 1e-9
        wrench = np.concatenate([F.sum(axis=0), np.cross(contacts.p_object - com, F).sum(axis=0) / 0.05])
        assert np.linalg.norm(wrench[:3]) + np.linalg.norm(wrench[3:]) <= residual + 1e-6
    assert residual > 0.5 * opts.grip_force, residual


def test_joint_commands_add_the_grip_and_the_lift_to_the_motion(hand, box_problem):
    """The commanded targets of a gait without a path (index lifted) under gravity, against the law of
    `sim_control` written per finger with `grip_forces` and the hand's tip Jacobians: at step 0 the
    plan's joints plus Σ Jᵀ R f / kp (f the LP's forces), and in mid-move the joints along the smoothstep
    plus Jᵀ R f_mid / kp of the three holding fingers plus the index's lift, J⁺ (h sin(π u) n) along its
    contact normal (palm frame)."""
    g0 = box_problem.grasp0
    q1 = lifted(hand, box_problem.obj, g0.q, g0.T_palm_object, "index", 0.01)
    plan = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object),
                                         ("gait", "index", q1, g0.T_palm_object)])
    opts, mass, com = SimOptions(gravity_palm=GRAVITY_DOWN), 0.21, np.zeros(3)
    cmd = joint_commands(plan, hand, opts, mass, com)
    t, q_cmd, _, q_grip0, _, q_start, holding = cmd[:7]
    contacts = step_contacts(plan, hand)
    R = g0.T_palm_object[:3, :3]
    g_object = R.T @ np.array(GRAVITY_DOWN)

    def expected(q, holding_rows, p_palm_lift=(0.0, 0.0, 0.0)):  # the index's tip raised by p_palm_lift, m
        F, _ = grip_forces(contacts[0], holding_rows, g_object, mass, com, opts)
        dq = sum(hand.tip_jacobian(q, f).T @ (R @ F[m]) / opts.kp for m, f in enumerate(plan.fingers))
        J = hand.tip_jacobian(q, "index")
        return q + dq + J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(3), np.asarray(p_palm_lift))

    np.testing.assert_allclose(q_grip0, expected(g0.q, contacts[0].touching), atol=1e-12)
    np.testing.assert_allclose(q_start, g0.q, atol=1e-15)  # no grip, no surface correction
    t_end = step_end_times(plan, opts.joint_velocity, opts.min_step_duration, opts.unload_fraction,
                           opts.min_handover_time)
    k = int(round(0.45 * t_end[1] / CONTROL_DT))  # mid-move: the index lifted, the others hold
    s = t[k] / t_end[1]
    u = (s - opts.unload_fraction) / (1.0 - 2.0 * opts.unload_fraction)
    row = list(plan.fingers).index("index")
    assert 0.0 < u < 1.0 and holding[k, row] == 0.0 and holding[k].sum() == 3.0
    q_smooth = g0.q + u * u * (3.0 - 2.0 * u) * (q1 - g0.q)
    n_index = (1 - s) * contacts[0].n_object[row] + s * contacts[1].n_object[row]
    p_palm_lift = opts.lift_height * np.sin(np.pi * u) * (R @ n_index) / np.linalg.norm(n_index)
    np.testing.assert_allclose(q_cmd[k], expected(q_smooth, holding[k] > 0, p_palm_lift), atol=1e-12)
    # the grip-force feedback's targets in mid-move: the LP's normal forces, the lifted index none
    F_mid, _ = grip_forces(contacts[0], holding[k] > 0, g_object, mass, com, opts)
    n_unit = (1 - s) * contacts[0].n_object + s * contacts[1].n_object
    n_unit /= np.linalg.norm(n_unit, axis=1, keepdims=True)
    np.testing.assert_allclose(cmd.press[k], -np.einsum("mi,mi->m", F_mid, n_unit), atol=1e-9)
    assert cmd.press[k, row] == 0.0 and np.all(cmd.press[k][holding[k] > 0] >= opts.grip_force - 1e-9)
    np.testing.assert_allclose(cmd.n_palm[k], n_unit @ R.T, atol=1e-12)


# ------------------------------------------------------------------------------------------ execution
@pytest.mark.parametrize("gravity, hold", [((0.0, 0.0, 0.0), 1.0), (GRAVITY_DOWN, 2.0)])
def test_initial_grasp_is_held(hand, box_problem, gravity, hold):
    """box_shift's grasp0, certified (force closure, and a gravity-hold certificate for the box's 0.21 kg
    along −z of the palm), held for `hold` s: within 2 mm / 2° with gravity off (1 s) and on (2 s)."""
    from regrasp_casadi.certificates import GravityHold, gravity_certificate
    from regrasp_casadi.stability import contact_normals, force_closure_quality, torque_reference

    g0 = box_problem.grasp0
    plan = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object)])
    # the grasp is certified: force closure (ε > 0, μ = 0.5), and it holds the box's weight along −z
    T = g0.T_palm_object
    contacts = np.asarray(plan.steps[0].contacts_object)
    normals = contact_normals(contacts, (hand.tip_positions(g0.q) - T[:3, 3]) @ T[:3, :3])
    com, length = torque_reference(box_problem.obj.mesh)
    assert force_closure_quality(contacts, normals, 0.5, com, length) > 1e-3
    weight = 0.21 * (T[:3, :3].T @ np.array(GRAVITY_DOWN))
    assert gravity_certificate(GravityHold(contacts, normals, weight=weight, center=com, mu=0.5)).ok
    report = simulate(plan, hand, box_problem.obj, SimOptions(gravity_palm=gravity, hold_time=hold))
    assert report.held, report.summary()
    assert report.max_deviation_mm < 2.0 and report.max_deviation_deg < 2.0, report.summary()
    assert report.sim_time == pytest.approx(0.5 + hold, abs=2e-3)
    final = report.steps[-1]
    assert set(final.fingers_touching) == set(hand.fingers)
    if any(gravity):  # the fingers carry the weight: friction ≥ m g needs Σ normal ≥ m g / μ
        assert sum(final.tip_normal_force.values()) >= report.object_mass * 9.81 / 0.5


@pytest.mark.parametrize("finger, dropped", [("thumb", True), ("index", False)])
def test_lifting_the_thumb_drops_the_box(hand, box_problem, finger, dropped):
    """grasp0 has index, middle and ring on one face and the thumb opposite: lifting the thumb 2 cm
    under gravity drops the box (deviation > 2 cm within 1 s of the settle); lifting the index instead
    leaves a force-closure grasp that holds (measured 0.27 mm / 0.50°)."""
    g0 = box_problem.grasp0
    q1 = lifted(hand, box_problem.obj, g0.q, g0.T_palm_object, finger)
    plan = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object),
                                         ("gait", finger, q1, g0.T_palm_object)])
    opts = SimOptions(gravity_palm=GRAVITY_DOWN, hold_time=1.0)
    report = simulate(plan, hand, box_problem.obj, opts)
    assert report.dropped is dropped, report.summary()
    if dropped:
        assert report.drop_time <= opts.settle_time + 1.0
        assert max(report.series["deviation_mm"]) > 20.0
        assert report.steps[1].grip_residual > 0.0
    else:
        assert report.held and report.max_deviation_mm < 2.0, report.summary()


@pytest.fixture(scope="module")
def box_shift_plan(box_problem):
    from regrasp_casadi import plan_regrasp

    # the paper's planner (stability "none"): its plan has gaits with and without force closure
    plan = plan_regrasp(box_problem.grasp0, box_problem.grasp_goal, method="svd", self_clearance=None,
                        stability="none")
    # with rolling tips this old problem's plan stops at 11 mm ("solver_failure"; its grasp0 has fingers
    # overlapping, hence no self-collision constraints); its steps are what the tests below execute
    assert len(plan.steps) >= 20, plan.status_detail
    return plan


@pytest.mark.xfail(strict=False, reason=(
    "measured (MuJoCo 4.0, default SimOptions: object-pose and grip-force feedback, gravity off, the steps' "
    "paths executed; 2026-12-02, with rolling tips, the plan's 22 steps): box_shift's svd plan of the "
    "paper's planner is 'deviating', max 10.8 mm / 16.4 deg, final 8.2 mm / 9.0 deg (open loop: max "
    "12.6 mm / 22.4 deg; with the fixed contacts before: max 10.5 mm / 42.6 deg, open loop dropped at "
    "t = 9.2 s): its thumb gaits leave index, middle and ring on one face (force-closure margin 0), so "
    "the holding fingers push the box away; the feedback brings it back only once the thumb lands."))
def test_shipped_plan_is_followed_with_gravity_off(box_problem, box_shift_plan):
    report = simulate(box_shift_plan, box_problem.hand, box_problem.obj, SimOptions())
    assert report.held and report.max_deviation_mm <= 5.0, report.summary()


def test_force_closure_part_of_a_shipped_plan_is_followed(box_problem, box_shift_plan):
    """The longest run of box_shift's plan whose gaits all keep force closure (ε > 0, `stability`),
    executed from its first step with gravity off: every step-end centre-of-mass deviation within 3 mm.
    Measured: steps 11-24 before 2026-12-03, 1.5 mm and 6.6 deg; since libigl's exact distance and the
    edge normals the plan's longest such runs are 5 steps (1-6, 6-11, 11-16), steps 1-6: 0.09 mm and
    0.12 deg. The rotation is not asserted (three point contacts of small margin ε ≈ 0.01-0.06 let the
    box turn a few degrees per gait)."""
    from regrasp_casadi.stability import holding_quality, torque_reference

    plan, hand, obj = box_shift_plan, box_problem.hand, box_problem.obj
    com, length = torque_reference(obj.mesh)

    def closed(i: int) -> bool:
        step, before = plan.steps[i], plan.steps[i - 1]
        if step.kind != "gait":
            return True
        T = before.T_palm_object
        tips = (hand.tip_positions(before.q) - T[:3, 3]) @ T[:3, :3]
        return holding_quality(before.contacts_object, tips, list(plan.fingers).index(step.finger),
                               com, length) > 1e-3

    runs, start = [], 0
    for i in range(1, len(plan.steps) + 1):
        if i == len(plan.steps) or not closed(i):
            runs.append((start, i))
            start = i
    a, b = max(runs, key=lambda r: r[1] - r[0])
    assert b - a >= 5, runs
    steps = list(plan.steps[a:b])
    steps[0] = dataclasses.replace(steps[0], kind="initial", finger=None)
    report = simulate(dataclasses.replace(plan, steps=tuple(steps)), hand, obj, SimOptions())
    assert not report.dropped and report.max_deviation_mm <= 3.0, report.summary()


# ------------------------------------------------------------------------------------------ CLI
def test_cli_simulate_exit_codes_and_json(hand, box_problem, tmp_path, capsys):
    from regrasp_casadi import cli

    g0 = box_problem.grasp0
    held = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object)])
    q1 = lifted(hand, box_problem.obj, g0.q, g0.T_palm_object, "thumb")
    dropped = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object),
                                            ("gait", "thumb", q1, g0.T_palm_object)])
    held.save(tmp_path / "held.json")
    dropped.save(tmp_path / "dropped.json")
    out = tmp_path / "report.json"
    assert cli.main(["simulate", str(tmp_path / "held.json"), "--gravity", "0", "0", "-9.81",
                     "--json", str(out)]) == cli.EXIT_OK
    assert "simulate: held" in capsys.readouterr().out
    report = json.loads(out.read_text())
    assert report["held"] and report["options"]["gravity_palm"] == [0.0, 0.0, -9.81]
    assert len(report["steps"]) == 2 and set(report["steps"][-1]["tip_normal_force"]) == set(hand.fingers)
    assert cli.main(["simulate", str(tmp_path / "dropped.json"), "--gravity", "0", "0", "-9.81"]) == 1
    assert "simulate: dropped" in capsys.readouterr().out
    assert cli.main(["simulate", str(tmp_path / "missing.json")]) == cli.EXIT_BAD_INPUT
    assert cli.main(["simulate", str(tmp_path / "held.json"), "--gravity", "0", "nan", "0"]) == 2
    capsys.readouterr()
    assert cli.main(["simulate", str(tmp_path / "held.json"), "--gravity", "plan"]) == cli.EXIT_BAD_INPUT
    assert "not 'gravity'" in capsys.readouterr().err  # a plan not certified for gravity has none
    certified = dataclasses.replace(held, options={**held.options, "stability": "gravity",
                                                   "gravity_palm": [0.0, -9.81, 0.0]})
    certified.save(tmp_path / "certified.json")
    argv = ["simulate", str(tmp_path / "certified.json"), "--gravity", "plan", "--json", str(out)]
    assert cli.main(argv) in (cli.EXIT_OK, cli.EXIT_FAILED)
    assert json.loads(out.read_text())["options"]["gravity_palm"] == [0.0, -9.81, 0.0]
    # "support": 9.81 m/s² against the outward normal of the thumb's face at the first step (trimesh's face
    # normal of the box mesh, object frame), so the object rests on index, middle and ring
    argv = ["simulate", str(tmp_path / "held.json"), "--gravity", "support", "--json", str(out)]
    assert cli.main(argv) == cli.EXIT_OK, capsys.readouterr().out
    g_palm = np.asarray(json.loads(out.read_text())["options"]["gravity_palm"])
    thumb = list(hand.fingers).index("thumb")
    mesh = box_problem.obj.mesh
    _, _, face = trimesh.proximity.closest_point(mesh, g0.contacts_object[thumb:thumb + 1])
    g_object = np.asarray(g0.T_palm_object)[:3, :3].T @ g_palm
    np.testing.assert_allclose(g_object, -9.81 * mesh.face_normals[face[0]], atol=1e-9)


def test_urdf_collision_elements_become_geoms(box_problem, tmp_path):
    """hand_collision="urdf" on a copy of the shipped model whose link_1.0 collides as one box and link_2.0
    as one STL mesh: the box geom has the URDF's half sizes and sits at the link's FK pose × its origin;
    the mesh geom's vertices span the STL's box (trimesh); the tip links keep only the tip sphere; a URDF
    without collision elements is refused; the default keeps the sphere cover."""
    import re
    import shutil

    import trimesh

    from regrasp_casadi.errors import ModelError
    from regrasp_casadi.hand import Hand

    src = Path(box_problem.hand.urdf_path).parent
    folder = tmp_path / src.name
    shutil.copytree(src, folder)
    urdf = folder / Path(box_problem.hand.urdf_path).name
    text = urdf.read_text()
    trimesh.creation.box(extents=(0.01, 0.02, 0.03)).export(folder / "block.stl")
    box = ('<collision><origin xyz="0.001 0.002 0.02" rpy="0.3 0 0"/><geometry><box size="0.02 0.026 0.05"/>'
           '</geometry></collision>')
    mesh = '<collision><geometry><mesh filename="block.stl"/></geometry></collision>'
    for link, repl in (("link_1.0", box), ("link_2.0", mesh)):
        one = rf'<collision name="{re.escape(link)}#\d+">.*?</collision>'
        text = re.sub(rf"{one}(\s*{one})*", repl, text, count=1, flags=re.S)
    urdf.write_text(text)
    hand = Hand(urdf)
    sim = build_model(hand, box_problem.obj, SimOptions(hand_collision="urdf"))
    model, data = sim.model, mujoco.MjData(sim.model)
    q = 0.5 * (hand.q_lower + hand.q_upper)
    data.qpos[sim.qpos_hand] = q
    mujoco.mj_kinematics(model, data)
    g = model.geom("urdf:link_1.0#0").id
    assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
    np.testing.assert_allclose(model.geom_size[g], [0.01, 0.013, 0.025])
    T_origin = np.eye(4)
    T_origin[:3, :3] = Rotation.from_euler("xyz", [0.3, 0, 0]).as_matrix()
    T_origin[:3, 3] = [0.001, 0.002, 0.02]
    T = hand.fk(q)["link_1.0"] @ T_origin
    np.testing.assert_allclose(data.geom_xpos[g], T[:3, 3], atol=1e-9)
    np.testing.assert_allclose(data.geom_xmat[g].reshape(3, 3), T[:3, :3], atol=1e-9)
    gm = model.geom("urdf:link_2.0#0").id
    mesh_id = model.geom_dataid[gm]
    v = model.mesh_vert[model.mesh_vertadr[mesh_id]:model.mesh_vertadr[mesh_id] + model.mesh_vertnum[mesh_id]]
    v_link = v @ data.geom_xmat[gm].reshape(3, 3).T + data.geom_xpos[gm]   # world = palm frame here
    T2 = hand.fk(q)["link_2.0"]
    v_link = (v_link - T2[:3, 3]) @ T2[:3, :3]
    np.testing.assert_allclose(v_link.max(axis=0) - v_link.min(axis=0), [0.01, 0.02, 0.03], atol=1e-9)
    names = {model.geom(i).name for i in range(model.ngeom)}
    assert not any(n.startswith("sphere:") for n in names)
    assert not any(n.startswith("urdf:") and "_tip" in n for n in names)
    tips = {n for n in names if n.startswith("tip:")}
    assert tips == {f"tip:{hand.tip_links[f]}#tip" for f in hand.fingers}
    default = build_model(hand, box_problem.obj, SimOptions())
    assert not any(default.model.geom(i).name.startswith("urdf:") for i in range(default.model.ngeom))
    urdf.write_text(re.sub(r"<collision.*?</collision>", "", text, flags=re.S))
    with pytest.raises(ModelError, match="no link has a <collision>"):
        build_model(Hand(urdf), box_problem.obj, SimOptions(hand_collision="urdf"))


def test_surface_correction_puts_the_tips_on_the_simulated_pieces(hand, box_problem, reference_dir):
    """The box's one convex piece is its mesh: the planned tips are on it (|d| < 0.05 mm). The bleach
    bottle's coacd pieces over-cover its scanned mesh where grasp0 touches (the middle tip 2.8 mm inside
    them): with the tips put back on the pieces the grasp holds with gravity off (measured 0.39 mm),
    without it the tips push the bottle away (measured 12.9 mm)."""
    from regrasp_casadi import RegraspProblem
    from regrasp_casadi.simulate import surface_distances

    g0 = box_problem.grasp0
    plan = make_plan(hand, box_problem.obj, [("initial", None, g0.q, g0.T_palm_object)])
    d = surface_distances(build_model(hand, box_problem.obj), plan, hand, SimOptions())
    assert np.abs(d).max() < 5e-5
    # the pair as it was before its regeneration with the self-collision rule (the grasp measured here)
    path = Path(__file__).resolve().parent / "data" / "soft-scrub_0_pre_self_collision.yaml"
    problem = RegraspProblem.load(path)
    g0 = problem.grasp0
    plan = make_plan(problem.hand, problem.obj, [("initial", None, g0.q, g0.T_palm_object)])
    d = surface_distances(build_model(problem.hand, problem.obj), plan, problem.hand, SimOptions())
    assert d.min() < -2e-3
    on = simulate(plan, problem.hand, problem.obj, SimOptions(hold_time=0.5))
    off = simulate(plan, problem.hand, problem.obj, SimOptions(hold_time=0.5, surface_correction=False))
    assert on.held and on.max_deviation_mm < 2.0, on.summary()
    assert off.max_deviation_mm > 5.0, off.summary()
