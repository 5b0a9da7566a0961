"""The grasp-synthesis NLP of grasp generation (`grasp_gen`) and its exact-distance correction.

For tip-centre targets x_r + r_tip n_r (object frame) and a pose prior (R₀, t₀) and joint prior q_ref:

    min_{q, δt, a}  Σ_r ||R(a)ᵀ(FK_r(q) − t) − (x_r + r_tip n_r)||² / s² + w_q ||q − q_ref||²
                    + w_t ||δt||² / s² + w_a ||a||²
    s.t.  sd(R(a)ᵀ(FK_r(q) − t)) + δ_r = r_tip                       (each fingertip r)
          sd_c(R(a)ᵀ(c_k(q) − t)) + δ_k − ρ_k ≥ β + margin           (each non-tip sphere k)
          smin_{(a,b) ∈ B} (|c_a(q) − c_b(q)| − ρ_a − ρ_b) ≥ c + margin  (each rigid-body pair B of two
                                                                    fingers or a finger and the palm)
          q_lower ≤ q ≤ q_upper

with t = t₀ + δt, R(a) = R₀·Cay(a) (Cayley map), sd the smooth signed distance of `ObjectModel`
(τ = 2 mm), sd_c its coarse clearance variant (≤ 16 planes per piece) and δ = d_exact − sd at the previous
solution (a local correction, `solver.correct_offsets`): every tip, and every non-tip sphere within
`_NEAR` (5 mm) of the object or of its constraint's bound, gets that offset (either sign); the others only
tighten. (A sphere held at its bound by a conservative model must be corrected even when its exact
clearance exceeds 5 mm: inside the bowl the coarse model is 2–8 mm conservative, more than the ≤ 3.9 mm
the distal link's sphere — radius 15.7 mm, 7.1 mm behind the 14 mm tip sphere — has to spare, so an
uncorrected bound makes the exact-tip rounds infeasible.) The self-collision constraint (self-clearance c,
None: none) is over `Hand.self_collision_pairs(within=c)`, one smooth minimum per rigid-body pair
(`Hand.sphere_pair_distance_function`); it is exact (no offsets), and a grasp counts only when every pair of
`Hand.self_collision_pairs()` keeps c. Later rounds re-centre the pose prior and q_ref
on the solution with large weights (a proximal step) and re-solve; once the spheres are clear and the
tips within 2 mm, Newton steps on the exact distance (each finger's tip moved along its contact normal
by a damped least-norm joint step) put the tips on the surface. The NLP is built once per (hand,
object, β, c) and re-solved from different seeds.

    >>> nlp = grasp_nlp(hand, obj, beta=0.001, self_clearance=0.001)
    >>> solution, why_not = solve_exact(nlp, targets_obj, q0, T_palm_object0)
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from regrasp_casadi import solver as _solver
from regrasp_casadi import terms
from regrasp_casadi.hand import Hand
from regrasp_casadi.nlp_cache import NLPCache
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.self_collision import SelfCollisionConstraint
from regrasp_casadi.transforms import inv_T, make_T, transform_points

__all__ = ["SURFACE_TOL", "GraspNLP", "GraspSolution", "grasp_nlp", "solve_exact", "sphere_offsets"]

log = logging.getLogger(__name__)

SURFACE_TOL = 1e-4
"""Allowed |exact distance of a tip centre − tip radius| of a generated grasp, m (0.1 mm)."""
_MARGIN = 5e-4  # extra clearance demanded of the smooth distance of non-tip spheres, m
_SELF_MARGIN = 2e-4  # extra self-clearance demanded in the NLP (the tips' Newton polish moves the fingers), m
_SCALE = 0.01  # length scale of the objective, m
_CORRECTION_ROUNDS = 5
_NEAR = 5e-3  # a non-tip sphere this close to the object, or to its constraint's bound, is corrected, m
_CLEARANCE_PLANES = 16  # planes per piece of the coarse distance used for the non-tip spheres
_TAU = 2e-3  # smoothing temperature of the NLP's distance, m (the exact-minus-smooth offset removes its bias)
_SOLVER_OPTIONS = _solver.SolverOptions(max_iter=100, tol=1e-10, acceptable_tol=None, acceptable_iter=None,
                                        constr_viol_tol=1e-9, warm_start=False, bound_relax_factor=0.0,
                                        linear_solver=None)
"""Tight tolerances and exact bounds: a generated grasp is checked to 0.1 mm with the exact distance. At
most 100 iterations: on the 7 cm sphere 13 of 16 solves took 8–85 iterations and the other three 275–396
(one infeasible), which cost 4/5 of the time for no more grasps (`generate_grasps(hand, sphere(0.035),
n=3, seed=0, max_attempts=40)` found 3 of 3 with either cap), so a seed that needs more is abandoned."""


@dataclass(frozen=True)
class _Round:
    """What one solve of the grasp NLP is given: the pose prior, the joint prior, the objective weights
    and the exact-distance offsets."""

    R0: NDArray[np.float64]
    t0: NDArray[np.float64]
    q_ref: NDArray[np.float64]
    weights: NDArray[np.float64]  # target, joints, translation, rotation
    delta_tip: NDArray[np.float64]
    delta_sph: NDArray[np.float64]


class GraspNLP:
    """The grasp-synthesis NLP of the module docstring for one (hand, object, β, self-clearance c);
    decision variables x = (q (n,), δt (3,), a (3,)), parameters `layout`."""

    def __init__(self, hand: Hand, obj: ObjectModel, beta: float, self_clearance: float | None = None):
        self.hand, self.obj, self.beta = hand, obj, float(beta)
        self.self_clearance = None if self_clearance is None else float(self_clearance)
        """Clearance of the spheres of different fingers / a finger and the palm, m (None: unconstrained)."""
        n, m = hand.n_joints, len(hand.fingers)
        self.radii = np.asarray(hand.sphere_radii(None, include_tip=False), float)
        k = len(self.radii)
        self.n, self.m, self.k = n, m, k
        # decision variables
        q = ca.MX.sym("q", n)
        dt = ca.MX.sym("dt", 3)
        a = ca.MX.sym("a", 3)
        x = ca.vertcat(q, dt, a)
        # parameters
        self.layout = _solver.ParamLayout([
            ("R0", (3, 3)),  # pose prior: object rotation, palm frame
            ("t0", (3,)),  # pose prior: object position, palm frame, m
            ("targets", (3, m)),  # tip-centre targets (columns), object frame, m
            ("delta_tip", (m,)),  # exact-distance offsets of the tips, m
            ("delta_sph", (k,)),  # exact-distance offsets of the non-tip spheres, m
            ("q_ref", (n,)),  # joint prior, rad
            ("weights", (4,)),  # of the target, joint, translation and rotation terms
        ])
        p, P = self.layout.symbols(ca.MX)
        R0, t0, targets, q_ref, weights = P["R0"], P["t0"], P["targets"], P["q_ref"], P["weights"]
        R = ca.mtimes(R0, terms.cayley_rotation(a))
        t = t0 + dt
        tips_palm = hand.tip_positions_function()(q)
        tips_obj = ca.mtimes(R.T, tips_palm - ca.repmat(t, 1, m))
        sph_palm = hand.sphere_centers_function(None, include_tip=False)(q)
        sph_obj = ca.mtimes(R.T, sph_palm - ca.repmat(t, 1, k))
        sd_tip = obj.signed_distance_map_function(m, _TAU)(tips_obj)
        sd_sph = obj.clearance_distance_function(_CLEARANCE_PLANES, _TAU).map(k)(sph_obj)
        # objective
        f = (weights[0] * ca.sumsqr(tips_obj - targets) / _SCALE**2
             + weights[1] * ca.sumsqr(q - q_ref)
             + weights[2] * ca.sumsqr(dt) / _SCALE**2
             + weights[3] * ca.sumsqr(a))
        # constraints
        g_tip = sd_tip.T + P["delta_tip"] - hand.tip_radius
        g_sph = sd_sph.T + P["delta_sph"] - ca.DM(self.radii)
        g = ca.vertcat(g_tip, g_sph)
        # bounds
        lbg = np.concatenate([np.zeros(m), np.full(k, self.beta + _MARGIN)])
        ubg = np.concatenate([np.zeros(m), np.full(k, np.inf)])
        if self.self_clearance is not None:  # the NLP's margin: the tips' Newton polish moves the fingers
            sc = SelfCollisionConstraint.build(hand, None, self.self_clearance + _SELF_MARGIN)
            g, lbg, ubg = sc.extend(g, lbg, ubg, q, 1.0)
        self.bounds = _solver.Bounds(
            lbx=np.concatenate([hand.q_lower, np.full(3, -0.05), np.full(3, -0.5)]),
            ubx=np.concatenate([hand.q_upper, np.full(3, 0.05), np.full(3, 0.5)]), lbg=lbg, ubg=ubg)
        # solver
        nlp = {"x": x, "p": p, "f": f, "g": g}
        self.solver = _solver.build_solver("grasp_synthesis", nlp, _SOLVER_OPTIONS)
        self.eval_points = ca.Function("grasp_points", [x, p], [tips_obj, sph_obj, sd_tip, sd_sph])

    def pack(self, targets: NDArray[np.float64], rnd: _Round) -> NDArray[np.float64]:
        """p of a solve towards `targets` (m, 3) (tip-centre targets, object frame, m, rows per finger)
        with the priors, weights and offsets of `rnd`."""
        return self.layout.pack(R0=rnd.R0, t0=rnd.t0, targets=np.asarray(targets).T, delta_tip=rnd.delta_tip,
                                delta_sph=rnd.delta_sph, q_ref=rnd.q_ref, weights=rnd.weights)

    def pose(self, x, R0, t0) -> NDArray[np.float64]:
        """Object pose (4, 4), palm frame, at `x` for the pose prior (R0 (3, 3), t0 (3,))."""
        C = np.asarray(terms.cayley_rotation(ca.DM(x[self.n + 3:])))
        return make_T(R0 @ C, t0 + x[self.n:self.n + 3])

    def solve(self, x0, p) -> _solver.SolveResult:
        """One solve from `x0` with the parameters `p` (`pack`)."""
        return _solver.solve(self.solver, x0=x0, p=p, **self.bounds.kwargs())


    def self_clear(self, q) -> bool:
        """Every self-collision pair of the hand (`Hand.self_collision_pairs()`, none pruned) keeps the
        self-clearance at `q` (True without a self-clearance)."""
        if self.self_clearance is None:
            return True
        return bool(np.min(self.hand.self_collision_distances(q), initial=np.inf) >= self.self_clearance)


_NLP_CACHE = NLPCache(max_size=8)
"""The grasp NLPs, one per (hand, object, β, self-clearance)."""


def grasp_nlp(hand: Hand, obj: ObjectModel, beta: float, self_clearance: float | None = None) -> GraspNLP:
    """The grasp NLP of (`hand`, `obj`, `beta` m, `self_clearance` m or None), built on first use and kept
    in a small cache."""
    key = (float(beta), None if self_clearance is None else float(self_clearance))
    return _NLP_CACHE.get("grasp_synthesis", hand, obj, key,
                          lambda: GraspNLP(hand, obj, beta, self_clearance))


@dataclass(frozen=True)
class GraspSolution:
    """The exact checks at one solution of the grasp NLP (after the Newton polish of the tips, if made)."""

    x: NDArray[np.float64]
    """Decision variables (q, δt, a), (n + 6,)."""
    T_palm_object: NDArray[np.float64]
    """Object pose, (4, 4) palm frame."""
    ex_tip: NDArray[np.float64]
    """Exact signed distances of the tip centres, (m,) m."""
    ex_sph: NDArray[np.float64]
    """Exact signed distances of the non-tip sphere centres, (k,) m."""
    sd_tip: NDArray[np.float64]
    """Smooth distances of the tip centres (no offsets), (m,) m."""
    sd_sph: NDArray[np.float64]
    """Smooth distances of the non-tip sphere centres (no offsets), (k,) m."""
    ok: bool
    """The tips are on the surface within `SURFACE_TOL` / 2, the spheres clear β + 0.2 mm and (with a
    self-clearance) every self-collision pair keeps it."""


def solve_exact(nlp: GraspNLP, targets_obj: NDArray[np.float64], q0: NDArray[np.float64],
                T0: NDArray[np.float64]) -> tuple[GraspSolution | None, str]:
    """Solve the grasp NLP from (`q0` (n,) rad, `T0` (4, 4)) towards the tip-centre targets
    `targets_obj` (m, 3) (object frame, m), with exact-distance offset corrections and proximal
    re-centring, until the exact checks hold.

    Returns:
        The solution, or None and why: "nlp_<status>" (a solve failed) or "not_exact" (the checks did
        not hold within the rounds).
    """
    hand, obj = nlp.hand, nlp.obj
    r = hand.tip_radius

    def params(rnd: _Round):
        return nlp.pack(targets_obj, rnd)

    def exact_at(x, rnd: _Round):
        tips_obj, sph_obj, sd_tip, sd_sph = (np.asarray(v) for v in nlp.eval_points(x, params(rnd)))
        return (obj.exact_signed_distance(tips_obj.T), obj.exact_signed_distance(sph_obj.T), sd_tip.ravel(),
                sd_sph.ravel())

    def evaluate(x, rnd: _Round) -> GraspSolution:
        ex_tip, ex_sph, sd_tip, sd_sph = exact_at(x, rnd)
        tip_ok = np.all(np.abs(ex_tip - r) <= 0.5 * SURFACE_TOL)
        sph_ok = np.all(ex_sph - nlp.radii >= nlp.beta + 2e-4)
        if sph_ok and not tip_ok and np.max(np.abs(ex_tip - r)) < 2e-3:
            q_pol = _polish_tips(hand, obj, x[: nlp.n], nlp.pose(x, rnd.R0, rnd.t0))
            if q_pol is not None:  # the polish moves the fingers: it counts only if the spheres stay clear
                x_pol = np.concatenate([q_pol, x[nlp.n:]])
                if np.all(exact_at(x_pol, rnd)[1] - nlp.radii >= nlp.beta + 2e-4):
                    x, tip_ok = x_pol, True
        self_ok = nlp.self_clear(x[: nlp.n])
        return GraspSolution(x, nlp.pose(x, rnd.R0, rnd.t0), ex_tip, ex_sph, sd_tip, sd_sph,
                             bool(tip_ok and sph_ok and self_ok))

    def new_round(x, c: GraspSolution, rnd: _Round) -> _Round:
        log.debug("tip error %.3g mm, min clearance %.3g mm", 1e3 * np.max(np.abs(c.ex_tip - r)),
                  1e3 * np.min(c.ex_sph - nlp.radii))
        delta_sph = sphere_offsets(c.ex_sph, c.sd_sph, rnd.delta_sph, nlp.radii, nlp.beta + _MARGIN)
        # polish: re-centre the pose prior on the solution and pull q towards it (a proximal term), so
        # the tips stay where the offsets were measured and the correction converges
        T_cur = c.T_palm_object
        return _Round(T_cur[:3, :3], T_cur[:3, 3], x[: nlp.n].copy(), np.array([0.01, 10.0, 10.0, 100.0]),
                      c.ex_tip - c.sd_tip, delta_sph)

    first = _Round(T0[:3, :3], T0[:3, 3], q0, np.array([1.0, 0.1, 1.0, 10.0]), np.zeros(nlp.m),
                   np.zeros(nlp.k))
    corr = _solver.correct_offsets(
        lambda x, rnd: nlp.solve(np.concatenate([rnd.q_ref, np.zeros(6)]), params(rnd)), evaluate,
        lambda c: c.ok, new_round, offsets=first, x=np.concatenate([q0, np.zeros(6)]), evaluation=None,
        max_solves=_CORRECTION_ROUNDS, accept=lambda res: res.x if res.success else None)
    if not corr.usable:
        log.debug("grasp NLP round %d: %s", corr.solves - 1, corr.result.status)
        return None, "nlp_" + corr.result.status
    if not corr.converged:
        return None, "not_exact"
    return corr.evaluation, ""


def sphere_offsets(ex_sph, sd_sph, delta_prev, radii, bound: float) -> NDArray[np.float64]:
    """The non-tip spheres' offsets δ (k,) m for the next round, from the exact and smooth distances of
    their centres (k,) m at the last solution, the offsets it was solved with (k,) m, their radii (k,) m
    and the constraint's bound β + margin (m): a sphere within `_NEAR` of the object by exact clearance,
    or whose constraint sd + δ − ρ was within `_NEAR` of the bound, gets δ = d_exact − sd (either sign);
    the others keep min(δ, d_exact − sd) (they only tighten, so a far sphere is not freed where the model
    is conservative)."""
    ex_sph, sd_sph, delta_prev = (np.asarray(v, float) for v in (ex_sph, sd_sph, delta_prev))
    near = (ex_sph - radii < _NEAR) | (sd_sph + delta_prev - radii - bound < _NEAR)
    return np.where(near, ex_sph - sd_sph, np.minimum(delta_prev, ex_sph - sd_sph))


def _polish_tips(hand: Hand, obj: ObjectModel, q, T_palm_object, iters: int = 10):
    """Newton steps on the exact distance: move each tip centre along its contact normal by
    −(d_exact − r_tip) with a damped least-norm step of its finger's joints that are free to move
    (`_free_joint_step`: a joint at a limit that the step would push past is held there, so a finger at
    a limit still corrects with its other joints). Returns q, or None if the tips do not reach
    `SURFACE_TOL` / 2 within `iters` steps."""
    q = np.array(q, float)
    T_object_palm = inv_T(T_palm_object)
    R_palm_object = np.asarray(T_palm_object)[:3, :3]
    q_lower, q_upper = np.asarray(hand.q_lower, float), np.asarray(hand.q_upper, float)
    for _ in range(iters):
        p_object_tips = transform_points(T_object_palm, np.asarray(hand.tip_positions(q)).reshape(-1, 3))
        p_object_closest, d = obj.closest_points(p_object_tips)
        err = np.asarray(d) - hand.tip_radius
        if np.max(np.abs(err)) <= 0.5 * SURFACE_TOL:
            return q
        for i, f in enumerate(hand.fingers):
            v = p_object_tips[i] - p_object_closest[i]
            nv = np.linalg.norm(v)
            n_object = v / nv if nv > 1e-9 else obj.surface_normals(p_object_tips[i:i + 1])[0]
            idx = np.asarray(hand.finger_joints[f])
            J_palm = np.asarray(hand.tip_jacobian(q, f))[:, idx]
            q[idx] = _free_joint_step(J_palm, -err[i] * (R_palm_object @ n_object), q[idx], q_lower[idx],
                                      q_upper[idx])
    return None


def _free_joint_step(J, dp, q, q_lower, q_upper, damping: float = 1e-8):
    """q + dq, dq the damped least-norm solution of J dq = dp (J (3, k), dp (3,) palm frame, m) over the
    joints not held at a limit: a joint the step would push past its limit is set to that limit and the
    rest of dp recomputed without it (at most k passes). With fewer than three free joints only the
    component of dp along its own direction is asked for (one row, n̂ᵀ J dq = |dp|)."""
    q = np.array(q, float)
    free = np.ones(len(q), bool)
    for _ in range(len(q)):
        if not np.any(free):
            return q
        Jf = J[:, free]
        if np.count_nonzero(free) < 3 and np.linalg.norm(dp) > 0:
            u = dp / np.linalg.norm(dp)
            row = u @ Jf
            dq_f = row * (np.linalg.norm(dp) / (row @ row + damping))
        else:
            dq_f = Jf.T @ np.linalg.solve(Jf @ Jf.T + damping * np.eye(3), dp)
        q_new = q.copy()
        q_new[free] += dq_f
        over = free & ((q_new < q_lower) | (q_new > q_upper))
        if not np.any(over):
            return q_new
        q_held = np.clip(q_new[over], q_lower[over], q_upper[over])
        dp = dp - J[:, over] @ (q_held - q[over])  # what the held joints' part-steps already move
        q[over] = q_held
        free &= ~over
    return q
