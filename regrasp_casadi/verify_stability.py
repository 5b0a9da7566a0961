"""verify's stability checks: the certificate of every step's holding set, and slide steps on the surface.

Rows of `verify.CHECK_TABLE` ("slide_path", "unstable_gait"); they judge with verify's own tolerances
(`Tolerances.mu`, `Tolerances.max_normal_force`, `Tolerances.surface_tol`), never the plan's. A slide's
finger counts as pushing along its normal and dragging the object with kinetic friction μ along its
motion over the surface (its tip centre's, previous step to this, in the tangent plane: over an edge
the contact point barely moves while the tip slides over it), and as pushing along its normal without
drag (a frictionless contact, as at the slide's start and end: a slide held only by its drag's help is
not certified), at both ends of the step. Also the
stability metrics of every plan (the paper's force-closure margin of the gaits' holding fingers,
`record_holding_quality`) and the stability line of `VerifyReport.summary`. Imports only the exact side
of the package (certificates, stability, transforms, motion): no NLP or smooth-distance code.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.certificates import GRAVITY, Certificate, certify_step, object_mass
from regrasp_casadi.constants import MU
from regrasp_casadi.stability import contact_normals, holding_quality, sliding_normal
from regrasp_casadi.transforms import inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import Plan, PlanStep
    from regrasp_casadi.verify import Finding, VerifyContext

__all__ = ["SLIDE_SAMPLES", "STABILITY_KINDS", "StabilitySetting", "stability_setting", "holding_certificate",
           "slide_samples", "check_slide_path", "check_unstable_gait", "record_holding_quality",
           "stability_metrics", "stability_summary"]

SLIDE_SAMPLES = 8
"""Interior samples of every segment of a slide step's path (of its joints' linear path when it has
none) at which the sliding tip must be on the surface, besides the knots."""

STABILITY_KINDS = ("force_closure", "gravity")
"""The certificate kinds a plan's `options["stability"]` may ask for (anything else: "none")."""


@dataclass(frozen=True)
class StabilitySetting:
    """What verify's stability check judges a plan by."""

    kind: str
    """The certificate kind recomputed: the plan's `options["stability"]`, or "force_closure" for a plan
    made without one (then a metric only)."""
    checked: bool
    """The plan asks for a certificate: a step without one is an `unstable_gait` violation."""
    mass: float | None
    """The object's mass, kg (gravity)."""
    gravity_palm: NDArray
    """(3,) gravity, palm frame, m/s² (gravity)."""


def stability_setting(plan: Plan, obj: ObjectModel, mass: float | None = None, gravity_palm: Any = None,
                      metrics: dict | None = None) -> StabilitySetting:
    """The stability setting of `plan`: its kind; for gravity the mass (kg: `mass`, else the plan's
    `options["object_mass"]`, else mesh volume × 500 kg/m³) and gravity (palm frame, m/s²:
    `gravity_palm`, else the plan's, else (0, 0, −9.81)). Recorded in `metrics` when given."""
    options = plan.options
    checked = options.get("stability", "none") in STABILITY_KINDS
    kind = options["stability"] if checked else "force_closure"
    g = np.asarray(gravity_palm if gravity_palm is not None
                   else options.get("gravity_palm", (0.0, 0.0, -GRAVITY)), float).reshape(3)
    m_kg = object_mass(obj.mesh, mass if mass is not None else options.get("object_mass")) \
        if kind == "gravity" else None
    if metrics is not None:
        metrics.update(stability=kind, stability_checked=checked)
        if m_kg is not None:
            metrics.update(mass_kg=m_kg, gravity_palm=g.tolist())
    return StabilitySetting(kind, checked, m_kg, g)


def holding_certificate(ctx: VerifyContext, k: int, hold: NDArray, sliding: NDArray,
                        direction: NDArray | None = None) -> Certificate:
    """The certificate (of the context's `stability` kind, verify's μ and force bound) of the fingers
    `hold` (m,) bool in the exact grasp of step k, those of `sliding` (m,) moving over the surface in
    `direction` (3,), object frame: pushing along the normal and dragging the object with kinetic
    friction μ (`stability.sliding_normal`; None: frictionless)."""
    step, exact = ctx.plan.steps[k], ctx.exact
    T = step.T_palm_object
    tips = transform_points(inv_T(T), exact.p_palm_tips[k])
    contacts = exact.p_object_closest[k]
    com, length = ctx.torque_reference
    st = ctx.stability
    normals = contact_normals(contacts, tips)
    for j in np.flatnonzero(sliding):
        normals[j] = sliding_normal(normals[j], direction, ctx.tol.mu)
    return certify_step(contacts, normals, hold, st.kind, ctx.tol.mu, st.mass,
                        T[:3, :3].T @ st.gravity_palm, center=com, length=length, sliding=sliding,
                        max_normal_force=ctx.tol.max_normal_force)


def slide_samples(step: PlanStep, prev: PlanStep) -> tuple[NDArray, NDArray, NDArray]:
    """Where a slide step's motion is judged: its path's knots and `SLIDE_SAMPLES` interior points of
    every segment (`motion.interpolate_knots`), or, for a step without a path, `SLIDE_SAMPLES` interior
    points of the joints' linear path from `prev` (the object at the step's pose). Returns the fraction
    of the motion (N,) (of its duration; of the joint path without one), q (N, n) rad and T_palm_object
    (N, 4, 4)."""
    u = np.arange(1, SLIDE_SAMPLES + 1) / (SLIDE_SAMPLES + 1)
    if step.path is None:
        q = (1 - u)[:, None] * np.asarray(prev.q, float)[None] + u[:, None] * np.asarray(step.q, float)[None]
        return u, q, np.repeat(np.asarray(step.T_palm_object, float)[None], len(u), axis=0)
    from regrasp_casadi.motion import interpolate_knots

    t = step.path.t
    inner = (t[:-1, None] + u[None, :] * np.diff(t)[:, None]).ravel()
    times = np.sort(np.concatenate([t, inner]))
    q, T = interpolate_knots(t, step.path.q, step.path.T_palm_object, times)
    return times / max(float(t[-1]), 1e-12), q, T


def check_slide_path(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """A slide keeps its tip on the surface all along: |exact distance − tip radius| ≤ surface_tol at
    every sample of `slide_samples` (its path, else the joints' linear path between the steps; metric
    "max_slide_path_error")."""
    if k == 0 or step.kind != "slide":
        return []
    hand, fi = ctx.hand, ctx.fingers.index(step.finger)
    where, Q, Ts = slide_samples(step, ctx.plan.steps[k - 1])
    tips = np.array([np.asarray(hand.tip_positions(q), float)[fi] for q in Q])
    p_object = np.einsum("kij,ki->kj", Ts[:, :3, :3], tips - Ts[:, :3, 3])
    _, sd = ctx.obj.closest_points(p_object)
    gap = np.abs(np.asarray(sd, float) - float(hand.tip_radius))
    j = int(np.argmax(gap))
    ctx.metrics["max_slide_path_error"] = max(ctx.metrics["max_slide_path_error"], float(gap[j]))
    if gap[j] <= ctx.tol.surface_tol:
        return []
    from regrasp_casadi.verify import Finding

    along = "its path" if step.path is not None else "the joints' linear path"
    return [Finding(step.finger, float(gap[j]), ctx.tol.surface_tol,
                    f"sliding {step.finger} tip leaves the surface by {gap[j] * 1e3:.2f} mm at "
                    f"{where[j]:.2f} of {along} (tolerance {ctx.tol.surface_tol * 1e3:.2f} mm)")]


def check_unstable_gait(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """The fingers holding the object during the step have a certificate of the plan's kind (see the
    module docstring); for a plan made without stability only the metrics ("uncertified_steps",
    "min_certificate_margin")."""
    m = len(ctx.fingers)
    everyone, nobody = np.ones(m, bool), np.zeros(m, bool)
    mover = np.array([f == step.finger for f in ctx.fingers])
    if step.kind == "gait" and k > 0:
        certs = [holding_certificate(ctx, k - 1, ~mover, nobody)]
    elif step.kind == "slide" and k > 0:
        fi = ctx.fingers.index(step.finger)
        tips = [transform_points(inv_T(ctx.plan.steps[j].T_palm_object), ctx.exact.p_palm_tips[j])[fi]
                for j in (k - 1, k)]
        certs = [holding_certificate(ctx, j, everyone, mover, drag) for j in (k - 1, k)
                 for drag in (tips[1] - tips[0], None)]
    else:
        certs = [holding_certificate(ctx, k, everyone, nobody)]
    worst = min(certs, key=lambda c: (c.ok, c.margin if np.isfinite(c.margin) else -np.inf))
    if np.isfinite(worst.margin):
        ctx.metrics["min_certificate_margin"] = min(ctx.metrics["min_certificate_margin"], worst.margin)
    if worst.ok:
        return []
    ctx.metrics["uncertified_steps"].append(k)
    if not ctx.stability.checked:
        return []
    who = step.finger if step.kind in ("gait", "slide") else ""
    held = "its other fingers" if step.kind == "gait" else "its fingers"
    limit = 1.0 if ctx.stability.kind == "gravity" else 0.0
    from regrasp_casadi.verify import Finding

    return [Finding(who, float(worst.margin), limit,
                    f"{step.kind} step: {held} have no {ctx.stability.kind} certificate ({worst.detail})")]


# ---------------------------------------------------------------------------------------------- metrics
def stability_metrics(plan: Plan) -> dict[str, Any]:
    """The stability keys of `VerifyReport.metrics` before any step is checked."""
    return {"min_holding_quality": float("inf"), "min_holding_quality_at": None, "unstable_gaits": 0,
            "max_slide_path_error": 0.0, "uncertified_steps": [], "min_certificate_margin": float("inf"),
            "stored_certificates": sum(s.certificate is not None for s in plan.steps)}


def record_holding_quality(ctx: VerifyContext, k: int, step: PlanStep) -> None:
    """The paper's stability metric (whatever the plan's kind): force-closure margin ε of the other
    fingers, which hold the object while the gait's finger is lifted (at step k − 1)."""
    if k == 0 or step.kind != "gait":
        return
    prev, exact, metrics = ctx.plan.steps[k - 1], ctx.exact, ctx.metrics
    com, length = ctx.torque_reference
    eps = holding_quality(exact.p_object_closest[k - 1],
                          transform_points(inv_T(prev.T_palm_object), exact.p_palm_tips[k - 1]),
                          ctx.fingers.index(step.finger), com, length, ctx.tol.mu)
    if eps < metrics["min_holding_quality"]:
        metrics["min_holding_quality"] = eps
        metrics["min_holding_quality_at"] = {"step": k, "who": step.finger}
    metrics["unstable_gaits"] += int(eps <= 0.0)


def stability_summary(m: dict[str, Any]) -> str:
    """The stability line of `VerifyReport.summary` from its metrics `m`."""
    return (f"  stability: {len(m.get('uncertified_steps') or [])} steps without a {m.get('stability')} "
            f"certificate ({'a check' if m.get('stability_checked') else 'a metric: planned without'}; μ = "
            f"{(m.get('tolerances') or {}).get('mu', MU):g}); {m.get('unstable_gaits', 0)} gaits "
            f"whose other fingers are not in force closure, least ε "
            f"{m.get('min_holding_quality', float('nan')):.4f}")
