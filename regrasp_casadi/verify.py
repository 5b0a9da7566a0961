"""Independent exact checks of a regrasp `Plan`: `verify(plan) -> VerifyReport`.

`verify` judges a plan with the exact object mesh (`ObjectModel.closest_points`, distances computed in
millimetres) and the hand's collision spheres, never with the smooth signed distance or the NLP modules.
At every step it checks:

* joint limits (within `limit_tol`);
* every fingertip on the surface: |d(tip centre) − tip radius| ≤ `surface_tol`;
* no other contact or penetration: every non-tip collision sphere (palm included) has
  d(centre) − radius ≥ `min_clearance`;
* the stored contacts equal the exact closest points of the tip centres (≤ `contact_consistency_tol`),
  and the stored contact errors equal the recomputed distances to the goal;
* gait steps: only the named finger's joints move, the object does not, and the tip centre moves at
  most `eta`;
* repose / final steps: each finger's contact on the object moves at most `max_slip` (slip);
* the plan's claims: a "converged" plan's last step has max contact error ≤ `zeta`.

    >>> report = verify(Plan.load("plan.json"))
    >>> print(report.summary()); assert report.ok
"""

from __future__ import annotations

import logging
import sys
import types
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from regrasp_casadi import constants
from regrasp_casadi.problem import plan_models
from regrasp_casadi.stability import holding_quality, torque_reference
from regrasp_casadi.transforms import inv_T, transform_points

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import Plan

__all__ = ["Violation", "VerifyReport", "verify", "CHECKS"]

log = logging.getLogger(__name__)

CHECKS = (
    "structure",  # malformed plan (shapes, fingers, kinds)
    "joint_limit",
    "tip_surface",
    "clearance",
    "contact_consistency",
    "contact_error",
    "gait_other_joints",
    "gait_object_moved",
    "gait_step",
    "slip",
    "converged_claim",
)
"""Names used in `Violation.check`."""

EXACT_TOL = 1e-9
"""Tolerance for "unchanged" (joints of other fingers and object pose during a gait)."""

STEP_TOL = 1e-6
"""Slack on the gait step bound `eta`, m."""

DEFAULT_ETA = constants.ETA
"""Gait step bound used when the plan's options do not say (DESIGN.md: 1 cm), m."""

DEFAULT_ZETA = constants.ZETA
"""Convergence threshold used when the plan's options do not say (DESIGN.md: 6 mm), m."""


@dataclass(frozen=True)
class Violation:
    """One failed check."""

    step: int
    """Index into `plan.steps` (-1: the plan as a whole)."""
    check: str
    """Which check failed (one of `CHECKS`)."""
    who: str
    """The joint, finger or collision-sphere label concerned ("" for the whole step)."""
    amount: float
    """The measured value (m or rad; for clearance the signed clearance, negative = penetration)."""
    limit: float
    """The bound it violates (same unit)."""
    message: str
    """Readable explanation."""


@dataclass(frozen=True)
class VerifyReport:
    """Result of `verify`: `ok` is True iff there is no violation."""

    ok: bool
    """True iff `violations` is empty."""
    violations: tuple[Violation, ...]
    """Every failed check, in step order."""
    metrics: dict[str, Any]
    """Figures of the plan: "min_clearance" (m) and "min_clearance_at" ({"step", "who"}),
    "max_surface_error", "max_gait_step", "max_slip", "final_avg_error", "final_max_error" (m, exact),
    "n_steps", and the stability metric (not a check): "min_holding_quality" (least Ferrari–Canny margin
    of the fingers holding the object during a gait, see `stability.holding_quality`; NaN without
    gaits), "min_holding_quality_at" and "unstable_gaits" (gaits whose holding fingers are not in force
    closure)."""

    def summary(self, max_violations: int = 20) -> str:
        """Readable multi-line text: verdict, metrics in mm, the first `max_violations` violations."""
        m = self.metrics
        where = m.get("min_clearance_at") or {}
        lines = [
            f"verify: {'OK' if self.ok else 'FAILED'} ({len(self.violations)} violations, "
            f"{m.get('n_steps', 0)} steps)",
            f"  min clearance {_mm(m.get('min_clearance'))} mm"
            + (f" (step {where.get('step')}, {where.get('who')})" if where else ""),
            f"  max surface error {_mm(m.get('max_surface_error'))} mm, max gait step "
            f"{_mm(m.get('max_gait_step'))} mm, max slip {_mm(m.get('max_slip'))} mm",
            f"  final contact error avg {_mm(m.get('final_avg_error'))} mm, "
            f"max {_mm(m.get('final_max_error'))} mm",
            f"  stability (metric): {m.get('unstable_gaits', 0)} gaits whose other fingers are not in force "
            f"closure (μ = 0.5); least margin ε {m.get('min_holding_quality', float('nan')):.4f}",
        ]
        for v in self.violations[:max_violations]:
            lines.append(f"  step {v.step}: {v.check} [{v.who}]: {v.message}")
        if len(self.violations) > max_violations:
            lines.append(f"  ... and {len(self.violations) - max_violations} more")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: ok, violations (list of dicts), metrics."""
        return {
            "ok": self.ok,
            "violations": [asdict(v) for v in self.violations],
            "metrics": dict(self.metrics),
        }


def _mm(x: Any) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x * 1e3:.3f}"


def verify(
    plan: Plan,
    hand: Hand | None = None,
    obj: ObjectModel | None = None,
    *,
    surface_tol: float = 0.5e-3,
    min_clearance: float = 0.0,
    limit_tol: float = 1e-6,
    eta: float | None = None,
    max_slip: float = 1e-3,
    contact_consistency_tol: float = 0.5e-3,
    mu: float = 0.5,
) -> VerifyReport:
    """Check a plan with exact geometry; never raises for a bad plan, reports it.

    Args:
        plan: the plan.
        hand: the hand (default: rebuilt from the plan, `problem.plan_models`).
        obj: the object (default: rebuilt from the plan, `problem.plan_models`).
        surface_tol: allowed |exact distance of a tip centre − tip radius|, m.
        min_clearance: required exact distance − radius of every non-tip collision sphere, m.
        limit_tol: slack on joint limits, rad.
        mu: friction coefficient of the stability metric (force closure of the holding fingers).
        eta: gait step bound on the tip centre, m (default `plan.options["eta"]`, else 0.01).
        max_slip: allowed motion of a contact on the object during repose / final steps, m.
        contact_consistency_tol: allowed distance between a stored contact and the exact closest
            point of its tip centre (and between stored and recomputed contact errors), m.

    Returns:
        VerifyReport with ok, violations and metrics.
    """
    hand, obj = plan_models(plan, hand, obj)
    eta = float(plan.options.get("eta", DEFAULT_ETA) if eta is None else eta)
    zeta = float(plan.options.get("zeta", DEFAULT_ZETA))
    V: list[Violation] = []

    def add(step: int, check: str, who: str, amount: float, limit: float, message: str) -> None:
        V.append(Violation(int(step), check, str(who), float(amount), float(limit), message))

    fingers = tuple(hand.fingers)
    m, n = len(fingers), hand.n_joints
    metrics: dict[str, Any] = {
        "min_clearance": float("inf"), "min_clearance_at": None, "max_surface_error": 0.0,
        "max_gait_step": 0.0, "max_slip": 0.0, "final_avg_error": float("nan"),
        "final_max_error": float("nan"), "n_steps": len(plan.steps),
        "min_holding_quality": float("inf"), "min_holding_quality_at": None, "unstable_gaits": 0,
    }
    com, length = torque_reference(obj.mesh)
    if tuple(plan.fingers) != fingers:
        add(-1, "structure", "", 0, 0, f"plan fingers {plan.fingers} differ from the hand's {fingers}")
        return _report(V, metrics)
    if plan.goal_contacts_object.shape != (m, 3):
        add(-1, "structure", "", 0, 0, f"goal_contacts_object has shape {plan.goal_contacts_object.shape}")
        return _report(V, metrics)
    if not plan.steps:
        add(-1, "structure", "", 0, 0, "plan has no steps")
        return _report(V, metrics)
    for k, s in enumerate(plan.steps):
        bad = []
        if s.q.shape != (n,):
            bad.append(f"q has shape {s.q.shape}, expected ({n},)")
        if s.contacts_object.shape != (m, 3) or s.contact_error.shape != (m,):
            bad.append(f"contacts/errors have shapes {s.contacts_object.shape}/{s.contact_error.shape}")
        if s.kind not in ("initial", "gait", "repose", "final") or (k == 0) != (s.kind == "initial"):
            bad.append(f"kind {s.kind!r} at step {k} (only step 0 is 'initial')")
        if s.kind == "gait" and s.finger not in fingers:
            bad.append(f"gait of unknown finger {s.finger!r}")
        if bad:
            add(k, "structure", "", 0, 0, "; ".join(bad))
    if V:
        return _report(V, metrics)

    # ---- all geometry of all steps in one exact query: tip centres then non-tip spheres, object frame
    radii = np.asarray(hand.sphere_radii(), dtype=float)
    labels = list(hand.sphere_labels())
    r_tip = float(hand.tip_radius)
    tips_palm = [np.asarray(hand.tip_positions(s.q), float).reshape(m, 3) for s in plan.steps]
    pts = []
    for s, tp in zip(plan.steps, tips_palm, strict=True):
        T_object_palm = inv_T(s.T_palm_object)
        spheres = np.asarray(hand.sphere_centers(s.q), float).reshape(-1, 3)
        pts.append(transform_points(T_object_palm, np.vstack([tp, spheres])))
    k_pts = m + len(radii)
    closest_all, sd_all = obj.closest_points(np.vstack(pts))
    closest_all = np.asarray(closest_all, float).reshape(len(plan.steps), k_pts, 3)
    sd_all = np.asarray(sd_all, float).reshape(len(plan.steps), k_pts)

    lower, upper = np.asarray(hand.q_lower, float), np.asarray(hand.q_upper, float)
    goal = plan.goal_contacts_object
    for k, s in enumerate(plan.steps):
        # joint limits
        for i in np.flatnonzero((s.q < lower - limit_tol) | (s.q > upper + limit_tol)):
            over = max(lower[i] - s.q[i], s.q[i] - upper[i])
            add(k, "joint_limit", hand.joint_names[i], over, limit_tol,
                f"{hand.joint_names[i]} = {s.q[i]:.6g} rad outside [{lower[i]:.6g}, {upper[i]:.6g}] "
                f"by {over:.3g} rad")
        # fingertips on the surface
        gap = sd_all[k, :m] - r_tip
        metrics["max_surface_error"] = max(metrics["max_surface_error"], float(np.max(np.abs(gap))))
        for f, g in zip(fingers, gap, strict=True):
            if abs(g) > surface_tol:
                where = "above" if g > 0 else "inside"
                add(k, "tip_surface", f, abs(g), surface_tol,
                    f"{f} tip is {abs(g) * 1e3:.2f} mm {where} the surface "
                    f"(tolerance {surface_tol * 1e3:.2f} mm)")
        # every other sphere clear of the object
        clear = sd_all[k, m:] - radii
        if clear.size:
            j = int(np.argmin(clear))
            if clear[j] < metrics["min_clearance"]:
                metrics["min_clearance"] = float(clear[j])
                metrics["min_clearance_at"] = {"step": k, "who": labels[j]}
            for j in np.flatnonzero(clear < min_clearance):
                what = "penetrates the object by" if clear[j] < 0 else "has only"
                add(k, "clearance", labels[j], clear[j], min_clearance,
                    f"sphere {labels[j]} {what} {abs(clear[j]) * 1e3:.2f} mm"
                    + ("" if clear[j] < 0 else f" clearance (< {min_clearance * 1e3:.2f} mm)"))
        # stored contacts vs exact closest points, stored errors vs recomputed
        actual = closest_all[k, :m]
        dev = np.linalg.norm(s.contacts_object - actual, axis=1)
        for f, d in zip(fingers, dev, strict=True):
            if d > contact_consistency_tol:
                add(k, "contact_consistency", f, d, contact_consistency_tol,
                    f"stored {f} contact is {d * 1e3:.2f} mm from the exact closest point of its tip")
        err = np.linalg.norm(actual - goal, axis=1)
        for f, e_stored, e in zip(fingers, s.contact_error, err, strict=True):
            if abs(e_stored - e) > contact_consistency_tol:
                add(k, "contact_error", f, abs(e_stored - e), contact_consistency_tol,
                    f"stored {f} contact error {e_stored * 1e3:.2f} mm, recomputed {e * 1e3:.2f} mm")
        if k == 0:
            continue
        prev = plan.steps[k - 1]
        if s.kind == "gait":
            moving = set(int(i) for i in np.asarray(hand.finger_joints[s.finger]).ravel())
            for i in range(n):
                if i not in moving and abs(s.q[i] - prev.q[i]) > EXACT_TOL:
                    add(k, "gait_other_joints", hand.joint_names[i], abs(s.q[i] - prev.q[i]), EXACT_TOL,
                        f"gait of {s.finger} moved joint {hand.joint_names[i]} "
                        f"by {s.q[i] - prev.q[i]:.3g} rad")
            dT = float(np.max(np.abs(s.T_palm_object - prev.T_palm_object)))
            if dT > EXACT_TOL:
                add(k, "gait_object_moved", s.finger, dT, EXACT_TOL,
                    f"object pose changed during the gait of {s.finger} (max |ΔT| = {dT:.3g})")
            fi = fingers.index(s.finger)
            # stability (a metric, not a check: the paper's method does not guarantee it): force-closure
            # margin of the other fingers, which hold the object while this one is lifted
            T_object_palm = inv_T(prev.T_palm_object)
            eps = holding_quality(closest_all[k - 1, :m], transform_points(T_object_palm, tips_palm[k - 1]),
                                  fi, com, length, mu)
            if eps < metrics["min_holding_quality"]:
                metrics["min_holding_quality"] = eps
                metrics["min_holding_quality_at"] = {"step": k, "who": s.finger}
            metrics["unstable_gaits"] += int(eps <= 0.0)
            step_len = float(np.linalg.norm(tips_palm[k][fi] - tips_palm[k - 1][fi]))
            metrics["max_gait_step"] = max(metrics["max_gait_step"], step_len)
            if step_len > eta + STEP_TOL:
                add(k, "gait_step", s.finger, step_len, eta,
                    f"{s.finger} tip moved {step_len * 1e3:.2f} mm in one gait (eta {eta * 1e3:.2f} mm)")
        else:  # repose / final: contacts must stay where they are on the object
            slip = np.linalg.norm(actual - closest_all[k - 1, :m], axis=1)
            metrics["max_slip"] = max(metrics["max_slip"], float(np.max(slip)))
            for f, sl in zip(fingers, slip, strict=True):
                if sl > max_slip:
                    add(k, "slip", f, sl, max_slip,
                        f"{f} contact slipped {sl * 1e3:.2f} mm on the object during {s.kind}")

    # ---- final figures and the plan's claims
    err = np.linalg.norm(closest_all[-1, :m] - goal, axis=1)
    metrics["final_avg_error"] = float(np.mean(err))
    metrics["final_max_error"] = float(np.max(err))
    last = len(plan.steps) - 1
    if plan.status == "converged":
        claimed = float(np.max(plan.steps[-1].contact_error))
        if claimed > zeta:
            add(last, "converged_claim", "", claimed, zeta,
                f"plan says converged but its last max contact error is {claimed * 1e3:.2f} mm "
                f"> zeta {zeta * 1e3:.2f} mm")
    if not np.isfinite(metrics["min_holding_quality"]):
        metrics["min_holding_quality"] = float("nan")  # no gait
    if not np.isfinite(metrics["min_clearance"]):
        metrics["min_clearance"] = float("nan")
    return _report(V, metrics)


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
