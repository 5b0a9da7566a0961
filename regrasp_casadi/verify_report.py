"""What `verify` returns: `Violation` (one failed check) and `VerifyReport` (the verdict, every violation
and the plan's metrics), with its readable summary and JSON-ready dict. Plain data: numpy and the
standard library only (the stability line from `verify_stability`, lazily).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

__all__ = ["Violation", "VerifyReport"]


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
    """Every failed check, in step order (within a step, in `CHECK_TABLE` order)."""
    metrics: dict[str, Any]
    """Figures of the plan: "min_clearance" (m) and "min_clearance_at" ({"step", "who"}), the same for
    self-collision ("min_self_clearance", "min_self_clearance_at", sphere model), "max_mesh_penetration"
    (m) and "mesh_check" (what the mesh check read, or why it was skipped),
    "max_surface_error", "max_gait_step", "max_slip", "final_avg_error", "final_max_error" (m, exact),
    "n_steps", "max_slide_path_error" (m), "min_holding_quality" (least Ferrari–Canny margin of a gait's
    holding fingers, `stability.holding_quality`; NaN without gaits), "min_holding_quality_at",
    "unstable_gaits"; the stability check's "stability" (kind), "stability_checked", "uncertified_steps"
    (indices), "min_certificate_margin", "stored_certificates". "tolerances": the bounds verify judged
    by (`Tolerances` as a dict, m / rad);
    "plan_options": the options the plan says it was planned with (reported, never obeyed)."""

    def summary(self, max_violations: int = 20) -> str:
        """Readable multi-line text: verdict, metrics in mm, the first `max_violations` violations."""
        from regrasp_casadi.verify_stability import stability_summary

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
            f"  self-collision: min sphere clearance {_mm(m.get('min_self_clearance'))} mm"
            + (f" (step {m['min_self_clearance_at']['step']}, {m['min_self_clearance_at']['who']})"
               if m.get("min_self_clearance_at") else "")
            + f"; mesh check: {m.get('mesh_check') or 'n/a'}",
            stability_summary(m),
        ]
        tol, opts = m.get("tolerances") or {}, m.get("plan_options") or {}
        if tol:
            lines.append(f"  judged with zeta {_mm(tol.get('zeta'))} mm, eta {_mm(tol.get('eta'))} mm "
                         f"(the plan's own: zeta {_mm(opts.get('zeta'))} mm, eta {_mm(opts.get('eta'))} mm)")
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
    if isinstance(x, bool) or not isinstance(x, (int, float, np.floating, np.integer)):
        return "n/a"
    return "n/a" if not np.isfinite(x) else f"{x * 1e3:.3f}"

