"""`verify`'s check that a "converged" plan's fingertips are on the side of the object their goals are on.

The contact error (the distance of each contact to its goal contact) does not see a wall: on a bowl
whose wall is 3–5 mm thick, a fingertip on the outside of the wall is within ζ = 6 mm of a goal right
across it on the inside, while the finger is on the wrong side of the wall, its tip centre two tip
radii from where the goal grasp puts it. So a "converged" plan's last step must also have the straight
segment from each tip centre to its goal tip centre outside the object: no deeper than `SIDE_DEPTH`
into it, at `SIDE_SAMPLES` points (exact signed distance). The goal tip centre is the goal contact
lifted one tip radius along the object's outward normal there (`ObjectModel.surface_normals`: the face's
normal, the angle-weighted pseudo-normal on an edge or vertex).

Contacts on either side of a convex edge within ζ pass (the segment between their tip centres stays
outside the edge while the contacts are closer to it than the tip radius), and so does a tip on the
inner top of a rim whose goal is on the outer top (the generated bowl pair of seed 15, SD: the middle's
contact 6.0 mm from its goal, its normal 122° from the goal's, the segment 5.5 mm above the rim).

    >>> findings = check_goal_sides(ctx, len(plan.steps) - 1, plan.steps[-1])
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from regrasp_casadi.transforms import inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import PlanStep
    from regrasp_casadi.verify import Finding, VerifyContext

__all__ = ["SIDE_DEPTH", "SIDE_SAMPLES", "check_goal_sides"]

SIDE_DEPTH = 0.5e-3
"""How deep the segment from a converged tip centre to its goal tip centre may pass into the object, m."""
SIDE_SAMPLES = 41
"""Points of that segment whose exact signed distance is taken (ends included)."""


def check_goal_sides(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """A plan that says "converged" ends with no finger across the object from its goal: the segment from
    each tip centre to its goal tip centre no deeper than `SIDE_DEPTH` in the object (module docstring);
    one finding per finger beyond it (amount: the depth, m)."""
    from regrasp_casadi.verify import Finding

    if k != len(ctx.plan.steps) - 1 or ctx.plan.status != "converged":
        return []
    rho = float(ctx.hand.tip_radius)
    goals = np.asarray(ctx.plan.goal_contacts_object, float)
    goal_tips = goals + rho * np.asarray(ctx.obj.surface_normals(goals), float)
    tips = transform_points(inv_T(step.T_palm_object), ctx.exact.p_palm_tips[k])
    s = np.linspace(0.0, 1.0, SIDE_SAMPLES)[None, :, None]
    segments = tips[:, None, :] + s * (goal_tips - tips)[:, None, :]  # (m, samples, 3)
    _, sd = ctx.obj.closest_points(segments.reshape(-1, 3))
    depth = -np.min(np.asarray(sd, float).reshape(len(tips), SIDE_SAMPLES), axis=1)
    return [Finding(f, float(d), SIDE_DEPTH,
                    f"plan says converged but the object lies between the {f} tip and its goal: the segment "
                    f"between their tip centres passes {d * 1e3:.2f} mm inside it (the other side of a wall)")
            for f, d in zip(ctx.fingers, depth, strict=True) if d > SIDE_DEPTH]
