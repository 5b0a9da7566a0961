"""Rolling fingertips: the slip of a tip's material over the object (`grasp_metrics.tip_slip`), the
rolling target of OPT2's relaxed rigidity (`terms.rolling_offset`) and OPT2's reposings with it."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from regrasp_casadi.grasp_metrics import path_tip_slip, tip_slip
from regrasp_casadi.in_grasp import InGraspNLP, InGraspOptions
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.terms import rolling_offset
from regrasp_casadi.transforms import exp_so3, inv_T, make_T, transform_points

BOX_PROBLEM = Path(__file__).resolve().parents[1] / "problems" / "box_rotate.yaml"
RHO = 0.012  # a tip radius, m
UP = np.array([[0.0, 0.0, 1.0]])  # outward normal of the plane z = 0


def _rot(axis, angle):
    return Rotation.from_rotvec(np.asarray(axis, float) * angle).as_matrix()[None]


def test_a_sphere_rolling_on_a_plane_does_not_slip():
    """A sphere of radius ρ turned by θ about y rolls ρθ along +x (θ ŷ × ẑ = θ x̂): no slip; the same
    turn with the centre held slides its material ρθ; a spin about the normal slides nothing; a
    translation without turning slides all of it."""
    theta, I = 0.3, np.eye(3)[None]
    p0 = np.array([[0.01, -0.02, RHO]])
    rolled = p0 + [[RHO * theta, 0.0, 0.0]]
    assert tip_slip(p0, I, rolled, _rot([0, 1, 0], theta), UP, RHO) == pytest.approx([0.0], abs=1e-12)
    assert tip_slip(p0, I, p0, _rot([0, 1, 0], theta), UP, RHO) == pytest.approx([RHO * theta])
    assert tip_slip(p0, I, p0, _rot([0, 0, 1], 1.0), UP, RHO) == pytest.approx([0.0], abs=1e-12)
    assert tip_slip(p0, I, p0 + [[0.0, 0.004, 0.0]], I, UP, RHO) == pytest.approx([0.004])
    # rolled the wrong way: the centre moves −ρθ while the turn asks +ρθ, twice the roll slides
    assert tip_slip(p0, I, p0 - [[RHO * theta, 0.0, 0.0]], _rot([0, 1, 0], theta), UP, RHO) == \
        pytest.approx([2 * RHO * theta])


def test_path_slip_is_the_net_slide_of_consecutive_samples():
    """A tip that slides 1 mm along +x, then 1 mm along +y, has slid √2 mm net; sliding back along −y
    and −x brings it to 0 (the summed slide vectors, not their lengths)."""
    xs = [[0.0, 0.0], [0.001, 0.0], [0.001, 0.001], [0.001, 0.0], [0.0, 0.0]]
    p = np.array([[[x, y, RHO]] for x, y in xs])
    R = np.broadcast_to(np.eye(3), (len(p), 1, 3, 3))
    n = np.broadcast_to(UP, (len(p), 1, 3))
    assert path_tip_slip(p, R, n, RHO)[:, 0] == pytest.approx([0.0, 1e-3, np.sqrt(2) * 1e-3, 1e-3, 0.0])


@pytest.mark.parametrize("angle", [0.05, 0.3, 0.52])
def test_rolling_offset_is_the_roll_of_the_closed_form(angle):
    """ρ θ × n for a turn of `angle` about a tangent axis: the closed form
    (axis × n) ρ angle, within 5e-4 rad of the angle up to 30° (the series of θ from sin θ)."""
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    n = np.array([0.0, 0.0, 1.0])
    R_start = Rotation.from_rotvec([0.2, -0.1, 0.4]).as_matrix()
    R = Rotation.from_rotvec(axis * angle).as_matrix() @ R_start
    got = np.asarray(ca.evalf(rolling_offset(ca.DM(R), ca.DM(R_start), ca.DM(n), RHO))).ravel()
    want = RHO * angle * np.cross(axis, n)
    assert np.linalg.norm(got - want) <= RHO * 5e-4
    # and the tip that moves by it does not slip (`tip_slip`, scipy's rotation vector)
    p0 = np.zeros((1, 3))
    assert tip_slip(p0, R_start[None], got[None], R[None], n[None], RHO)[0] <= RHO * 5e-4


@pytest.fixture(scope="module")
def problem():
    return RegraspProblem.load(BOX_PROBLEM)


def _box_slip(problem, q0, T0, q1, T1):
    """Each tip's slide over the box (m,), m: tip centres and tip-link orientations from the hand's FK,
    the box's outward normals in closed form (the axis of the largest component of the centre's
    excess over the box's half extents)."""
    hand = problem.hand
    half = np.asarray(problem.obj.spec["extents"]) / 2

    def frames(q, T):
        fk = hand.fk(q)
        p = transform_points(inv_T(T), hand.tip_positions(q))
        R = np.stack([T[:3, :3].T @ fk[hand.tip_links[f]][:3, :3] for f in hand.fingers])
        excess = np.abs(p) - half
        n = np.zeros_like(p)
        rows = np.arange(len(p))
        axis = np.argmax(excess, axis=1)
        n[rows, axis] = np.sign(p[rows, axis])
        return p, R, n

    (p0, R0, n0), (p1, R1, n1) = frames(q0, T0), frames(q1, T1)
    return tip_slip(p0, R0, p1, R1, n0 + n1, hand.tip_radius)


def test_reposing_with_rolling_tips_does_not_slide_them(problem):
    """OPT2 turns the box towards 12° about the palm's y axis. With the rolling relaxed rigidity the box
    turns at least 8° and no tip's material slides more than `max_slip` (closed-form box normals, the
    hand's FK). With the paper's fixed contacts the tips must turn over their contacts: the box turns
    less than 4° (the halved targets) and the move is refused, some tip sliding more than 1 mm."""
    g0 = problem.grasp0
    T0 = np.asarray(g0.T_palm_object)
    T_target = make_T(exp_so3(np.array([0.0, np.radians(12.0), 0.0])) @ T0[:3, :3], T0[:3, 3])
    slides, turned, accepted = {}, {}, {}
    for rolling in (True, False):
        nlp = InGraspNLP(problem.hand, problem.obj, "svd", InGraspOptions(rolling=rolling))
        res = nlp.solve(g0.q, T0, g0.tip_centers_object, T_target=T_target)
        slides[rolling] = _box_slip(problem, g0.q, T0, res.q, res.T_palm_object)
        assert res.max_slip == pytest.approx(np.max(slides[rolling]), abs=2e-5)  # OPT2's own measure agrees
        turned[rolling] = np.degrees(np.linalg.norm(Rotation.from_matrix(
            T0[:3, :3].T @ res.T_palm_object[:3, :3]).as_rotvec()))
        accepted[rolling] = res.success
    assert accepted[True] and turned[True] >= 8.0
    assert np.max(slides[True]) <= InGraspOptions().max_slip
    assert not accepted[False] and turned[False] <= 4.0
    assert np.max(slides[False]) >= 1e-3


def test_final_moves_that_roll_the_contacts_away_are_followed_by_gaits(problem):
    """box_rotate (paper planner, svd): the contacts reach ζ with the box 24° from the desired pose; a
    final move towards it rolls a contact 9.8 mm from its goal, so the final moves stop there
    ("pose_not_reached, ... stopped: contact drift" with `final_regait=False` and no re-posture gaits,
    which also get it there, `test_reposture`). With it, the planner
    reposes towards the desired pose anyway and gaits the contacts back: a final move, then a reposing
    and gaits; converged, judged by verify (slip and motion included)."""
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.verify import verify

    without = plan_regrasp(problem.grasp0, problem.grasp_goal, method="svd", stability="none",
                           final_regait=False, final_reposture=0, restarts=0)
    assert without.status == "pose_not_reached", without.status_detail
    assert "contact drift" in without.status_detail
    plan = plan_regrasp(problem.grasp0, problem.grasp_goal, method="svd", stability="none",
                        final_reposture=0)
    assert plan.status == "converged", plan.status_detail
    kinds = "".join(s.kind[0] for s in plan.steps)
    assert "fr" in kinds and kinds.index("fr") < kinds.rindex("g")  # a final move, a reposing, gaits
    assert verify(plan, problem.hand, problem.obj).ok
