"""Plans and problems shared by the simulation tests (tests/test_simulate*.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

# the box_shift problem as shipped before the self-collision constraint (issue 15): the measured motions of
# tests/test_simulate*.py are of its grasps and of its plan without that constraint (its fingers overlap;
# by default the MuJoCo model does not collide hand bodies with each other, SimOptions.hand_self_collision)
BOX_SHIFT = Path(__file__).resolve().parent / "data" / "box_shift_before_self_collision.yaml"
GRAVITY_DOWN = (0.0, 0.0, -9.81)  # along −z of the palm frame (the fingers point up)


def make_plan(hand, obj, steps) -> object:
    """A Plan of (kind, finger, q, T_palm_object) steps; contacts = closest points of the tip centres."""
    from regrasp_casadi import Plan, PlanStep

    out = []
    for kind, finger, q, T in steps:
        p_object_tips = (hand.tip_positions(q) - T[:3, 3]) @ T[:3, :3]
        contacts, _ = obj.closest_points(p_object_tips)
        out.append(PlanStep(kind=kind, finger=finger, q=q, T_palm_object=T, contacts_object=contacts,
                            contact_error=np.zeros(len(hand.fingers)), solver_status="", solve_time=0.0))
    return Plan(steps=tuple(out), goal_contacts_object=out[-1].contacts_object,
                goal_T_palm_object=out[-1].T_palm_object, fingers=tuple(hand.fingers),
                hand_spec=hand.spec(), object_spec=obj.spec, method="svd", status="converged",
                status_detail="", iterations=0, iteration_errors=np.zeros(1), timing={}, options={})


def lifted(hand, obj, q, T, finger: str, clearance: float = 0.02):
    """q with ``finger``'s tip moved along the outward surface normal until ``clearance`` (m) clear."""
    q = np.array(q, dtype=float)
    k = list(hand.fingers).index(finger)
    for _ in range(40):
        p_object_tip = (hand.tip_positions(q)[k] - T[:3, 3]) @ T[:3, :3]
        closest, d = obj.closest_points(p_object_tip[None])
        if d[0] - hand.tip_radius > clearance:
            return q
        n_palm = T[:3, :3] @ ((p_object_tip - closest[0]) / np.linalg.norm(p_object_tip - closest[0]))
        J = hand.tip_jacobian(q, finger)
        q = hand.clip(q + J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(3), 0.004 * n_palm))
    raise AssertionError(f"could not lift {finger} {clearance} m clear")
