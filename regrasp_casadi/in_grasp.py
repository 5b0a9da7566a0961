"""OPT2 — in-grasp manipulation: move the whole hand, and the object with it, keeping the contacts.

Two targets: a desired object pose (`method="svd"`: the SVD form of the paper, its target pose from
`svd_target`; also the final in-grasp move, towards the desired pose) or the reachable workspaces of the
fingers (`method="sd"`). The targets, the workspace hulls and the trust region are in `in_grasp_targets`
(re-exported here).

    >>> nlp = InGraspNLP(hand, obj, "svd")                 # built once per (hand, object, method)
    >>> T_target = svd_target(T_palm_object, contacts_object, goal_contacts_object)
    >>> result = nlp.solve(q, T_palm_object, p_object_tips, T_target=T_target)
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from regrasp_casadi import signed_distance, terms
from regrasp_casadi import solver as _solver
from regrasp_casadi.constants import K_ORIENT, K_POS
from regrasp_casadi.convex import LOCAL_PIECES, LOCAL_PLANES
from regrasp_casadi.grasp_metrics import object_contacts, tip_frames, tip_slip
from regrasp_casadi.in_grasp_targets import (
    ROUND_GOAL_PULL,
    WorkspaceHull,
    clip_pose,
    is_round,
    svd_target,
    trust_region,
    workspace_hull,
)
from regrasp_casadi.local_clearance import ClearanceParams, LocalClearance
from regrasp_casadi.self_collision import SelfCollisionConstraint
from regrasp_casadi.signed_distance import DEFAULT_TAU
from regrasp_casadi.stability import contact_normals
from regrasp_casadi.transforms import interpolate_pose, make_T

if TYPE_CHECKING:
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel

__all__ = ["InGraspOptions", "InGraspResult", "InGraspNLP", "WorkspaceHull", "workspace_hull", "svd_target",
           "is_round", "ROUND_GOAL_PULL", "clip_pose", "trust_region"]

_log = logging.getLogger(__name__)

_MM = 1e3  # positions in the objective and distance constraints: m → mm


@dataclass(frozen=True)
class InGraspOptions(_solver.NLPOptions):
    """Knobs of OPT2 (paper §III-B), beyond the NLPs' common ones (β, τ, ...); SI units. `max_corrections`:
    re-solves with exact-distance offsets when a sphere's exact clearance is below β/2."""

    k_pos: float = K_POS
    """k1, weight of the relaxed-rigidity position term E_pos (paper: 1000)."""
    k_orient: float = K_ORIENT
    """k2, weight of the relaxed-rigidity orientation term E_or (paper: 10)."""
    max_translation: float = 0.03
    """Trust region: largest object translation per reposing, per axis, m."""
    max_rotation: float = 0.3
    """Trust region: bound on each component of the Cayley vector tan(θ/2)·axis (0.3 ≈ 33°)."""
    sd_margin: float = 0.02
    """SD method: depth inside its workspace hull each goal tip centre is pulled to, m (0 = the paper's
    max(0, SD); a margin keeps pulling goals that are inside the convex hull but not reachable)."""
    tau_hull: float = 0.002
    """Temperature of the smooth distance to the workspace hulls and of the smooth max(0, ·), m."""
    goal_pull: float | None = None
    """α of `svd_target` in the planner's SVD reposings: how far towards the desired grasp's tip positions
    (palm frame) each reposing brings the goal contacts (0: the paper's target); None: `ROUND_GOAL_PULL`
    on a round object (`is_round`), whose orientation the contacts do not pin, else 0
    (`InGraspNLP.goal_pull`)."""
    max_slip: float = 5e-4
    """A result whose tips slide more than this over the object is rejected, m (`grasp_metrics.tip_slip`,
    as `verify` measures: with `rolling`, a tip may roll its contact along the surface)."""
    surface_tol: float = 2e-4
    """A result whose tip centre is farther than this from the tip radius off the exact surface is
    rejected, m (verify allows 0.5 mm). A rolling tip leaves the local planes taken at its start contact:
    on the 320-face 7 cm ball, 15° turns left 0.09-0.15 mm after the corrections (measured; 0.1 mm
    before the tips rolled)."""
    rolling: bool = True
    """The relaxed rigidity keeps each tip where it rolls to without slipping (its centre moves by ρ θ × n
    as the tip turns by θ relative to the object, `terms.rolling_offset`). False: where it was (the
    paper's fixed contacts: a tip turning over its contact then slides its material over the object by
    ρ θ, which the fixed-contact measure does not see and a physics engine does)."""
    clearance_pieces: int = 2
    """Convex pieces in each non-tip sphere's local plane set (`local_clearance.LocalClearance`)."""
    clearance_local_planes: int = 8
    """Planes per piece in each non-tip sphere's local plane set."""
    offset_radius: float = 0.005
    """σ, m: distance from the start over which a positive exact-distance offset of a sphere fades."""
    clearance_curvature: bool = False
    """`NLPOptions.clearance_curvature`, off: OPT2 per call 63 / 50 → 45 / 43 ms (svd / sd, README)."""
    settled_change: float | None = 1e-3
    """`NLPOptions.settled_change`, on: IPOPT zig-zags along the rolling tips' nearly flat directions for
    tens of iterations after the objective has settled (OPT2 iterations median 15 → 8, benchmarks/README)."""


@dataclass(frozen=True)
class InGraspResult(_solver.SolveStats):
    """The outcome of one in-grasp move; `success`: it is valid with the exact geometry (clearance ≥ 0,
    slip ≤ `max_slip`, tips on the surface)."""

    q: NDArray[np.float64]
    """Joint angles after the move, (n,) rad."""
    T_palm_object: NDArray[np.float64]
    """Object pose after the move, (4, 4)."""
    max_slip: float
    """Largest slip of a tip's material over the object (`grasp_metrics.tip_slip`), m."""
    min_clearance: float
    """Smallest exact distance of a non-tip sphere to the object, m."""
    surface_error: float
    """Largest |SD_exact(tip centre) − tip radius| over the fingers, m."""
    min_self_clearance: float = float("inf")
    """Smallest surface distance of the constrained self-collision sphere pairs, m (inf: none)."""


@dataclass(frozen=True)
class _Evaluation:
    """The exact distances of a point x of OPT2 (see `InGraspNLP._evaluate`)."""

    exact: NDArray[np.float64]
    """(k + m,) exact distances of the sphere centres, non-tip spheres then tips, m."""
    sd_tips: NDArray[np.float64]
    """(m,) smooth distances of the tips on their local planes (no offsets), m."""
    centres: NDArray[np.float64]
    """(k + m, 3) sphere centres, object frame, m."""


@dataclass(frozen=True)
class _Offsets:
    """What the correction loop updates: the clearance model's parameters and the tips' offsets."""

    clearance: ClearanceParams
    delta_tips: NDArray[np.float64]
    """(m,) exact − smooth distance of the tips, m."""


def _param_layout(method: str, clearance: LocalClearance, m: int, n_planes: int) -> _solver.ParamLayout:
    """OPT2's parameters for a hand of `m` fingers, `n_planes` local planes per tip and the non-tip
    spheres' `clearance` model; the target blocks depend on the method."""
    blocks = [
        ("R0_palm_object", (3, 3)),  # object pose at the start, palm frame
        ("t0_palm_object", (3,)),  # m
        ("p_object_tips", (3, m)),  # tip-sphere centres at the start (columns), object frame, m
        ("R_object_tips", (3, 3 * m)),  # tip orientations at the start, object frame: [R_1 | … | R_m]
        ("n_object_tips", (3, m)),  # outward normals at the start contacts, object frame (rolling)
        ("delta_tips", (m,)),  # exact-distance offsets of the tips, m
        ("normals_tips", (3 * n_planes, m)),  # local planes near each tip (columns, as
        ("offsets_tips", (n_planes, m)),  # signed_distance.local_signed_distance reads them)
        *clearance.blocks("clear").items(),  # local planes and offsets of the non-tip spheres
    ]
    if method == "svd":
        blocks += [("R_target", (3, 3)), ("t_target", (3,)),  # target object pose, palm frame
                   ("ell_mm", (1,))]  # ℓ, the object's radius, mm
    else:
        blocks += [("p_object_tips_goal", (3, m))]  # goal tip-sphere centres (columns), object frame, m
    return _solver.ParamLayout(blocks)


def _relaxed_rigidity(hand: Hand, q: ca.SX, tips_palm: ca.SX, pose: tuple[ca.SX, ca.SX], c_tips: ca.SX,
                      R_tips: ca.SX, n_tips: ca.SX | None) -> tuple[ca.SX, ca.SX]:
    """E_pos (mm²) and E_or of the relaxed rigidity: the tips (3, m) at `q` against the start contacts
    `c_tips` (3, m) and orientations `R_tips` (3, 3m), object frame, carried by the object pose (R, t).
    With the outward normals `n_tips` (3, m) at the start contacts, each tip's place is where it rolls
    to without slipping (`terms.rolling_offset`); None: where it was (the paper's)."""
    R, t = pose
    e_pos = 0
    e_or = 0
    for r, finger in enumerate(hand.fingers):
        R_tip = hand.link_rotation_function(hand.tip_links[finger])(q)
        R_start = R_tips[:, 3 * r: 3 * r + 3]
        c = c_tips[:, r]
        if n_tips is not None:
            c = c + terms.rolling_offset(R.T @ R_tip, R_start, n_tips[:, r], hand.tip_radius)
        e_pos += ca.sumsqr(_MM * (tips_palm[:, r] - (R @ c + t)))
        e_or += terms.rotation_error_sq(R_tip, R @ R_start)
    return e_pos, e_or


def _outside_workspaces(hulls: list[WorkspaceHull], R: ca.SX, t: ca.SX, g_tips: ca.SX,
                        o: InGraspOptions) -> ca.SX:
    """E_des of the SD method, mm: Σ_r softplus(SD(R g_r + t, R_r) + margin), the goal tip centres
    `g_tips` (3, m) (object frame) carried by the pose (R, t) against the workspace hulls (palm frame)."""
    e_des = 0
    for r, hull in enumerate(hulls):
        d = signed_distance.hull_signed_distance(hull.normals, hull.offsets, R @ g_tips[:, r] + t,
                                                 o.tau_hull)
        d = d + o.sd_margin
        e_des += _MM * terms.softplus(d, o.tau_hull)
    return e_des


class InGraspNLP:
    r"""OPT2, in-grasp manipulation (Sundaralingam & Hermans, ICRA 2018, §III-B), all joints Θ and the
    object pose (R, t) = (C(w) R₀, t₀ + Δt) as decision variables:

    .. math::
        \min_{\Theta, \Delta t, w} \; E_{des} + k_1 E_{pos}(\Theta) + k_2 E_{or}(\Theta)
        \quad \text{s.t.} \quad \Theta_{min} \preceq \Theta \preceq \Theta_{max},\;
        d_l(R^T(FK_l(\Theta) - t)) - \rho_l \ge \min(\beta, d_l(c_l) - \rho_l) \;\;
        \forall \text{non-tip spheres } l, \;
        SD(R^T(FK_r(\Theta) - t), M) + \delta_r = \rho \;\; \forall \text{fingers } r

    Relaxed rigidity (Sundaralingam & Hermans, 2017): with c_r the tip-sphere centres and
    R_{O,r} the tip orientations in the object frame at the start (c_r taken where the tip touches the
    surface: its contact plus ρ along the contact normal, so that a start tip off the surface within
    ``surface_tol`` does not pull against the tips' surface equality below),
    ``E_pos = Σ_r ||FK_r(Θ) − (R c_r' + t)||²`` (mm²) and ``E_or = Σ_r ||R_r(Θ) − R R_{O,r}||_F²``.
    The paper's c_r' = c_r holds each tip centre at its start point of the object; with ``rolling`` (the
    default, not in the paper) c_r' = c_r + ρ θ_r × n_r, where the tip rolls to without slipping: θ_r the
    rotation vector of (Rᵀ R_r(Θ)) R_{O,r}ᵀ, n_r the outward normal at the start contact, ρ the tip radius
    (`terms.rolling_offset`). A tip held at c_r while it turns slides its material over the object by
    ρ |θ_r|; the move is judged by that slide (`grasp_metrics.tip_slip` ≤ ``max_slip``).

    * ``method="svd"`` (the paper's SVD form, and the final in-grasp move):
      ``E_des = ||t − t*||² + (ℓ²/2) ||R − R*||_F²`` (mm², ℓ the object's radius in mm), with the target
      pose (R*, t*) passed as a parameter: `svd_target` (Kabsch / Besl–McKay), or the desired pose.
      A target beyond the trust region is first moved onto it (along the geodesic), so E_des cannot
      outpull the relaxed rigidity.
    * ``method="sd"``: ``E_des = Σ_r max(0, SD(R g_r + t, R_r) + m)`` (mm), g_r the goal tip centres in
      the object frame, R_r the finger's reachable-workspace hull and m ≥ 0 a margin (``sd_margin``; the
      paper's form is m = 0); max and SD are smoothed (``tau_hull``).

    The tip-on-surface equality is an addition to the paper's OPT2: the relaxed rigidity alone lets a
    tip drift off the surface by ~0.1–1 mm when other constraints are active. A trust region bounds |Δt|
    and |w| per reposing. δ_r are the tips' exact-distance offsets (see FingerGaitNLP); the tips'
    distances use the local planes at their contacts (parameters, `ObjectModel.local_planes`).

    Clearance model (`local_clearance.LocalClearance`): each non-tip sphere l has its own local plane
    set (parameters, selected near its start centre c_l, re-selected near the start and the solution
    between corrections) and ``d_l(p) = s_l(p) + δ⁻_l + δ⁺_l exp(−|p − c_l|²/σ²)``, the exact offset at
    the start split both ways, so that d_l(c_l) is the exact distance: a grasp feasible on the mesh is
    feasible in the model, and a sphere already closer than β keeps at least its start value. After
    each solve the exact distances at the solution correct δ⁻ where the model was optimistic; the move is
    judged with the exact distances. A solution whose objective is not below the start's is replaced by
    the start (with the target at the current pose the grasp stays where it is). IPOPT's Hessian of the
    Lagrangian leaves out the clearance constraints' curvature (``clearance_curvature``).

    Self-collision (not in the paper; `options.self_clearance` = c, None: off): every sphere pair (a, b)
    of two fingers, or of a finger and the palm, in `Hand.self_collision_pairs(within=c)` keeps
    ``|c_a(Θ) − c_b(Θ)| − ρ_a − ρ_b ≥ c``, one smooth minimum per rigid-body pair
    (`self_collision.SelfCollisionConstraint`); a pair already closer than c at the start keeps at least
    its start value (no worse).
    """

    def __init__(self, hand: Hand, obj: ObjectModel, method: Literal["svd", "sd"] = "svd",
                 options: InGraspOptions | None = None):
        if method not in ("svd", "sd"):
            raise ValueError(f"method must be 'svd' or 'sd', got {method!r}")
        self.hand, self.obj, self.method = hand, obj, method
        self.options = o = options or InGraspOptions()
        n, m = hand.n_joints, len(hand.fingers)
        radii = np.asarray(hand.sphere_radii(None), dtype=float)
        k = radii.size
        self._radii, self._k, self._n, self._m = radii, k, n, m
        tau = float(DEFAULT_TAU if o.tau is None else o.tau)
        n_local = self._n_local = LOCAL_PIECES  # pieces per local plane set (an object of fewer repeats
        # its nearest: `convex.select_local_planes`), so that the NLP does not depend on the object
        self.clearance = LocalClearance(obj.pieces, k, o.clearance_pieces, o.clearance_local_planes, tau,
                                        o.offset_radius)
        """The non-tip spheres' clearance model (local plane sets, two-way offsets)."""
        self._ell_mm = _MM * 0.5 * float(np.linalg.norm(obj.mesh.extents))  # ℓ, a parameter

        # decision variables
        q = ca.SX.sym("q", n)
        dt = ca.SX.sym("dt", 3)
        w = ca.SX.sym("w", 3)
        x = ca.vertcat(q, dt, w)
        # parameters
        self.layout = _param_layout(method, self.clearance, m, n_local * LOCAL_PLANES)
        p, P = self.layout.symbols()
        R, t = terms.pose_from_params(P["R0_palm_object"], P["t0_palm_object"], dt, w)

        # objective
        tips_palm = hand.tip_positions_function()(q)  # (3, m)
        e_pos, e_or = _relaxed_rigidity(hand, q, tips_palm, (R, t), P["p_object_tips"], P["R_object_tips"],
                                        P["n_object_tips"] if o.rolling else None)
        if method == "svd":
            e_des = ca.sumsqr(_MM * (t - P["t_target"])) + 0.5 * P["ell_mm"] ** 2 * terms.rotation_error_sq(
                R, P["R_target"])
        else:
            self.hulls = [workspace_hull(hand, f) for f in hand.fingers]
            e_des = _outside_workspaces(self.hulls, R, t, P["p_object_tips_goal"], o)
        f = e_des + o.k_pos * e_pos + o.k_orient * e_or
        # constraints: non-tip spheres keep β; the tips stay on the surface
        s_obj = terms.to_object_frame(R, t, ca.horzcat(hand.sphere_centers_function(None)(q), tips_palm))
        sd_tips = [signed_distance.local_signed_distance(P["normals_tips"][:, r], P["offsets_tips"][:, r],
                                                         s_obj[:, k + r], n_local, tau) for r in range(m)]
        sd_tips = ca.vertcat(*sd_tips)
        _, d_clear = self.clearance.distances(s_obj[:, :k], P, "clear")
        radii_all = np.concatenate([radii, np.full(m, hand.tip_radius)])
        g = _MM * (ca.vertcat(d_clear, sd_tips + P["delta_tips"]) - ca.DM(radii_all))
        lbg = np.concatenate([np.full(k, _MM * o.beta), np.zeros(m)])
        ubg = np.concatenate([np.full(k, np.inf), np.zeros(m)])
        # self-collision: sphere pairs of different fingers and of a finger and the palm
        self.self_collision = SelfCollisionConstraint.build(hand, None, o.self_clearance)
        """The self-collision constraints (None: `self_clearance` None)."""
        if self.self_collision is not None:
            g, lbg, ubg = self.self_collision.extend(g, lbg, ubg, q, _MM)
        # bounds
        big_t, big_w = o.max_translation, o.max_rotation
        self._bounds = _solver.Bounds(
            lbx=np.concatenate([hand.q_lower, np.full(3, -big_t), np.full(3, -big_w)]),
            ubx=np.concatenate([hand.q_upper, np.full(3, big_t), np.full(3, big_w)]), lbg=lbg, ubg=ubg)
        self._radii_all = radii_all
        # solver
        self._solver = _solver.build_solver(  # curvature of the tips and self-collision pairs (rows k:)
            f"in_grasp_{method}", {"x": x, "p": p, "f": f, "g": g}, o.solver_options(),
            None if o.clearance_curvature else np.arange(k, len(lbg)))
        self._points = ca.Function("in_grasp_points", [x, p], [s_obj, sd_tips, R, t], ["x", "p"],
                                   ["p_object_spheres", "sd_tips", "R_palm_object", "t_palm_object"])
        self._objective = ca.Function("in_grasp_objective", [x, p], [f], ["x", "p"], ["f"])
        self._constraints = ca.Function("in_grasp_g", [x, p], [g], ["x", "p"], ["g"])
        self.warm_start = _solver.WarmStart()
        """Multipliers of the last successful solve, for the next one."""
        self._blank = self._placeholder_offsets()

    @functools.cached_property
    def goal_pull(self) -> float:
        """α of `svd_target` for this object: `InGraspOptions.goal_pull`, or when None `ROUND_GOAL_PULL` on a
        round object (`is_round`) and 0 (the paper) on any other (decided once per NLP, not per reposing)."""
        pull = self.options.goal_pull
        return float(pull if pull is not None else ROUND_GOAL_PULL if is_round(self.obj) else 0.0)

    def _placeholder_offsets(self) -> _Offsets:
        """Offsets with placeholder planes, for evaluations that need none (the sphere centres)."""
        k = self._k
        N0, H0 = self.clearance.select(np.zeros((k, 3)))
        zero = np.zeros(k)
        return _Offsets(ClearanceParams(N0, H0, np.zeros((3, k)), zero, zero), np.zeros(self._m))

    def reset(self) -> None:
        """Forget the warm-start multipliers (a new plan starts cold, so plans are reproducible)."""
        self.warm_start.reset()

    def _evaluate(self, x, p) -> _Evaluation:
        """The exact distances (k + m,) of the non-tip spheres, then the tips, the tips' smooth ones (m,)
        (no offsets) and the sphere centres (k + m, 3), object frame, m, at `x`."""
        s_obj, sd_tips, _, _ = self._points(x, p)
        centres = np.asarray(s_obj, float).T
        exact = np.asarray(self.obj.near_signed_distance(centres, self._radii_all + 0.01), float).ravel()
        return _Evaluation(exact, np.asarray(sd_tips, float).ravel(), centres)

    def start_clearance(self, q: ArrayLike, T_palm_object: ArrayLike) -> NDArray[np.float64]:
        """The non-tip spheres' clearance (k,), m, in the NLP's model at the start of a move from the grasp
        (`q` (n,), `T_palm_object` (4, 4)): the first k constraints g/1000 with the model's first
        parameters (`LocalClearance.at_start`), to compare with β."""
        q, T0, k = np.asarray(q, float), np.asarray(T_palm_object, float), self._k
        x = np.concatenate([q, np.zeros(6)])
        blocks = self.layout.unpack(self._param_template())
        blocks.update(R0_palm_object=T0[:3, :3], t0_palm_object=T0[:3, 3])
        start = self._evaluate(x, self.layout.pack(**blocks))
        blocks.update(self.clearance.at_start(start.centres[:k], start.exact[:k]).blocks("clear"))
        return np.asarray(self._constraints(x, self.layout.pack(**blocks)), float).ravel()[:k] / _MM

    def _param_template(self) -> NDArray[np.float64]:
        """A parameter vector with every block filled (identity rotations, the placeholder planes)."""
        blocks = {name: np.zeros(shape) for name, shape in self.layout.shapes.items()}
        blocks.update(self._blank.clearance.blocks("clear"), R0_palm_object=np.eye(3))
        return self.layout.pack(**blocks)

    def solve(self, q: ArrayLike, T_palm_object: ArrayLike, p_object_tips: ArrayLike, *,
              T_target: ArrayLike | None = None,
              p_object_tips_goal: ArrayLike | None = None) -> InGraspResult:
        """Repose the object from the grasp (`q` (n,), `T_palm_object` (4, 4)) whose tip-sphere centres are
        `p_object_tips` (m, 3) (object frame, m), towards `T_target` (4, 4) (method "svd") or so that the
        goal tip centres `p_object_tips_goal` (m, 3) enter the fingers' workspaces (method "sd").

        Method "svd": a target beyond the trust region is moved onto it; if the tips then slide more than
        `max_slip` (fingers that cannot follow a large move), the move is tried again towards a target
        half and a quarter as far."""
        q = np.asarray(q, float)
        T0 = np.asarray(T_palm_object, float)
        c_tips = np.asarray(p_object_tips, float).reshape(self._m, 3)
        R_tips = np.hstack(list(tip_frames(self.hand, q, T0)[1]))  # [R_1 | … | R_m], the same for every try
        contacts = object_contacts(self.obj, c_tips)
        n_tips = contact_normals(contacts, c_tips)
        # the relaxed rigidity holds each tip where it would touch the surface (ρ from its contact, along
        # its normal): a start tip off the surface by up to `surface_tol` would otherwise pull against the
        # tips' surface equality, and a move that only restores it would count as no better than staying
        on_surface = contacts + self.hand.tip_radius * n_tips
        grasp = {"R0_palm_object": T0[:3, :3], "t0_palm_object": T0[:3, 3], "p_object_tips": on_surface.T,
                 "R_object_tips": R_tips, "n_object_tips": n_tips.T, **self._tip_planes(c_tips)}
        if self.method == "sd":
            if p_object_tips_goal is None:
                raise ValueError("method 'sd' needs p_object_tips_goal")
            target = {"p_object_tips_goal": np.asarray(p_object_tips_goal, float).reshape(self._m, 3).T}
            res = self._solve_once(q, grasp, target)
            res.record("opt2")
            return res
        if T_target is None:
            raise ValueError("method 'svd' needs T_target")
        o = self.options
        T_far = clip_pose(T0, np.asarray(T_target, float), *trust_region(o))
        spent = (0.0, 0)
        for fraction in (1.0, 0.5, 0.25):
            T_try = interpolate_pose(T0, T_far, fraction)
            res = self._solve_once(q, grasp, {"R_target": T_try[:3, :3], "t_target": T_try[:3, 3],
                                              "ell_mm": np.array([self._ell_mm])})
            spent = (spent[0] + res.solve_time, spent[1] + res.iterations)
            if res.success or res.max_slip <= o.max_slip:
                break
        res = replace(res, solve_time=spent[0], iterations=spent[1])
        res.record("opt2")  # per-solve statistics (solve_log), when recorded
        return res

    def _solve_once(self, q, grasp: dict, target: dict) -> InGraspResult:
        """One move; `grasp` (the start pose, tips and their local planes) and `target` (pose or goal tip
        centres) are parameter blocks of `layout`. The clearance model is taken at the start (local
        planes, two-way offsets: `LocalClearance.at_start`), a sphere already closer than β keeps at least
        its start value, and after each solve the exact distances correct it (`LocalClearance.correction`)
        and the NLP is solved again from that solution (the offsets change little: from the start, the
        re-solves took a third more IPOPT time on 14 plans, measured)."""
        o, k = self.options, self._k

        def params(off: _Offsets):
            return self.layout.pack(**grasp, **off.clearance.blocks("clear"), delta_tips=off.delta_tips,
                                    **target)

        x_start = np.concatenate([q, np.zeros(6)])
        sc = self.self_collision
        bounds, floor = (self._bounds, None) if sc is None else sc.bounds(self._bounds, q, _MM)
        start = self._evaluate(x_start, params(self._blank))  # the centres do not depend on the planes
        p_start, exact_start = start.centres[:k], start.exact[:k]
        off0 = _Offsets(self.clearance.at_start(p_start, exact_start), start.exact[k:] - start.sd_tips)
        start_gap = exact_start - self._radii

        def solve_with(x, off: _Offsets):  # from the grasp, then each correction from the last solution
            _, model = self.clearance.evaluate(p_start, off.clearance)
            lbg = bounds.lbg.copy()  # a sphere closer than β at the start keeps its start value (no worse)
            lbg[:k] = _MM * _solver.no_worse(o.beta, model - self._radii)
            if floor is not None:  # the same slack for self-collision pairs at their start value
                lbg[lbg.size - floor.size:] -= _MM * _solver.NO_WORSE_SLACK * (floor < sc.clearance)
            b = replace(bounds, lbg=lbg)
            return self.warm_start.solve(self._solver, b, x0=x, p=params(off))

        def new_offsets(x, ev: _Evaluation, off: _Offsets) -> _Offsets:
            clear = self.clearance.correction(off.clearance, p_start, exact_start, ev.centres[:k],
                                              ev.exact[:k])
            return _Offsets(clear, ev.exact[k:] - ev.sd_tips)

        def done(ev: _Evaluation) -> bool:
            gap = ev.exact - self._radii_all  # exact distance − radius
            clear = bool(np.all(gap[:k] >= np.minimum(0.5 * o.beta, start_gap - 1e-5)))
            return clear and bool(np.max(np.abs(gap[k:])) <= 5e-5)

        corr = _solver.correct_offsets(
            solve_with, lambda x, off: self._evaluate(x, params(off)), done, new_offsets, offsets=off0,
            x=x_start, evaluation=start, max_solves=o.max_corrections + 1,
            accept=_solver.clipped_if_finite(self._bounds))
        if corr.x is not x_start and self._no_better(corr.x, x_start, params(off0)):
            corr = replace(corr, x=x_start, evaluation=start)  # staying is a fixed point
        return self._result(corr, grasp, params(self._blank), floor)

    def _no_better(self, x, x_start, p) -> bool:
        """Whether the solution `x` does not lower the objective below the start's (then the start, a
        feasible point of the NLP, is kept: with the target at the current pose the grasp stays)."""
        f = float(self._objective(x, p))
        f_start = float(self._objective(x_start, p))
        return not f < f_start - 1e-9 * max(1.0, abs(f_start))

    def _tip_planes(self, p_object_tips: NDArray) -> dict:
        """The "normals_tips" and "offsets_tips" parameter blocks: the local planes nearest each tip
        centre (m, 3), object frame (`ObjectModel.local_planes`)."""
        planes = [self.obj.local_planes(c[None], self._n_local) for c in p_object_tips]
        return {"normals_tips": np.stack([N.ravel() for N, _ in planes], axis=1),
                "offsets_tips": np.stack([h.ravel() for _, h in planes], axis=1)}

    def _slip(self, grasp: dict, q_new: NDArray, T_new: NDArray) -> float:
        """The largest slip of a tip's material over the object from the start `grasp` (its parameter
        blocks) to (q_new, T_new), m (`grasp_metrics.tip_slip`, the mean of the start and end normals)."""
        p_a, n_a = grasp["p_object_tips"].T, grasp["n_object_tips"].T
        R_a = grasp["R_object_tips"].reshape(3, self._m, 3).transpose(1, 0, 2)
        p_b, R_b = tip_frames(self.hand, q_new, T_new)
        n_b = contact_normals(object_contacts(self.obj, p_b), p_b)
        return float(np.max(tip_slip(p_a, R_a, p_b, R_b, n_a + n_b, self.hand.tip_radius)))

    def _result(self, corr: _solver.Correction, grasp: dict, p_zero: NDArray, floor) -> InGraspResult:
        """The move's result from the correction loop's last point, judged with the exact distances."""
        o = self.options
        x, exact = corr.x, corr.evaluation.exact
        _, _, R_new, t_new = self._points(x, p_zero)  # (`exact` is already at x)
        T_new = make_T(np.asarray(R_new), np.asarray(t_new).ravel())
        surface_error = float(np.max(np.abs(exact[self._k:] - self.hand.tip_radius)))
        q_new = x[: self._n]
        max_slip = self._slip(grasp, q_new, T_new) if np.all(np.isfinite(x)) else float("inf")
        min_clear = float(np.min(exact[: self._k] - self._radii)) if self._k else float("inf")
        # accepted when the exact checks hold, whatever IPOPT's status (e.g. a converged point reported
        # as Search_Direction_Becomes_Too_Small is still a valid reposing)
        ok = bool(np.all(np.isfinite(x)) and min_clear >= 0.0 and max_slip <= o.max_slip
                  and surface_error <= o.surface_tol)
        sc, min_self = self.self_collision, float("inf")
        if sc is not None and np.all(np.isfinite(q_new)):
            min_self = sc.min_distance(q_new)
            ok = ok and sc.holds(q_new, floor)
        return InGraspResult(q=q_new, T_palm_object=T_new, status=corr.status, success=ok,
                             iterations=corr.iterations, solve_time=corr.solve_time, max_slip=max_slip,
                             min_clearance=min_clear, surface_error=surface_error,
                             min_self_clearance=min_self)
