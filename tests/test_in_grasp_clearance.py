"""OPT2's clearance model (local plane sets, two-way offsets) against the exact mesh, and the fixed point.

References: trimesh's signed distance (independent of the package's exact distance), the scalar
`select_local_planes`, and the grasp the solve starts from.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from regrasp_casadi.convex import select_local_planes, select_local_planes_batch
from regrasp_casadi.in_grasp import InGraspNLP
from regrasp_casadi.local_clearance import LocalClearance
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.signed_distance import DEFAULT_TAU
from regrasp_casadi.transforms import exp_so3, inv_T, make_T, rotation_angle, transform_points

REPO = Path(__file__).resolve().parents[1]
BOX_PROBLEM = REPO / "problems" / "box_rotate.yaml"
YCB = Path("/work/shared/reference/ycb")
YCB_OBJECTS = ("006_mustard_bottle", "011_banana")


@pytest.fixture(scope="module")
def box_problem():
    return RegraspProblem.load(BOX_PROBLEM)


@pytest.fixture(scope="module")
def box_nlp(box_problem):
    return InGraspNLP(box_problem.hand, box_problem.obj, "svd")


def _trimesh_clearance(mesh: trimesh.Trimesh, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Exact clearance (surface distance − radius) of spheres, m, by trimesh (positive outside)."""
    return -trimesh.proximity.signed_distance(mesh, centres) - radii


def _near_configurations(hand, obj: ObjectModel, seed: int, n: int, beta: float):
    """Random joint angles and object poses (palm frame) at which no sphere penetrates the mesh and
    some non-tip sphere is within 3 mm of the clearance β (where the model matters): (q, T, centres
    (k, 3) object frame) triples."""
    rng = np.random.default_rng(seed)
    radii = np.asarray(hand.sphere_radii(None), float)
    found, tries = [], 0
    while len(found) < n and tries < 400:
        tries += 1
        q = rng.uniform(hand.q_lower, hand.q_upper)
        centres_palm = hand.sphere_centers(q)[: radii.size]
        i = rng.integers(radii.size)  # put the object's surface near sphere i
        R = exp_so3(rng.normal(size=3))
        surface, normals = obj.sample_surface(1, seed=int(rng.integers(1 << 30)))
        gap = radii[i] + beta + rng.uniform(-0.5e-3, 3e-3)
        p_obj = surface[0] + normals[0] * gap  # where sphere i's centre should be, object frame
        T = make_T(R, centres_palm[i] - R @ p_obj)
        centres = transform_points(inv_T(T), centres_palm)
        if np.min(obj.near_signed_distance(centres, radii + 0.01) - radii) < 0.0:
            continue  # penetrating (the package's exact distance, cheap); confirmed by trimesh below
        if _trimesh_clearance(obj.mesh, centres, radii).min() >= 0.0:
            found.append((q, T, centres))
    return found


def _model_violations(obj: ObjectModel, hand, beta: float, seed: int) -> tuple[int, int]:
    """(spheres with exact clearance ≥ β whose model clearance is below β, such spheres checked)."""
    radii = np.asarray(hand.sphere_radii(None), float)
    model = LocalClearance(obj.pieces, radii.size, 2, 8, DEFAULT_TAU, 0.005)
    bad = checked = 0
    for _, _, centres in _near_configurations(hand, obj, seed, 6, beta):
        exact = obj.near_signed_distance(centres, radii + 0.01)
        params = model.at_start(centres, exact)
        _, d = model.evaluate(centres, params)
        reference = _trimesh_clearance(obj.mesh, centres, radii)
        clear = reference >= beta
        bad += int(np.sum((d - radii)[clear] < beta - 1e-9))
        checked += int(np.sum(clear))
    return bad, checked


def test_batch_plane_selection_is_the_scalar_selection_per_set():
    obj = ObjectModel.bottle()
    pts = np.random.default_rng(3).normal(size=(9, 2, 3)) * 0.05
    for n_pieces, k in [(2, 8), (1, 4), (3, 300)]:
        N, H = select_local_planes_batch(obj.pieces, pts, n_pieces, k)
        for i in range(len(pts)):
            N1, H1 = select_local_planes(obj.pieces, pts[i], n_pieces, k)
            assert np.array_equal(N[i], N1) and np.array_equal(H[i], H1)


@pytest.mark.parametrize("shape", ["bottle", "banana"])
def test_model_is_feasible_where_the_mesh_is_on_generated_shapes(hand, shape):
    """No sphere whose exact (trimesh) clearance is ≥ β is below β in OPT2's model at the start."""
    obj = getattr(ObjectModel, shape)()
    bad, checked = _model_violations(obj, hand, 1e-3, seed=7)
    assert checked > 100
    assert bad == 0


@pytest.mark.parametrize("name", YCB_OBJECTS)
def test_model_is_feasible_where_the_mesh_is_on_ycb_meshes(hand, name):
    if not (YCB / name / "mesh.obj").is_file():
        pytest.skip("YCB meshes not available")
    obj = ObjectModel.from_mesh(YCB / name / "mesh.obj")
    bad, checked = _model_violations(obj, hand, 1e-3, seed=11)
    assert checked > 100
    assert bad == 0


def test_nlp_constraints_at_the_start_hold_where_the_mesh_clearance_does(box_problem, box_nlp):
    """The built NLP's clearance constraints at the start of a move (its first parameters): every sphere
    with exact clearance ≥ β is ≥ β, at the shipped grasps and at perturbed object poses."""
    hand, obj, beta = box_problem.hand, box_problem.obj, box_nlp.options.beta
    radii = np.asarray(hand.sphere_radii(None), float)
    rng = np.random.default_rng(5)
    g0 = box_problem.grasp0
    cases = [(g0.q, g0.T_palm_object)]
    for _ in range(4):
        T = np.array(g0.T_palm_object)
        T[:3, 3] += rng.normal(size=3) * 0.004
        cases.append((g0.q, T))
    for q, T in cases:
        centres = transform_points(inv_T(T), hand.sphere_centers(q)[: radii.size])
        reference = _trimesh_clearance(obj.mesh, centres, radii)
        model = box_nlp.start_clearance(q, T)
        clear = reference >= beta
        assert np.all(model[clear] >= beta - 1e-9)
        # and the model is the exact clearance there, not only above β
        assert np.allclose(model[reference < 0.009], reference[reference < 0.009], atol=1e-5)


def _assert_stays(nlp, problem):
    g0 = problem.grasp0
    res = nlp.solve(g0.q, g0.T_palm_object, g0.tip_centers_object, T_target=g0.T_palm_object)
    assert res.success, res.status
    assert np.linalg.norm(res.T_palm_object[:3, 3] - g0.T_palm_object[:3, 3]) <= 1e-4
    assert rotation_angle(res.T_palm_object[:3, :3], g0.T_palm_object[:3, :3]) <= 1e-3
    tips = problem.hand.tip_positions(res.q)
    assert np.max(np.linalg.norm(tips - problem.hand.tip_positions(g0.q), axis=1)) <= 1e-4


def test_target_at_the_current_pose_keeps_the_grasp(box_problem, box_nlp):
    """Staying still is a fixed point, cold and after another move (warm multipliers)."""
    box_nlp.reset()
    _assert_stays(box_nlp, box_problem)
    g0 = box_problem.grasp0
    T_far = np.array(g0.T_palm_object)
    T_far[:3, 3] += [0.0, 0.0, 0.01]
    box_nlp.solve(g0.q, g0.T_palm_object, g0.tip_centers_object, T_target=T_far)
    _assert_stays(box_nlp, box_problem)


@pytest.mark.slow
def test_target_at_the_current_pose_keeps_a_ycb_grasp():
    path = REPO / "benchmarks" / "problems" / "mustard_0.yaml"
    if not (YCB / "006_mustard_bottle" / "mesh.obj").is_file():
        pytest.skip("YCB meshes not available")
    problem = RegraspProblem.load(path)
    _assert_stays(InGraspNLP(problem.hand, problem.obj, "svd"), problem)


def test_solve_log_records_each_ipopt_call_and_the_move(box_problem, box_nlp):
    """`solve_log.recording` sees every backend call of a move (their iterations add up to the move's,
    as IPOPT counts them) and the move itself with the exact checks' verdict; nothing outside it."""
    from regrasp_casadi.solve_log import recording

    g0 = box_problem.grasp0
    T_target = np.array(g0.T_palm_object)
    T_target[:3, 3] += [0.002, 0.0, 0.0]
    with recording() as log:
        res = box_nlp.solve(g0.q, g0.T_palm_object, g0.tip_centers_object, T_target=T_target)
    box_nlp.solve(g0.q, g0.T_palm_object, g0.tip_centers_object, T_target=T_target)  # not recorded
    assert [c.kind for c in log.calls] == ["opt2"] * len(log.calls) and log.calls
    assert sum(c.iterations for c in log.calls) == res.iterations
    assert len(log.moves) == 1 and log.moves[0].accepted == res.success
    s = log.summary()["opt2"]
    assert s["calls"] == len(log.calls) and s["rejected"] == (0 if res.success else 1)
