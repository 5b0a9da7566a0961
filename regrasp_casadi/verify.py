"""Independent exact checks of a regrasp `Plan`: `verify(plan) -> VerifyReport`.

`verify` judges a plan with the exact object mesh (`ObjectModel.closest_points`, distances computed in
millimetres) and the hand's collision spheres, never with the smooth signed distance or the NLP modules.
It judges with its own tolerances (the keyword arguments of `verify`, defaults below), never with the
ζ and η the plan says it was planned with: those are only reported (`metrics["plan_options"]`).

The checks are data: `CHECK_TABLE` lists them by name, one function each, run on every step in table
order. At every step:

* structure: the plan's form (shapes, fingers, kinds); a malformed plan stops there;
* joint limits (within `limit_tol`);
* every fingertip on the surface: |d(tip centre) − tip radius| ≤ `surface_tol`;
* no other contact or penetration: every non-tip collision sphere (palm included) has
  d(centre) − radius ≥ `min_clearance`;
* the stored contacts equal the exact closest points of the tip centres (≤ `contact_consistency_tol`),
  and the stored contact errors equal the recomputed distances to the goal;
* gait and slide steps: only the named finger's joints move, the object does not, and the tip centre
  moves at most `eta`;
* slide steps: the tip on the surface (≤ `surface_tol`) along the joints' linear path (`slide_path`);
* repose / final steps: each fingertip's material slides at most `max_slip` over the object (slip; it may
  roll, `grasp_metrics.tip_slip`);
* no self-collision (`self_clearance`; `regrasp_casadi.self_collision_checks`): sphere pairs of two fingers
  or a finger and the palm, and the link meshes of different fingers (python-fcl, `link_meshes`);
* stability (`unstable_gait`, `verify_stability`): the fingers holding the object during the step have a
  certificate of the plan's kind (`options["stability"]`), recomputed with verify's μ and force bound
  (a metric only, "uncertified_steps", for a plan made without one);
* the motion between the steps, sampled so that no point of the hand moves more than 1 mm between
  samples (`regrasp_casadi.verify_motion`): penetration, self-collision, joint limits, held contacts,
  slip (``motion_*``);
* the plan's claims: a "converged" plan's last step has max contact error ≤ `zeta` and its object
  within `pose_tol_position` / `pose_tol_rotation` of the desired pose, and each contact on the side
  of the object its goal is on (`regrasp_casadi.verify_sides`: not across a thin wall from it).

A new check is one function `check_x(ctx, step_index, step) -> list[Finding]` and one row of
`CHECK_TABLE`.

    >>> report = verify(Plan.load("plan.json"))
    >>> print(report.summary()); assert report.ok
"""

from __future__ import annotations

import functools
import logging
import os
import sys
import types
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi import constants
from regrasp_casadi import verify_motion as motion
from regrasp_casadi.certificates import MAX_NORMAL_FORCE
from regrasp_casadi.grasp_metrics import pose_error, tip_frames, tip_slip
from regrasp_casadi.self_collision_checks import check_self_collision, check_self_collision_mesh
from regrasp_casadi.stability import contact_normals, torque_reference
from regrasp_casadi.transforms import inv_T, transform_points
from regrasp_casadi.verify_report import VerifyReport, Violation
from regrasp_casadi.verify_sides import check_goal_sides
from regrasp_casadi.verify_stability import (
    StabilitySetting,
    check_slide_path,
    check_unstable_gait,
    record_holding_quality,
    stability_metrics,
    stability_setting,
)

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import Plan, PlanStep

__all__ = ["Violation", "VerifyReport", "verify", "CHECKS", "CHECK_TABLE", "Check", "Finding", "Tolerances",
           "VerifyContext"]

log = logging.getLogger(__name__)

EXACT_TOL = 1e-9
"""Tolerance for "unchanged" (joints of other fingers and object pose during a gait)."""

STEP_TOL = 1e-6
"""Slack on the gait step bound `eta`, m."""

DEFAULT_ETA = constants.ETA
"""Gait step bound verify judges by unless told otherwise (DESIGN.md: 1 cm), m."""

DEFAULT_ZETA = constants.ZETA
"""Convergence threshold verify judges by unless told otherwise (DESIGN.md: 6 mm), m."""


# ---------------------------------------------------------------------------------------------- context
@dataclass(frozen=True)
class Tolerances:
    """The bounds `verify` judges by: its own, never read from the plan (see `verify` for each)."""

    surface_tol: float = 0.5e-3
    """Allowed |exact distance of a tip centre − tip radius|, m."""
    min_clearance: float = 0.0
    """Required exact distance − radius of every non-tip collision sphere, m."""
    limit_tol: float = 1e-6
    """Slack on joint limits, rad."""
    eta: float = DEFAULT_ETA
    """Gait step bound on the tip centre, m."""
    zeta: float = DEFAULT_ZETA
    """Largest contact error a "converged" plan may end with, m."""
    pose_tol_position: float = 2e-3
    """Largest distance of a "converged" plan's final object position from the desired one, m."""
    pose_tol_rotation: float = float(np.radians(2.0))
    """Largest angle of a "converged" plan's final object orientation from the desired one, rad."""
    max_slip: float = 1e-3
    """Allowed slide of a fingertip's material over the object during repose / final steps and along any
    step's motion, m (`grasp_metrics.tip_slip`: rolling is not sliding)."""
    contact_consistency_tol: float = 0.5e-3
    """Allowed gap between a stored contact and the exact closest point of its tip (and between stored
    and recomputed contact errors), m."""
    mu: float = constants.MU
    """Friction coefficient of the stability check and metrics."""
    max_normal_force: float = MAX_NORMAL_FORCE
    """Bound on each contact's normal force of the gravity certificate, N."""
    self_clearance: float | None = 0.0
    """Required surface distance of every self-collision sphere pair, m (None: no self-collision check)."""


@dataclass(frozen=True)
class ExactGeometry:
    """The exact geometry of every step, from one exact query (S = steps, m = fingers, s = non-tip
    collision spheres)."""

    p_palm_tips: NDArray
    """(S, m, 3) fingertip centres, palm frame, m."""
    p_object_closest: NDArray
    """(S, m, 3) exact closest points of the tip centres on the mesh (the true contacts), object frame, m."""
    tip_gap: NDArray
    """(S, m) exact distance of each tip centre − tip radius, m (> 0 above the surface)."""
    clearance: NDArray
    """(S, s) exact distance of each non-tip sphere centre − its radius, m (< 0 penetration)."""


class VerifyContext:
    """What every check reads: the plan, its models, verify's tolerances, the exact geometry of every
    step (computed once, on first use) and the metrics the checks fill in."""

    def __init__(self, plan: Plan, hand: Hand, obj: ObjectModel, tol: Tolerances,
                 link_meshes: str | Path | None = None):
        self.plan, self.hand, self.obj, self.tol = plan, hand, obj, tol
        self.link_meshes_urdf = Path(link_meshes) if link_meshes is not None else hand.urdf_path
        self.fingers: tuple[str, ...] = tuple(hand.fingers)
        self.sphere_labels: list[str] = list(hand.sphere_labels())
        self.metrics: dict[str, Any] = {
            "min_clearance": float("inf"), "min_clearance_at": None, "max_surface_error": 0.0,
            "max_gait_step": 0.0, "max_slip": 0.0, "final_avg_error": float("nan"),
            "final_max_error": float("nan"), "n_steps": len(plan.steps),
            **stability_metrics(plan), "tolerances": asdict(tol), "plan_options": dict(plan.options),
            "min_self_clearance": float("inf"), "min_self_clearance_at": None, "max_mesh_penetration": 0.0,
            "mesh_check": "",
        }
        self.stability: StabilitySetting = stability_setting(plan, obj)
        """What the stability check judges (`verify_stability.stability_setting`)."""

    @functools.cached_property
    def exact(self) -> ExactGeometry:
        """All tip centres and non-tip spheres of all steps, in the object frame, in one exact query."""
        hand, steps, m = self.hand, self.plan.steps, len(self.fingers)
        radii = np.asarray(hand.sphere_radii(), dtype=float)
        tips = np.stack([np.asarray(hand.tip_positions(s.q), float).reshape(m, 3) for s in steps])
        pts = []
        for s, p_palm_tips in zip(steps, tips, strict=True):
            spheres = np.asarray(hand.sphere_centers(s.q), float).reshape(-1, 3)
            pts.append(transform_points(inv_T(s.T_palm_object), np.vstack([p_palm_tips, spheres])))
        closest, sd = self.obj.closest_points(np.vstack(pts))
        closest = np.asarray(closest, float).reshape(len(steps), m + len(radii), 3)
        sd = np.asarray(sd, float).reshape(len(steps), m + len(radii))
        return ExactGeometry(p_palm_tips=tips, p_object_closest=closest[:, :m],
                             tip_gap=sd[:, :m] - float(hand.tip_radius), clearance=sd[:, m:] - radii)

    @functools.cached_property
    def self_pairs(self) -> tuple[tuple[int, int], ...]:
        """Every self-collision sphere pair (indices into `hand.spheres`), none pruned."""
        return self.hand.self_collision_pairs()

    @functools.cached_property
    def link_meshes(self):
        """The `link_meshes.LinkMeshes` of the mesh check, or None (`metrics["mesh_check"]` says why)."""
        from regrasp_casadi.link_meshes import LinkMeshes

        meshes, self.metrics["mesh_check"] = LinkMeshes.from_urdf(self.link_meshes_urdf, self.hand)
        return meshes

    @functools.cached_property
    def torque_reference(self) -> tuple[NDArray, float]:
        """(centre (3,) object frame m, length m) of the stability metric (`stability.torque_reference`)."""
        return torque_reference(self.obj.mesh)


class Finding(NamedTuple):
    """What a check reports; `verify` adds the step index and the check's name to make a `Violation`."""

    who: str
    amount: float
    limit: float
    message: str


StepCheck = Callable[[VerifyContext, int, "PlanStep"], list[Finding]]


@dataclass(frozen=True)
class Check:
    """One row of `CHECK_TABLE`."""

    name: str
    """The name in `Violation.check`."""
    run: StepCheck
    """`run(ctx, step_index, step) -> findings` (empty when the step passes or the check does not apply)."""
    needs_geometry: bool = True
    """False for the checks of the plan's form, run on every step before any geometry: a finding of one
    stops `verify` there (the geometric checks would read malformed arrays)."""


# ---------------------------------------------------------------------------------------------- checks
def check_structure(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Shapes of q, contacts and errors, the step kind (only step 0 is 'initial'), the gait's finger."""
    m, n = len(ctx.fingers), ctx.hand.n_joints
    bad = []
    if step.q.shape != (n,):
        bad.append(f"q has shape {step.q.shape}, expected ({n},)")
    if step.contacts_object.shape != (m, 3) or step.contact_error.shape != (m,):
        bad.append(f"contacts/errors have shapes {step.contacts_object.shape}/{step.contact_error.shape}")
    kinds = ("initial", "gait", "repose", "final", "slide")
    if step.kind not in kinds or (k == 0) != (step.kind == "initial"):
        bad.append(f"kind {step.kind!r} at step {k} (only step 0 is 'initial')")
    if step.kind in ("gait", "slide") and step.finger not in ctx.fingers:
        bad.append(f"{step.kind} of unknown finger {step.finger!r}")
    return [Finding("", 0.0, 0.0, "; ".join(bad))] if bad else []


def check_joint_limits(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Every joint within [q_lower − limit_tol, q_upper + limit_tol], rad."""
    hand, tol = ctx.hand, ctx.tol.limit_tol
    lower, upper = np.asarray(hand.q_lower, float), np.asarray(hand.q_upper, float)
    q = step.q
    out = []
    for i in np.flatnonzero((q < lower - tol) | (q > upper + tol)):
        over = max(lower[i] - q[i], q[i] - upper[i])
        out.append(Finding(hand.joint_names[i], over, tol,
                           f"{hand.joint_names[i]} = {q[i]:.6g} rad outside [{lower[i]:.6g}, {upper[i]:.6g}] "
                           f"by {over:.3g} rad"))
    return out


def check_tip_surface(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Every fingertip on the surface: |exact distance − tip radius| ≤ surface_tol (metric
    "max_surface_error")."""
    gap, tol = ctx.exact.tip_gap[k], ctx.tol.surface_tol
    ctx.metrics["max_surface_error"] = max(ctx.metrics["max_surface_error"], float(np.max(np.abs(gap))))
    out = []
    for f, g in zip(ctx.fingers, gap, strict=True):
        if abs(g) > tol:
            where = "above" if g > 0 else "inside"
            out.append(Finding(f, abs(g), tol, f"{f} tip is {abs(g) * 1e3:.2f} mm {where} the surface "
                                               f"(tolerance {tol * 1e3:.2f} mm)"))
    return out


def check_clearance(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Every non-tip collision sphere clear of the object by min_clearance (metrics "min_clearance",
    "min_clearance_at")."""
    clear, limit, labels = ctx.exact.clearance[k], ctx.tol.min_clearance, ctx.sphere_labels
    if not clear.size:
        return []
    j = int(np.argmin(clear))
    if clear[j] < ctx.metrics["min_clearance"]:
        ctx.metrics["min_clearance"] = float(clear[j])
        ctx.metrics["min_clearance_at"] = {"step": k, "who": labels[j]}
    out = []
    for j in np.flatnonzero(clear < limit):
        what = "penetrates the object by" if clear[j] < 0 else "has only"
        out.append(Finding(labels[j], clear[j], limit,
                           f"sphere {labels[j]} {what} {abs(clear[j]) * 1e3:.2f} mm"
                           + ("" if clear[j] < 0 else f" clearance (< {limit * 1e3:.2f} mm)")))
    return out


def check_contact_consistency(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """The stored contacts are the exact closest points of the tip centres."""
    tol = ctx.tol.contact_consistency_tol
    dev = np.linalg.norm(step.contacts_object - ctx.exact.p_object_closest[k], axis=1)
    return [Finding(f, d, tol,
                    f"stored {f} contact is {d * 1e3:.2f} mm from the exact closest point of its tip")
            for f, d in zip(ctx.fingers, dev, strict=True) if d > tol]


def check_contact_error(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """The stored contact errors are the distances of the exact contacts to the goal contacts."""
    tol = ctx.tol.contact_consistency_tol
    err = np.linalg.norm(ctx.exact.p_object_closest[k] - ctx.plan.goal_contacts_object, axis=1)
    return [Finding(f, abs(e_stored - e), tol,
                    f"stored {f} contact error {e_stored * 1e3:.2f} mm, recomputed {e * 1e3:.2f} mm")
            for f, e_stored, e in zip(ctx.fingers, step.contact_error, err, strict=True)
            if abs(e_stored - e) > tol]


def check_gait_other_joints(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """A gait or slide moves only the joints of its finger."""
    if k == 0 or step.kind not in ("gait", "slide"):
        return []
    hand, prev = ctx.hand, ctx.plan.steps[k - 1]
    moving = set(int(i) for i in np.asarray(hand.finger_joints[step.finger]).ravel())
    return [Finding(hand.joint_names[i], abs(step.q[i] - prev.q[i]), EXACT_TOL,
                    f"{step.kind} of {step.finger} moved joint {hand.joint_names[i]} "
                    f"by {step.q[i] - prev.q[i]:.3g} rad")
            for i in range(hand.n_joints) if i not in moving and abs(step.q[i] - prev.q[i]) > EXACT_TOL]


def check_gait_object_moved(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """The object does not move during a gait or slide."""
    if k == 0 or step.kind not in ("gait", "slide"):
        return []
    dT = float(np.max(np.abs(step.T_palm_object - ctx.plan.steps[k - 1].T_palm_object)))
    if dT <= EXACT_TOL:
        return []
    return [Finding(step.finger, dT, EXACT_TOL,
                    f"object pose changed during the {step.kind} of {step.finger} (max |ΔT| = {dT:.3g})")]


def check_gait_step(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """The moving tip centre travels at most eta in one gait or slide step (metric "max_gait_step")."""
    if k == 0 or step.kind not in ("gait", "slide"):
        return []
    fi, eta = ctx.fingers.index(step.finger), ctx.tol.eta
    tips = ctx.exact.p_palm_tips
    step_len = float(np.linalg.norm(tips[k][fi] - tips[k - 1][fi]))
    ctx.metrics["max_gait_step"] = max(ctx.metrics["max_gait_step"], step_len)
    if step_len <= eta + STEP_TOL:
        return []
    return [Finding(step.finger, step_len, eta,
                    f"{step.finger} tip moved {step_len * 1e3:.2f} mm in one {step.kind} "
                    f"(eta {eta * 1e3:.2f} mm)")]


def check_slip(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """Repose / final steps: no tip's material slides more than max_slip over the object from the step
    before (`grasp_metrics.tip_slip`: a tip may roll its contact along the surface, not turn over it in
    place; metric "max_slip")."""
    if k == 0 or step.kind in ("gait", "slide"):
        return []
    tol, a, b = ctx.tol.max_slip, ctx.plan.steps[k - 1], step
    (p_a, R_a), (p_b, R_b) = (tip_frames(ctx.hand, a.q, a.T_palm_object),
                              tip_frames(ctx.hand, b.q, b.T_palm_object))
    closest = ctx.exact.p_object_closest
    normals = contact_normals(closest[k - 1], p_a) + contact_normals(closest[k], p_b)
    slip = tip_slip(p_a, R_a, p_b, R_b, normals, ctx.hand.tip_radius)
    ctx.metrics["max_slip"] = max(ctx.metrics["max_slip"], float(np.max(slip)))
    return [Finding(f, sl, tol, f"{f} tip slid {sl * 1e3:.2f} mm over the object during {step.kind}")
            for f, sl in zip(ctx.fingers, slip, strict=True) if sl > tol]


def check_converged_claim(ctx: VerifyContext, k: int, step: PlanStep) -> list[Finding]:
    """A plan that says "converged" ends with a largest stored contact error ≤ zeta, and with the object
    within `pose_tol_position` / `pose_tol_rotation` of the desired pose (the stored last and desired
    poses; verify's tolerances, not the plan's)."""
    if k != len(ctx.plan.steps) - 1 or ctx.plan.status != "converged":
        return []
    tol = ctx.tol
    claimed = float(np.max(step.contact_error))
    dp, dr = pose_error(step.T_palm_object, ctx.plan.goal_T_palm_object)
    out = []
    if claimed > tol.zeta:
        out.append(Finding("", claimed, tol.zeta, f"plan says converged but its last max contact error is "
                                                  f"{claimed * 1e3:.2f} mm > zeta {tol.zeta * 1e3:.2f} mm"))
    if dp > tol.pose_tol_position:
        out.append(Finding("object", dp, tol.pose_tol_position,
                           f"plan says converged but the object ends {dp * 1e3:.2f} mm from the desired "
                           f"position (> {tol.pose_tol_position * 1e3:.2f} mm)"))
    if dr > tol.pose_tol_rotation:
        out.append(Finding("object", dr, tol.pose_tol_rotation, f"plan says converged but the object ends "
                           f"{np.degrees(dr):.2f}° from the desired orientation "
                           f"(> {np.degrees(tol.pose_tol_rotation):.2f}°)"))
    return out


CHECK_TABLE: tuple[Check, ...] = (
    Check("structure", check_structure, needs_geometry=False),  # malformed plan (shapes, fingers, kinds)
    Check("joint_limit", check_joint_limits),
    Check("tip_surface", check_tip_surface),
    Check("clearance", check_clearance),
    Check("contact_consistency", check_contact_consistency),
    Check("contact_error", check_contact_error),
    Check("gait_other_joints", check_gait_other_joints),
    Check("gait_object_moved", check_gait_object_moved),
    Check("gait_step", check_gait_step),
    Check("slip", check_slip),
    Check("self_collision", check_self_collision),
    Check("self_collision_mesh", check_self_collision_mesh),
    Check("slide_path", check_slide_path),
    Check("unstable_gait", check_unstable_gait),
    Check("motion_penetration", motion.check_motion_penetration),  # the motion, sampled: `verify_motion`
    Check("motion_self_collision", motion.check_motion_self_collision),
    Check("motion_joint_limit", motion.check_motion_joint_limits),
    Check("motion_held_contact", motion.check_motion_held_contacts),
    Check("motion_slip", motion.check_motion_slip),
    Check("converged_claim", check_converged_claim),
    Check("goal_side", check_goal_sides),
)
"""Every check, in the order it runs on each step."""

CHECKS = tuple(c.name for c in CHECK_TABLE)
"""Names used in `Violation.check`."""


# ---------------------------------------------------------------------------------------------- metrics
def _record_final_metrics(ctx: VerifyContext) -> None:
    """Final contact errors (exact); NaN for the minima that saw no value (no gait, no sphere)."""
    metrics = ctx.metrics
    err = np.linalg.norm(ctx.exact.p_object_closest[-1] - ctx.plan.goal_contacts_object, axis=1)
    metrics["final_avg_error"] = float(np.mean(err))
    metrics["final_max_error"] = float(np.max(err))
    for key in ("min_holding_quality", "min_clearance", "min_self_clearance", "min_certificate_margin"):
        if not np.isfinite(metrics[key]):
            metrics[key] = float("nan")


# ---------------------------------------------------------------------------------------------- verify
def verify(  # noqa: PLR0913 (one keyword-only argument per tolerance, as `regrasp verify` flags)
    plan: Plan | str | os.PathLike,
    hand: Hand | None = None,
    obj: ObjectModel | None = None,
    *,
    surface_tol: float = 0.5e-3,
    min_clearance: float = 0.0,
    limit_tol: float = 1e-6,
    eta: float = DEFAULT_ETA,
    zeta: float = DEFAULT_ZETA,
    pose_tol_position: float = 2e-3,
    pose_tol_rotation: float = float(np.radians(2.0)),
    max_slip: float = 1e-3,
    contact_consistency_tol: float = 0.5e-3,
    mu: float = constants.MU,
    self_clearance: float | None = 0.0,
    link_meshes: str | Path | None = None,
    max_normal_force: float = MAX_NORMAL_FORCE,
    mass: float | None = None,
    gravity_palm: Any = None,
) -> VerifyReport:
    """Check a plan with exact geometry and verify's own tolerances; never raises for a bad plan, reports it.

    The plan's own options (its ζ, η, ...) are reported in `metrics["plan_options"]` and never used: a
    plan cannot loosen the bounds it is judged by.

    Args:
        plan: the plan, or the path of a plan file (read with `Plan.load`).
        hand: the hand (default: rebuilt from the plan, `problem.plan_models`).
        obj: the object (default: rebuilt from the plan, `problem.plan_models`).
        surface_tol: allowed |exact distance of a tip centre − tip radius|, m.
        min_clearance: required exact distance − radius of every non-tip collision sphere, m.
        limit_tol: slack on joint limits, rad.
        eta: gait step bound on the tip centre, m.
        zeta: largest contact error a plan that says "converged" may end with, m.
        pose_tol_position, pose_tol_rotation: how far (m, rad) a "converged" plan's final object pose may
            be from the desired one.
        max_slip: allowed slide of a fingertip's material over the object (it may roll), m.
        contact_consistency_tol: allowed distance between a stored contact and the exact closest
            point of its tip centre (and between stored and recomputed contact errors), m.
        mu: friction coefficient of the stability check and metrics (verify's, never the plan's).
        max_normal_force: bound on each normal force of the gravity check, N (verify's).
        mass, gravity_palm: the gravity check's object mass, kg, and gravity (3,), palm frame, m/s²
            (default: the plan's, as its object spec is; `verify_stability.stability_setting`).
        self_clearance: required surface distance of every self-collision sphere pair (different fingers,
            a finger and the palm), m; None: no self-collision check (spheres nor meshes).
        link_meshes: a URDF with link meshes (same link and joint names as the hand's, e.g. the vendor
            URDF) for the mesh check; default: the hand's own URDF, if it has link meshes.

    Returns:
        VerifyReport with ok, violations and metrics.

    Raises:
        TypeError: `plan` is neither a Plan nor a path.
        PlanFormatError: the plan file cannot be read (`Plan.load`).
    """
    from regrasp_casadi.problem import plan_models  # lazy: importing verify loads no model code

    plan = _as_plan(plan)
    hand, obj = plan_models(plan, hand, obj)
    tol = Tolerances(surface_tol=float(surface_tol), min_clearance=float(min_clearance),
                     limit_tol=float(limit_tol), eta=float(eta), zeta=float(zeta), max_slip=float(max_slip),
                     pose_tol_position=float(pose_tol_position), pose_tol_rotation=float(pose_tol_rotation),
                     contact_consistency_tol=float(contact_consistency_tol), mu=float(mu),
                     self_clearance=None if self_clearance is None else float(self_clearance),
                     max_normal_force=float(max_normal_force))
    ctx = VerifyContext(plan, hand, obj, tol, link_meshes)
    ctx.stability = stability_setting(plan, obj, mass, gravity_palm, ctx.metrics)
    problem = _plan_form_problem(ctx)
    if problem:
        return _report([Violation(-1, "structure", "", 0.0, 0.0, problem)], ctx.metrics)
    violations = _run_checks(ctx, [c for c in CHECK_TABLE if not c.needs_geometry])
    if violations:
        return _report(violations, ctx.metrics)
    violations = _run_checks(ctx, [c for c in CHECK_TABLE if c.needs_geometry], (record_holding_quality,))
    _record_final_metrics(ctx)
    return _report(violations, ctx.metrics)


def _as_plan(plan: Any) -> Plan:
    """`plan` itself, or the plan read from a file path (str or os.PathLike)."""
    from regrasp_casadi.plan import Plan

    if isinstance(plan, Plan):
        return plan
    if isinstance(plan, (str, os.PathLike)):
        return Plan.load(plan)
    raise TypeError(f"plan: expected a Plan or a plan file path, got {type(plan).__name__}")


def _plan_form_problem(ctx: VerifyContext) -> str:
    """What makes the plan as a whole unreadable (fingers, goal shape, no steps), or ""."""
    plan, fingers = ctx.plan, ctx.fingers
    if tuple(plan.fingers) != fingers:
        return f"plan fingers {plan.fingers} differ from the hand's {fingers}"
    if plan.goal_contacts_object.shape != (len(fingers), 3):
        return f"goal_contacts_object has shape {plan.goal_contacts_object.shape}"
    if not plan.steps:
        return "plan has no steps"
    return ""


def _run_checks(ctx: VerifyContext, checks: list[Check],
                metrics: tuple[Callable[[VerifyContext, int, PlanStep], None], ...] = ()) -> list[Violation]:
    """Run `checks` (then the metric recorders `metrics`) on every step, in step order."""
    out: list[Violation] = []
    for k, step in enumerate(ctx.plan.steps):
        for check in checks:
            out.extend(Violation(k, check.name, str(f.who), float(f.amount), float(f.limit), f.message)
                       for f in check.run(ctx, k, step))
        for record in metrics:
            record(ctx, k, step)
    return out


def _report(V: list[Violation], metrics: dict[str, Any]) -> VerifyReport:
    report = VerifyReport(ok=not V, violations=tuple(V), metrics=metrics)
    log.debug("%s", report.summary())
    return report


class _CallableModule(types.ModuleType):
    """This module, callable as `verify(...)`: `from regrasp_casadi import verify` gives the module
    (Python binds a package's submodule to its attribute of the same name), so calling it must work."""

    def __call__(self, *args, **kwargs) -> VerifyReport:
        return self.verify(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
