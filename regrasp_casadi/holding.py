"""The planner's stability checks: the certificate of the fingers that hold the object during a step.

`plan_regrasp` with `PlannerOptions.stability` "force_closure" or "gravity" asks a `Holding` before every
step whether the fingers that stay on the object hold it, and stores the answer in the step
(`PlanStep.certificate`). The holding set of a step is:

* a gait of finger r (it lifts off): every other finger, in the grasp it lifts from;
* a slide of finger r (its tip stays on the surface): every finger, r sliding, at the start and at the
  end of the slide segment. A sliding finger pushes along its normal and drags the object with kinetic
  friction μ along its motion ŝ over the surface, f = f_n (−n + μ ŝ): a frictionless contact of normal
  n' ∝ n − μ ŝ (`stability.sliding_normal`); the direction is the step's motion (of the tip centre, new
  − old), or, where a slide is only considered, the way to the finger's goal;
* a reposing, a final move, the initial grasp: every finger, in the step's grasp.

The contacts are the exact closest points of the tip-sphere centres (`ObjectModel.closest_points`) and the
normals point from them to the centres, as `verify` and `certificates.step_certificates` take them, so a
grasp the planner certifies is the grasp verify recomputes.

Force closure is decided by the Ferrari–Canny margin ε alone (`stability.force_closure_quality`, one
convex hull): the certificate's LP margin s satisfies s ≥ ε (`certificates`), so ε > `FORCE_CLOSURE_TOL`
implies the LP verdict; the planner asks for ε ≥ `HoldingOptions.min_margin`, well above it. Gravity
hold is the full SOCP (`certificates.certify_step`), asked for a weight scale ≥ 1 + `gravity_margin`.

    >>> holding = Holding(hand, obj, "force_closure", HoldingOptions())
    >>> cert = holding.lift(q, T_palm_object, "thumb")          # the others hold while the thumb lifts
    >>> holding.certified(cert), cert.margin
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.certificates import (
    DENSITY,
    FORCE_CLOSURE_TOL,
    GRAVITY,
    MAX_NORMAL_FORCE,
    Certificate,
    certify_step,
    object_mass,
)
from regrasp_casadi.constants import JOINT_TORQUE, MU
from regrasp_casadi.stability import (
    FRICTION_EDGES,
    contact_mu,
    contact_normals,
    force_closure_quality,
    sliding_normal,
    torque_reference,
)
from regrasp_casadi.surface_route import surface_targets

if TYPE_CHECKING:
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel

__all__ = ["StabilityKind", "STABILITY_KINDS", "HoldingOptions", "Holding"]

JOINT_TORQUE_RESERVE = 0.8
"""Share of `constants.JOINT_TORQUE` the gravity certificate lets a holding finger use (the rest is for
the motion and the controller's corrections)."""

StabilityKind = Literal["force_closure", "gravity", "none"]
"""The certificate every step of a plan must have: force closure of the holding contacts, a gravity hold
of the object's weight, or none (the paper's planner)."""

STABILITY_KINDS: tuple[str, ...] = ("force_closure", "gravity", "none")


@dataclass(frozen=True)
class HoldingOptions:
    """Knobs of the planner's stability checks and sliding steps; SI units."""

    mu: float = MU
    """Friction coefficient of the planner's certificates (verify uses its own)."""
    max_normal_force: float = MAX_NORMAL_FORCE
    """Bound on each contact's normal force of the gravity certificate, N."""
    min_normal_force: float = 0.0
    """Gravity: every holding finger presses with at least this in the certificate's forces, N. A finger
    that carries almost nothing is lost to the least tilt (a position-controlled support tips over it);
    0: no reserve. Verify checks the plain certificate (its own μ and force bound)."""
    min_load_share: float = 0.0
    """Gravity: every holding finger presses with at least this fraction of an equal share of the weight,
    m g / k for k holding fingers (the least normal force is the larger of this and `min_normal_force`)."""
    max_joint_torque: float | None = JOINT_TORQUE_RESERVE * JOINT_TORQUE
    """Gravity: every joint torque of a holding finger, τ = Jᵀ f for its tip Jacobian J and the force f it
    presses the object with, stays within this, N·m (by default 80 % of the Allegro's 0.7 N·m, the
    reserve the simulation's grip keeps as well). None: no bound (the certificate of issue 14, which
    verify checks: a finger may then be asked for forces its motors cannot make)."""
    density: float = DENSITY
    """Object density when the problem states no mass, kg/m³ (mass = mesh volume × density)."""
    min_margin: float = 1e-3
    """Force closure: the planner's certified grasps have ε at least this (> `FORCE_CLOSURE_TOL`, so
    that verify's LP, which is ≥ ε, agrees)."""
    gravity_margin: float = 0.02
    """Gravity: the planner's certified grasps hold (1 + this) × the weight."""
    slide: bool = True
    """A finger whose lift is not certified may slide along the surface instead (steps of kind
    "slide"; in their certificate the finger pushes along its normal and drags the object with kinetic
    friction μ along its motion, `stability.sliding_normal`). Slides are what lets the lone opposing
    thumb move, and they are hard to execute with position-controlled fingers. Measured in MuJoCo
    (`simulate`, benchmarks/README.md "tip drift"): a sliding tip stays 1.5–1.8 mm behind a 2 mm
    slide step, held by its own static friction against the soft servos. The shipped problems'
    gravity-support plans with slides converge on 6 of 10 and are held on 0 of 10; without slides
    (False) they converge on 1 of 10 and are held on 5 of 10."""
    kinetic_mu: float = MU
    """Kinetic friction coefficient of a sliding finger: its drag on the object, μ_k per newton of normal
    force along its motion (`stability.sliding_normal`). Not lowered with `mu`: more drag is the safe side."""
    slide_drag_range: bool = True
    """Certify a slide for any drag from none to μ_k f_n (both ends: the holding sets of the two are
    convex in the forces, so every drag between is held too), as verify does: a slide whose balance needs
    the drag's help fails when the drag falls short (at the slide's start and end, or when the contact
    creeps). False: the full drag only (such plans may fail verify's slide certificate)."""
    slide_budget: float = 2.0
    """Largest tip travel of a finger's slides in one round, in gait bounds η (a lifted finger moves at
    most η; a slide is a sequence of steps of at most `slide_step`, each judged like a gait)."""
    slide_step: float = 0.002
    """Longest tip travel of one slide step, m (the plan's steps are its samples)."""
    slide_tol: float = 0.3e-3
    """Largest distance of the sliding tip from the surface along a slide step (the joints moving
    linearly between its ends), m; a longer step is halved until it keeps this."""
    max_contact_slip: float = 0.9e-3
    """A reposing or final move whose tips slide over the object by more than this is refused, m
    (`grasp_metrics.tip_slip`: rolling is not sliding; verify allows 1 mm of slip)."""
    lookahead: bool = True
    """A gait is accepted only where its new contact leaves some finger still to move (this round, else
    the next) with a certified lift; otherwise the gait is retried with a halved step bound."""
    lookahead_tries: int = 3
    """Gait solves per finger with the lookahead (η, η/2, η/4, ...); when none passes, the first is kept."""
    support_search: bool = True
    """While some finger can only slide, a lifted finger goes where that slide stays certified
    (`certified_round._support_target`) rather than straight to its goal."""
    support_candidates: int = 9
    """Surface points the support search tries (the first towards the finger's goal)."""
    search_edges: int = 4
    """Friction-cone edges of the support search's certificates (an inscribed pyramid: its margin is at
    most the 8-edge one; the checks that decide a step use `stability.FRICTION_EDGES`)."""
    support_score: str = "worst"
    """"best": keep the sliders that can slide and let the best one advance; "worst": raise the worst
    slider's margin (its contact and further on)."""
    support_switch: bool = True
    """While the plan makes no progress (every other `stall_escape` iterations without it), the support
    search uses the other `support_score`."""
    staging: bool = True
    """When the plan stalls (`PlannerOptions.stall_limit`), the last resort: a finger that can neither
    lift nor slide to its goal with a certificate (the thumb against three fingers) gets a support
    configuration of the others in which its whole slide is certified (`staging`), and the plan goes
    on for `stall_limit` more iterations."""
    support_advance: float = 0.005
    """How far ahead towards its goal a slider's certificate is tried by the support search, m."""


class Holding:
    """Certificates of the holding sets of candidate steps of one planning run (cached per grasp).

    Args:
        hand, obj: the run's hand and object.
        kind: "force_closure" or "gravity".
        options: the `HoldingOptions`.
        mass: the object's mass, kg (gravity; None: mesh volume × `options.density`).
        gravity_palm: (3,) gravitational acceleration in the palm frame, m/s² (gravity).
    """

    def __init__(self, hand: Hand, obj: ObjectModel, kind: str, options: HoldingOptions,
                 mass: float | None = None, gravity_palm=(0.0, 0.0, -GRAVITY)):
        if kind not in ("force_closure", "gravity"):
            raise ValueError(f"kind: expected 'force_closure' or 'gravity', got {kind!r}")
        self.hand, self.obj, self.kind, self.options = hand, obj, kind, options
        self.fingers = tuple(hand.fingers)
        self.com, self.length = torque_reference(obj.mesh)
        self.mass = object_mass(obj.mesh, mass, options.density) if kind == "gravity" else None
        self.gravity_palm = np.asarray(gravity_palm, float).reshape(3)
        self._grasps: dict[bytes, tuple[NDArray, NDArray]] = {}
        self._certs: dict[tuple, Certificate] = {}
        self.evaluations = 0
        """Certificates computed (cache misses)."""

    # ------------------------------------------------------------------------------------ the checks
    def lift(self, q: NDArray, T_palm_object: NDArray, finger: str) -> Certificate:
        """The fingers other than `finger` in the grasp (q (n,) rad, T_palm_object (4, 4))."""
        hold = tuple(f != finger for f in self.fingers)
        return self._certificate(q, T_palm_object, hold, (False,) * len(self.fingers))

    def slide(self, q: NDArray, T_palm_object: NDArray, finger: str, direction: NDArray | None = None
              ) -> Certificate:
        """Every finger in the grasp, `finger` sliding in `direction` (3,), object frame (its kinetic
        friction drags the object, `sliding_normal`; None: frictionless). With `slide_drag_range`, the
        worse of that and the frictionless slide."""
        hold, sliding = (True,) * len(self.fingers), tuple(f == finger for f in self.fingers)
        drag = self._certificate(q, T_palm_object, hold, sliding, direction)
        if direction is None or not self.options.slide_drag_range or not self.certified(drag):
            return drag
        still = self._certificate(q, T_palm_object, hold, sliding, None)
        return drag if self.certified(still) and drag.margin <= still.margin else still

    def sliding_normal(self, normal: NDArray, direction: NDArray | None) -> NDArray:
        """The frictionless normal (3,) of a contact (outward normal (3,)) sliding in `direction` (3,),
        object frame, with `HoldingOptions.kinetic_mu` (`stability.sliding_normal`)."""
        return sliding_normal(normal, direction, self.options.kinetic_mu)

    def grasp(self, q: NDArray, T_palm_object: NDArray) -> Certificate:
        """Every finger in the grasp."""
        m = len(self.fingers)
        return self._certificate(q, T_palm_object, (True,) * m, (False,) * m)

    def certified(self, cert: Certificate) -> bool:
        """Whether the planner accepts `cert`: ok, with ε ≥ min_margin (force closure) or a weight scale
        ≥ 1 + gravity_margin (gravity)."""
        if not cert.ok or not np.isfinite(cert.margin):
            return False
        if self.kind == "force_closure":
            return cert.margin >= self.options.min_margin
        return cert.margin >= 1.0 + self.options.gravity_margin

    def hypothetical(self, contacts: NDArray, normals: NDArray, T_palm_object: NDArray, hold: NDArray,
                     sliding: NDArray, n_edges: int | None = None) -> Certificate:
        """The certificate of a grasp that is not (yet) a hand configuration: contacts and outward
        normals (m, 3), object frame, object pose (4, 4) (gravity), `hold` and `sliding` (m,) bool;
        friction cones of `n_edges` edges (default `HoldingOptions.search_edges`; the step checks use
        `stability.FRICTION_EDGES`); no joint torque bound (no joint angles to take it from)."""
        self.evaluations += 1
        return self._compute(np.asarray(contacts, float), np.asarray(normals, float), np.asarray(hold, bool),
                             np.asarray(sliding, bool), np.asarray(T_palm_object, float),
                             self.options.search_edges if n_edges is None else int(n_edges))

    def surface_targets(self, tip: NDArray, goal_tip: NDArray, distance: float, n_dirs: int
                        ) -> tuple[NDArray, NDArray, NDArray]:
        """`surface_route.surface_targets` on this object with this hand's tip radius."""
        return surface_targets(self.obj, float(self.hand.tip_radius), tip, goal_tip, distance, n_dirs)

    # ------------------------------------------------------------------------------------ internals
    def contacts(self, q: NDArray, T_palm_object: NDArray) -> tuple[NDArray, NDArray]:
        """The grasp's exact contacts (m, 3) and outward normals (m, 3), object frame (cached)."""
        q, T = np.asarray(q, float), np.asarray(T_palm_object, float)
        key = q.tobytes() + T.tobytes()
        if key not in self._grasps:
            tips = (np.asarray(self.hand.tip_positions(q), float).reshape(-1, 3) - T[:3, 3]) @ T[:3, :3]
            contacts, _ = self.obj.closest_points(tips)
            contacts = np.asarray(contacts, float)
            self._grasps[key] = (contacts, contact_normals(contacts, tips))
        return self._grasps[key]

    def _certificate(self, q, T, hold: tuple[bool, ...], sliding: tuple[bool, ...],
                     direction: NDArray | None = None) -> Certificate:
        q, T = np.asarray(q, float), np.asarray(T, float)
        d = None if direction is None else np.asarray(direction, float).reshape(3)
        key = (q.tobytes(), T.tobytes(), hold, sliding, None if d is None else d.tobytes())
        if key not in self._certs:
            self.evaluations += 1
            contacts, normals = self.contacts(q, T)
            if d is not None:
                normals = normals.copy()
                for j in np.flatnonzero(sliding):
                    normals[j] = self.sliding_normal(normals[j], d)
            maps = self.torque_maps(q, T) if self.kind == "gravity" else None
            self._certs[key] = self._compute(contacts, normals, np.array(hold), np.array(sliding), T,
                                             torque_maps=maps)
        return self._certs[key]

    def torque_maps(self, q: NDArray, T_palm_object: NDArray) -> NDArray | None:
        """(m, J, 3) joint torques of each finger per newton of force its tip presses the object with,
        object frame, N·m/N: J_fᵀ R_palm_object restricted to the finger's J joints (tip-sphere centre
        Jacobian J_f, palm frame; the moment of a tangential force about the centre, tip radius × force,
        is neglected). None without `HoldingOptions.max_joint_torque`."""
        if self.options.max_joint_torque is None:
            return None
        q, R = np.asarray(q, float), np.asarray(T_palm_object, float)[:3, :3]
        J_max = max(len(self.hand.finger_joints[f]) for f in self.fingers)
        maps = np.zeros((len(self.fingers), J_max, 3))
        for i, f in enumerate(self.fingers):
            idx = self.hand.finger_joints[f]
            maps[i, :len(idx)] = (self.hand.tip_jacobian(q, f)[:, idx]).T @ R
        return maps

    def _compute(self, contacts, normals, hold, sliding, T, n_edges: int = FRICTION_EDGES,
                 torque_maps: NDArray | None = None) -> Certificate:
        o = self.options
        if self.kind == "gravity":
            solver = "auto" if n_edges == FRICTION_EDGES else "lp"
            f_min = max(o.min_normal_force, o.min_load_share * self.mass * float(np.linalg.norm(
                self.gravity_palm)) / max(int(np.sum(hold)), 1))
            tau = {} if torque_maps is None else {"torque_maps": torque_maps,
                                                  "max_joint_torque": o.max_joint_torque}
            return certify_step(contacts, normals, hold, "gravity", o.mu, self.mass,
                                T[:3, :3].T @ self.gravity_palm, center=self.com, sliding=sliding,
                                max_normal_force=o.max_normal_force, min_normal_force=f_min, solver=solver,
                                **tau)
        mu_i = contact_mu(o.mu, len(contacts), sliding)[hold]
        eps = force_closure_quality(contacts[hold], normals[hold], mu_i, self.com, self.length, n_edges)
        ok = bool(eps > FORCE_CLOSURE_TOL)
        n_slide = int(np.sum(sliding & hold))
        detail = (f"{'force closure' if ok else 'no force closure'} of {int(hold.sum())} contacts"
                  f"{f' ({n_slide} sliding)' if n_slide else ''}: ε {eps:.3g} (planner, μ {o.mu:g}; "
                  f"LP margin ≥ ε)")
        return Certificate("force_closure", ok, eps, None, detail)
