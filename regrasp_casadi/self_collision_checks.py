"""verify's two self-collision checks (rows of `verify.CHECK_TABLE`), exact and independent of the NLPs.

* ``self_collision``: every sphere pair of two fingers, or of a finger and the palm, that the hand does not
  exclude (`Hand.self_collision_pairs()`, none pruned) keeps a surface distance ≥ verify's
  ``self_clearance``; one violation per link pair (its closest sphere pair), naming the step, the links
  and the depth;
* ``self_collision_mesh``: the link meshes of different fingers of a URDF with meshes (the hand's own, or
  verify's ``link_meshes``) do not intersect (python-fcl, `regrasp_casadi.link_meshes`); without
  python-fcl or meshes the check is skipped and ``metrics["mesh_check"]`` says why.

Both are off with ``verify(..., self_clearance=None)``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.plan import PlanStep
    from regrasp_casadi.verify import Finding, VerifyContext

__all__ = ["check_self_collision", "check_self_collision_mesh"]


def check_self_collision(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Sphere pairs of different fingers / a finger and the palm keep ≥ self_clearance: one finding per
    link pair, its closest sphere pair (metrics "min_self_clearance", "min_self_clearance_at")."""
    from regrasp_casadi.self_collision import closest_per_link_pair
    from regrasp_casadi.verify import Finding

    limit, pairs, spheres = ctx.tol.self_clearance, ctx.self_pairs, ctx.hand.spheres
    if limit is None or not pairs:
        return []
    d = ctx.hand.self_collision_distances(step.q, pairs)
    out = []
    for i in closest_per_link_pair(ctx.hand, pairs, d):
        sa, sb = spheres[pairs[i][0]], spheres[pairs[i][1]]
        if d[i] < ctx.metrics["min_self_clearance"]:
            ctx.metrics["min_self_clearance"] = float(d[i])
            ctx.metrics["min_self_clearance_at"] = {"step": k, "who": f"{sa.label}|{sb.label}"}
        if d[i] < limit:
            what = f"overlap by {-d[i] * 1e3:.2f} mm" if d[i] < 0 else f"are only {d[i] * 1e3:.2f} mm apart"
            out.append(Finding(f"{sa.link}|{sb.link}", float(d[i]), limit,
                               f"at step {k} links {sa.link} ({sa.finger or 'palm'}) and {sb.link} "
                               f"({sb.finger or 'palm'}) {what} (spheres {sa.label}, {sb.label}; required "
                               f"{limit * 1e3:.2f} mm)"))
    return out


def check_self_collision_mesh(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """The link meshes of different fingers do not intersect (python-fcl; metric "max_mesh_penetration")."""
    from regrasp_casadi.verify import Finding

    if ctx.tol.self_clearance is None or ctx.link_meshes is None:
        return []
    out = []
    for la, lb, depth in ctx.link_meshes.intersections(step.q):
        ctx.metrics["max_mesh_penetration"] = max(ctx.metrics["max_mesh_penetration"], depth)
        fa, fb = ctx.link_meshes.finger_of[la], ctx.link_meshes.finger_of[lb]
        out.append(Finding(f"{la}|{lb}", -depth, 0.0, f"at step {k} the link meshes of {la} ({fa}) and {lb} "
                                                      f"({fb}) intersect, depth {depth * 1e3:.2f} mm"))
    return out
