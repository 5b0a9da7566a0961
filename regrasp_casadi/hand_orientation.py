"""The hand's orientation for a gravity-certified regrasp: gravity that presses the object onto the fingers.

With fingertip contacts only, a grasp in which one finger (on the Allegro, the thumb) alone opposes the
others cannot move that finger under a force-closure certificate: the others sit on one side of the object
and are not in force closure without it, so it cannot lift; and a slide drags the object with kinetic
friction μ·f_n that the others' friction (at most μ·f_n, the normal forces being equal) cannot balance
with any margin, the drag and the others' friction acting on opposite faces and making a couple
(`tests/test_stability.py`). That is exact when the others' contacts all face the opposing finger
squarely (one face of a box); where they spread over curved or adjacent faces some slides certify, but
not enough: on box_shift (svd) four certified thumb slides bring the thumb from 31 to 17 mm of its goal
and the plan stops there. Every shipped problem's goal moves the thumb by 3–5 cm, and the certified
planner (`stability="force_closure"`) converges on 1 of the 10 plans (box_shift sd; benchmarks/README.md).

Under gravity the weight can do the thumb's work: oriented so that gravity presses the object onto the
fingers that oppose the thumb, those fingers carry it while the thumb slides or lifts, and the gravity
certificate (`stability="gravity"`) holds. `supporting_gravity` gives that direction in the palm frame,
for a hand fixed in the world during the regrasp (a wrist or arm orients it beforehand):

    g_palm = |g| · R_palm_object · (−n_o)

where n_o is the outward surface normal (object frame) at the contact of the opposing finger o in the
grasp, and R_palm_object the grasp's object orientation. The opposing finger is the one whose normal is
most opposed to the sum of the others' normals (the thumb on every shipped problem).

    >>> g = supporting_gravity(problem.grasp0)                       # (3,) m/s², palm frame
    >>> plan = plan_regrasp(problem.grasp0, problem.grasp_goal, stability="gravity", gravity_palm=tuple(g))
    >>> simulate(plan, options=SimOptions(gravity_palm=tuple(g)))

Measured on the shipped problems (benchmarks/README.md, "simulate.py"): see there for how many of these
plans converge, verify and are held in MuJoCo.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.certificates import GRAVITY
from regrasp_casadi.grasp import Grasp

__all__ = ["opposing_finger", "supporting_gravity", "pinned_opposer_hint"]


def opposing_finger(grasp: Grasp) -> str:
    """The finger whose contact's outward normal is most opposed to the sum of the other fingers' (object
    frame): the one that alone opposes the others (the thumb of an Allegro precision grasp)."""
    return grasp.hand.fingers[_most_opposed(_contact_normals(grasp))]


def _most_opposed(normals: NDArray) -> int:
    """The row of the normal (m, 3) most opposed to the sum of the others: argmax_k −n_k · Σ_{j≠k} n_j."""
    n = np.asarray(normals, float).reshape(-1, 3)
    total = n.sum(axis=0)
    return int(np.argmax([-float(row @ (total - row)) for row in n]))


def supporting_gravity(grasp: Grasp, finger: str | None = None, g: float = GRAVITY) -> NDArray[np.float64]:
    """Gravitational acceleration (3,), palm frame, m/s², that presses the object of `grasp` onto the
    fingers opposite `finger` (default: `opposing_finger`): |g| · R_palm_object · (−n), n the outward
    surface normal at `finger`'s contact, object frame.

    Raises:
        ValueError: `finger` is not one of the grasp's hand's fingers, or `g` is not positive.
    """
    fingers = list(grasp.hand.fingers)
    finger = opposing_finger(grasp) if finger is None else finger
    if finger not in fingers:
        raise ValueError(f"finger {finger!r} is not a finger of the hand ({', '.join(fingers)})")
    if not g > 0.0:
        raise ValueError(f"g must be positive, got {g!r}")
    n = _contact_normals(grasp)[fingers.index(finger)]
    R_palm_object = np.asarray(grasp.T_palm_object, float)[:3, :3]
    return float(g) * (R_palm_object @ -n)


def pinned_opposer_hint(obj, fingers, step, zeta: float) -> str:
    """For a force-closure plan that stopped short at `step` (a `PlanStep`: its contacts, object frame,
    and their errors, m): "" unless the finger that alone opposes the others (outward surface normals of
    `obj` at the contacts, `fingers` order) is still farther than `zeta` (m) from its goal; then a hint
    (text) that force closure cannot move it and gravity can (`supporting_gravity`)."""
    contact_error = np.asarray(step.contact_error, float)
    n = np.asarray(obj.surface_normals(np.asarray(step.contacts_object, float)), float).reshape(-1, 3)
    k = _most_opposed(n)
    others = np.delete(n, k, axis=0)
    if contact_error[k] <= zeta or np.any(others @ n[k] > 1e-6):  # another finger on its side, or it arrived
        return ""
    return (f"; the {fingers[k]} ({contact_error[k] * 1e3:.1f} mm from its goal) alone opposes the other "
            f"fingers, so force closure lets it lift only when the others alone are in force closure and "
            f"slide only where their friction balances its drag: plan with stability='gravity' and "
            f"gravity_palm=hand_orientation.supporting_gravity(grasp0) (regrasp plan --gravity support)")


def _contact_normals(grasp: Grasp) -> NDArray[np.float64]:
    """Outward unit surface normals (m, 3), object frame, at the grasp's contacts (exact mesh)."""
    contacts = np.asarray(grasp.contacts_object, float).reshape(-1, 3)
    return np.asarray(grasp.obj.surface_normals(contacts), float)
