"""Routes over the surface (`surface_route`): graph distances against closed-form geodesics on a sphere
and over a bowl's rim, the η-ahead gait target, the blocked-line test against the bowl's geometry, and
the planner on a bowl pair whose index must cross the rim (issue 12), and a goal right across the wall,
within ζ, which the planner must not call reached."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from regrasp_casadi.grasp import Grasp
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.planner import plan_regrasp
from regrasp_casadi.planner_options import PlannerOptions
from regrasp_casadi.problem import RegraspProblem
from regrasp_casadi.surface_route import (
    MAX_EDGE,
    SurfaceRoutes,
    fingers_across,
    gait_target,
    line_blocked,
    nearer_goal,
)
from regrasp_casadi.verify import verify

R_OUT, WALL = 0.06, 0.004  # ObjectModel.bowl()'s outer radius and wall, m
BEHIND_THE_RIM = Path(__file__).resolve().parent / "data" / "bowl_index_behind_the_rim.yaml"


@pytest.fixture(scope="module")
def bowl():
    return ObjectModel.bowl(R_OUT, WALL)


def _bowl_point(bowl, radius: float, below: float, azimuth: float = 0.0) -> np.ndarray:
    """The point `radius` m from the bowl's hemisphere centre, `below` rad under the rim's plane (the
    hemisphere's centre sits w/2 under the mesh's top, the rounded rim's crest)."""
    z_centre = float(bowl.mesh.bounds[1, 2]) - WALL / 2
    d = np.array([np.cos(below) * np.cos(azimuth), np.cos(below) * np.sin(azimuth), -np.sin(below)])
    return np.array([0.0, 0.0, z_centre]) + radius * d


def test_route_on_a_sphere_is_the_great_circle():
    sphere = ObjectModel.sphere(0.035)
    rng = np.random.default_rng(4)
    for _ in range(3):
        a, b = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
        routes = SurfaceRoutes(sphere, 0.035 * b[None])
        way, _ = routes.distance(0, 0.035 * a, a)
        great_circle = 0.035 * np.arccos(np.clip(a @ b, -1.0, 1.0))
        # the graph's polyline zigzags over the facets: longer than the arc, by at most a few %
        assert 0.98 * great_circle - 1e-4 <= way <= 1.08 * great_circle + MAX_EDGE / 4


def test_route_through_a_thin_wall_goes_over_the_rim(bowl):
    below = np.radians(30.0)
    outside, inside = _bowl_point(bowl, R_OUT, below), _bowl_point(bowl, R_OUT - WALL, below)
    routes = SurfaceRoutes(bowl, inside[None])
    way, _ = routes.distance(0, outside, np.array([np.cos(below), 0.0, -np.sin(below)]))
    # up the outer arc, round the rim's half circle, down the inner arc (the smooth shape's geodesic)
    over_the_rim = R_OUT * below + np.pi * WALL / 2 + (R_OUT - WALL) * below
    assert np.linalg.norm(outside - inside) == pytest.approx(WALL)
    assert 0.98 * over_the_rim <= way <= 1.08 * over_the_rim


def test_target_is_eta_up_the_outer_face_off_the_surface_by_rho(bowl):
    eta, rho = 0.01, 0.012
    below = np.radians(40.0)
    outside, inside = _bowl_point(bowl, R_OUT, below), _bowl_point(bowl, R_OUT - WALL, below)
    n_out = np.array([np.cos(below), 0.0, -np.sin(below)])
    routes = SurfaceRoutes(bowl, inside[None])
    way, _ = routes.distance(0, outside, n_out)
    target = routes.target(0, outside, n_out, eta, rho)
    assert float(bowl.exact_signed_distance(target[None])[0]) == pytest.approx(rho, abs=3e-4)
    contact = bowl.closest_points(target[None])[0][0]
    normal = (target - contact) / np.linalg.norm(target - contact)
    assert normal @ n_out > 0.9  # still on the outer face, nearer the rim
    assert contact[2] > outside[2] + 0.5 * eta * np.cos(below)
    assert way - routes.distance(0, contact, normal)[0] == pytest.approx(eta, abs=MAX_EDGE)
    assert routes.target(0, inside + 0.002 * n_out, -n_out, eta, rho) is None  # within η: the goal itself


def test_the_line_is_blocked_through_the_wall_and_free_across_the_bowl(bowl):
    rho = 0.012
    below = np.radians(30.0)
    n_out = np.array([np.cos(below), 0.0, -np.sin(below)])
    outside_tip = _bowl_point(bowl, R_OUT, below) + rho * n_out
    inside_tip = _bowl_point(bowl, R_OUT - WALL, below) - rho * n_out
    far_inside_tip = _bowl_point(bowl, R_OUT - WALL - rho, below, azimuth=np.pi / 2)
    assert line_blocked(bowl, outside_tip, inside_tip)
    assert not line_blocked(bowl, inside_tip, far_inside_tip)
    sphere = ObjectModel.sphere(0.035)  # two tip centres 40° apart: the chord is under ρ, not inside
    a, b = np.array([1.0, 0.0, 0.0]), np.array([np.cos(0.7), np.sin(0.7), 0.0])
    assert float(sphere.exact_signed_distance((0.5 * (a + b) * (0.035 + rho))[None])[0]) < rho
    assert not line_blocked(sphere, (0.035 + rho) * a, (0.035 + rho) * b)
    assert line_blocked(sphere, (0.035 + rho) * a, -(0.035 + rho) * a)  # antipodes: through it


def test_a_blocked_finger_aims_straight_until_the_plan_stops_progressing(bowl):
    # cup_regrasp SD stalled when its middle and ring took routes from the first iteration on (a route
    # can lead into a dead end the straight pull avoids): routes are the stall's remedy, not the default
    eta, rho = 0.01, 0.012
    below = np.radians(40.0)
    n_out = np.array([np.cos(below), 0.0, -np.sin(below)])
    inside = _bowl_point(bowl, R_OUT - WALL, below)
    tip, goal = _bowl_point(bowl, R_OUT, below) + rho * n_out, inside - rho * n_out
    assert line_blocked(bowl, tip, goal)
    run = SimpleNamespace(goal_tips=goal[None], goal_contacts=inside[None], obj=bowl, routes=None,
                          hand=SimpleNamespace(tip_radius=rho), tips_object=lambda: tip[None],
                          options=replace(PlannerOptions(), finger_gait=SimpleNamespace(eta=eta)), stalled=0)
    assert np.array_equal(gait_target(run, 0), goal)
    run.stalled = run.options.route_after
    target = gait_target(run, 0)
    assert np.linalg.norm(target - tip) == pytest.approx(eta, rel=0.5)  # a step up the outer face
    assert float(bowl.exact_signed_distance(target[None])[0]) == pytest.approx(rho, abs=3e-4)
    run.options = replace(run.options, route_after=3)  # the option sets how long the plan must stall
    assert np.array_equal(gait_target(run, 0), goal)
    run.stalled = 3
    assert np.array_equal(gait_target(run, 0), target)
    run.options = replace(run.options, surface_routes=False)
    assert np.array_equal(gait_target(run, 0), goal)


def test_up_the_rim_is_nearer_the_goal_along_the_surface_and_down_is_not(bowl):
    # long_gait's test of progress (`nearer_goal`): a routed finger climbing the outer face towards the
    # rim gets farther from its goal inside in a straight line but nearer along the surface; a gait back
    # down (what `long_gait` towards the goal tip did, undoing each route gait of bowl seed 19 SD) is not
    rho, wall_angle = 0.012, np.radians(40.0)

    def tip_at(below: float) -> np.ndarray:  # the tip centre on the outer face, `below` rad under the rim
        point = _bowl_point(bowl, R_OUT, below)
        return point + rho * np.asarray(bowl.surface_normals(point[None]))[0]

    inside = _bowl_point(bowl, R_OUT - WALL, wall_angle)
    tip, up, down = tip_at(wall_angle), tip_at(wall_angle - 0.15), tip_at(wall_angle + 0.15)
    goal_tip = inside + rho * np.asarray(bowl.surface_normals(inside[None]))[0]
    error = float(np.linalg.norm(bowl.closest_points(tip[None])[0][0] - inside))
    run = SimpleNamespace(goal_tips=goal_tip[None], goal_contacts=inside[None], obj=bowl, routes=None,
                          hand=SimpleNamespace(tip_radius=rho), tips_object=lambda: tip[None],
                          steps=[SimpleNamespace(contact_error=np.array([error]))],
                          options=replace(PlannerOptions(), finger_gait=SimpleNamespace(eta=0.01)),
                          stalled=PlannerOptions().route_after)
    assert np.linalg.norm(up - goal_tip) > np.linalg.norm(tip - goal_tip)  # farther in a straight line
    assert nearer_goal(run, 0, up) and not nearer_goal(run, 0, down)
    run.stalled = 0  # not routed yet: the straight contact error decides, and both are farther
    assert not nearer_goal(run, 0, up) and not nearer_goal(run, 0, down)
    assert not nearer_goal(run, 0, tip)  # where it is: not nearer


@pytest.fixture(scope="module")
def behind_the_rim():
    return RegraspProblem.load(BEHIND_THE_RIM)


def test_the_index_walks_over_the_rim_to_its_goal(behind_the_rim):
    p = behind_the_rim
    plan = plan_regrasp(p.grasp0, p.grasp_goal, method="svd", stability="none")
    assert plan.status == "converged", plan.status_detail
    assert verify(plan).ok


@pytest.mark.slow
def test_without_routes_the_index_stalls_behind_the_rim(behind_the_rim):
    p = behind_the_rim
    options = replace(PlannerOptions(method="svd", stability="none"), surface_routes=False, restarts=0)
    plan = plan_regrasp(p.grasp0, p.grasp_goal, options=options)
    assert plan.status == "stalled"
    index = plan.status_detail.split("not at their goals:")[1].split("index")[1]
    assert "the object lies between its tip and its goal" in index.split("|")[0]


def test_a_tip_across_the_wall_within_zeta_is_across_and_one_beside_it_is_not(bowl):
    rho, zeta, below = 0.012, 0.006, np.radians(40.0)
    n_out = np.array([np.cos(below), 0.0, -np.sin(below)])
    outside, inside = _bowl_point(bowl, R_OUT, below), _bowl_point(bowl, R_OUT - WALL, below)
    beside = _bowl_point(bowl, R_OUT, below + 0.004 / R_OUT)  # 4 mm down the same (outer) face
    tips = np.array([outside + rho * n_out] * 3)
    goals = np.array([inside, beside, inside])
    goal_tips = goals + rho * np.asarray(bowl.surface_normals(goals))
    error = np.array([np.linalg.norm(outside - inside), np.linalg.norm(outside - beside), 0.02])
    assert error[:2] == pytest.approx([WALL, 0.004], abs=2e-4)  # both within ζ of their goal contacts
    # the third is across too, but farther than ζ: the contact error already says it is not there
    assert fingers_across(bowl, tips, goal_tips, error, zeta) == [0]


@pytest.mark.parametrize("method", ["svd", "sd"])
def test_a_goal_across_the_wall_within_zeta_is_not_called_reached(behind_the_rim, method):
    # grasp0 itself as the goal, but the index's goal contact right across the 4 mm wall from its own:
    # within ζ = 6 mm, on the other face. Before `fingers_across`, both methods said "converged" with no
    # move and verify's goal_side check failed the plan.
    g0 = behind_the_rim.grasp0
    contacts = np.array(g0.contacts_object)
    n = np.asarray(g0.obj.surface_normals(contacts[:1]))[0]
    (inside,), _ = g0.obj.closest_points((contacts[0] - WALL * n)[None])
    contacts[0] = inside
    goal = Grasp(g0.hand, g0.obj, g0.T_palm_object, contacts, None)
    assert np.linalg.norm(inside - g0.contacts_object[0]) < PlannerOptions().zeta
    plan = plan_regrasp(g0, goal, method=method, stability="none")
    report = verify(plan)
    assert report.ok, [v.message for v in report.violations]
    if plan.status != "converged":
        assert "the index tip is across the object from its goal" in plan.status_detail
