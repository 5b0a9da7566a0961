"""Grasp generation: feasible four-finger precision grasps on any object, and regrasp pairs.

A generated grasp G = (X, o, Θ) satisfies, checked with the *exact* mesh distance (never the smooth one):

* every fingertip contact sphere touches the surface: |d_exact(tip centre) − r_tip| ≤ `SURFACE_TOL`
  (0.1 mm);
* no other hand–object contact: every non-tip collision sphere of the hand (palm included) keeps
  d_exact(centre) − radius ≥ β (1 mm by default);
* joints within their limits;
* the grasp can hold the object: **force closure** with Coulomb friction μ (0.5), see `grasp_quality`.

How (one attempt): sample an object pose in front of the palm (an orientation aligned with the object's
oriented bounding box plus a random tilt, a random position where the fingertip workspaces reach it),
pick one contact target per finger among sampled surface points that the finger can reach (tip
workspace samples over the joint limits), with the fingers on one side and the thumb (`hand.thumb`)
opposite them, keeping only target sets that are themselves in force closure, then solve with IPOPT

    min_{q, δt, a}  Σ_r ||R(a)ᵀ(FK_r(q) − t) − (x_r + r_tip n_r)||² / s² + w_q ||q − q_ref||²
                    + w_t ||δt||² / s² + w_a ||a||²
    s.t.  sd(R(a)ᵀ(FK_r(q) − t)) + δ_r = r_tip                       (each fingertip r)
          sd_c(R(a)ᵀ(c_k(q) − t)) + δ_k − ρ_k ≥ β + margin           (each non-tip sphere k)
          q_lower ≤ q ≤ q_upper

with t = t₀ + δt, R(a) = R₀·Cay(a) (Cayley map), sd the smooth signed distance of `ObjectModel`
(τ = 2 mm), sd_c its coarse clearance variant (≤ 16 planes per piece) and δ = d_exact − sd at the previous
solution (a local correction). Later rounds re-centre the pose prior and q_ref on the solution with large
weights (a proximal step) and re-solve; once the spheres are clear and the tips within 2 mm, Newton
steps on the exact distance (each finger's tip moved along its contact normal by a damped least-norm
joint step) put the tips on the surface. The NLP is built once per (hand, object, β) and re-solved from
different seeds. Same seed → same grasps (for the same hand and object models).

    >>> grasps = generate_grasps(Hand.allegro_right(), ObjectModel.box((0.06, 0.06, 0.12)), n=3, seed=0)
    >>> pairs = generate_regrasp_pairs(hand, obj, n_pairs=2, seed=0)
"""

from __future__ import annotations

import collections
import logging
from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from regrasp_casadi import solver as _solver
from regrasp_casadi import terms
from regrasp_casadi.constants import BETA, MU
from regrasp_casadi.errors import GraspError
from regrasp_casadi.grasp import Grasp
from regrasp_casadi.hand import Hand
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.stability import FRICTION_EDGES, force_closure_quality, torque_reference
from regrasp_casadi.transforms import exp_so3, inv_T, make_T, transform_points

__all__ = [
    "SURFACE_TOL",
    "force_closure_quality",
    "grasp_quality",
    "generate_grasps",
    "generate_regrasp_pairs",
]

log = logging.getLogger(__name__)

SURFACE_TOL = 1e-4
"""Allowed |exact distance of a tip centre − tip radius| of a generated grasp, m (0.1 mm)."""
_N_WORKSPACE = 20000  # joint samples for the fingertip workspaces
_N_SURFACE = 3000  # surface samples for contact targets
_REACH_TOL = 0.006  # a target is reachable if a workspace sample lies within this distance, m
_TIP_SPACING = 0.03  # minimum distance between two fingertip targets, m
_MARGIN = 5e-4  # extra clearance demanded of the smooth distance of non-tip spheres, m
_SCALE = 0.01  # length scale of the objective, m
_MIN_QUALITY = 1e-3  # force-closure margin a generated grasp must exceed
_CONE_SHRINK = float(np.cos(np.pi / FRICTION_EDGES))
"""Generated grasps are tested with μ·cos(π/8): the circle of that radius lies inside every 8-edge
polygon of radius μ, so the grasp is in force closure however the linearised cones are turned."""
_CORRECTION_ROUNDS = 5
_CLEARANCE_PLANES = 16  # planes per piece of the coarse distance used for the non-tip spheres
_TAU = 2e-3  # smoothing temperature of the NLP's distance, m (the exact-minus-smooth offset removes its bias)
_SOLVER_OPTIONS = _solver.SolverOptions(max_iter=400, tol=1e-10, acceptable_tol=None, acceptable_iter=None,
                                        constr_viol_tol=1e-9, warm_start=False, bound_relax_factor=0.0,
                                        linear_solver=None)
"""Tight tolerances and exact bounds: a generated grasp is checked to 0.1 mm with the exact distance."""


# ------------------------------------------------------------------------------------ force closure
def grasp_quality(grasp: Grasp, mu: float = MU) -> float:
    """Force-closure margin ε of a grasp (see `force_closure_quality`); > 0 means force closure.

    Normals: the direction from each contact to its fingertip sphere centre when the grasp has joints
    (the contact normal of a sphere tip), else the outward normal of the closest mesh face. Torques are
    taken about the object's centre of mass and scaled by L = the radius of the object's bounding
    sphere about that point (its largest vertex distance).

    Args:
        grasp: the grasp.
        mu: Coulomb friction coefficient.
    """
    c = np.asarray(grasp.contacts_object, float)
    normals = None
    if grasp.q is not None:
        tips = np.asarray(grasp.tip_centers_object, float)
        d = tips - c
        norm = np.linalg.norm(d, axis=1, keepdims=True)
        if np.all(norm > 1e-6):
            normals = d / norm
    if normals is None:
        normals = np.asarray(grasp.obj.surface_normals(c), float)
    com, length = torque_reference(grasp.obj.mesh)
    return force_closure_quality(c, normals, mu, com, length)


# ------------------------------------------------------------------------------------------- NLP
class _GraspNLP:
    """The grasp-synthesis NLP of the module docstring, built once per (hand, object, β)."""

    def __init__(self, hand: Hand, obj: ObjectModel, beta: float):
        self.hand, self.obj, self.beta = hand, obj, float(beta)
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
        self.lbg = np.concatenate([np.zeros(m), np.full(k, self.beta + _MARGIN)])
        self.ubg = np.concatenate([np.zeros(m), np.full(k, np.inf)])
        self.lbx = np.concatenate([hand.q_lower, np.full(3, -0.05), np.full(3, -0.5)])
        self.ubx = np.concatenate([hand.q_upper, np.full(3, 0.05), np.full(3, 0.5)])
        # solver
        nlp = {"x": x, "p": p, "f": f, "g": g}
        self.solver = _solver.build_solver("grasp_synthesis", nlp, _SOLVER_OPTIONS)
        self.bounds = _solver.Bounds(self.lbx, self.ubx, self.lbg, self.ubg)
        self.eval_points = ca.Function("grasp_points", [x, p], [tips_obj, sph_obj, sd_tip, sd_sph])

    def pack(self, R0, t0, targets, delta_tip, delta_sph, q_ref, weights) -> NDArray[np.float64]:
        """p of a solve; `targets` (m, 3) tip-centre targets, object frame, m (rows per finger)."""
        return self.layout.pack(R0=R0, t0=t0, targets=np.asarray(targets).T, delta_tip=delta_tip,
                                delta_sph=delta_sph, q_ref=q_ref, weights=weights)

    def pose(self, x, R0, t0) -> NDArray[np.float64]:
        C = np.asarray(terms.cayley_rotation(ca.DM(x[self.n + 3:])))
        return make_T(R0 @ C, t0 + x[self.n:self.n + 3])

    def solve(self, x0, p) -> _solver.SolveResult:
        return _solver.solve(self.solver, x0=x0, p=p, **self.bounds.kwargs())


_STATS: collections.Counter = collections.Counter()
"""Outcome counts of generation attempts in this process (diagnostics)."""

_NLP_CACHE = _solver.NLPCache(max_size=8)
"""The grasp NLPs, one per (hand, object, β)."""


def _grasp_nlp(hand: Hand, obj: ObjectModel, beta: float) -> _GraspNLP:
    return _NLP_CACHE.get("grasp_synthesis", hand, obj, float(beta), lambda: _GraspNLP(hand, obj, beta))


# ------------------------------------------------------------------------------ sampling helpers
@dataclass
class _Workspace:
    """Joint samples over the limits and, per finger, tip centres (palm frame) with a KD-tree."""

    Q: NDArray[np.float64]  # (N, n)
    tips: dict[str, NDArray[np.float64]]  # finger -> (N, 3)
    trees: dict[str, cKDTree]


_WORKSPACES: dict[int, tuple[Hand, _Workspace]] = {}


def _workspace(hand: Hand) -> _Workspace:
    hit = _WORKSPACES.get(id(hand))
    if hit is not None and hit[0] is hand:
        return hit[1]
    rng = np.random.default_rng(12345)
    Q = rng.uniform(hand.q_lower, hand.q_upper, size=(_N_WORKSPACE, hand.n_joints))
    m = len(hand.fingers)
    out = np.asarray(hand.tip_positions_function().map(_N_WORKSPACE)(Q.T))  # (3, N*m)
    T = out.reshape(3, _N_WORKSPACE, m)
    tips = {f: np.ascontiguousarray(T[:, :, i].T) for i, f in enumerate(hand.fingers)}
    ws = _Workspace(Q, tips, {f: cKDTree(v) for f, v in tips.items()})
    _WORKSPACES[id(hand)] = (hand, ws)
    return ws


def _random_rotation(rng: np.random.Generator) -> NDArray[np.float64]:
    qv = rng.normal(size=4)
    w, x, y, z = qv / np.linalg.norm(qv)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _signed_permutations() -> list[NDArray[np.float64]]:
    import itertools

    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            P = np.zeros((3, 3))
            P[np.arange(3), perm] = signs
            if np.linalg.det(P) > 0:
                out.append(P)
    return out


_PERMS = _signed_permutations()


@dataclass
class _ObjectData:
    points: NDArray[np.float64]  # (s, 3) object frame
    normals: NDArray[np.float64]
    com: NDArray[np.float64]
    length: float  # bounding radius about the centre of mass, m (torque scale of the quality)
    R_obb: NDArray[np.float64]  # object <- OBB axes
    palm_centers: NDArray[np.float64]  # (p, 3) palm-fixed sphere centres, palm frame
    palm_radii: NDArray[np.float64]


_OBJECT_DATA: dict[tuple[int, int], tuple[ObjectModel, _ObjectData]] = {}


def _object_data(hand: Hand, obj: ObjectModel) -> _ObjectData:
    hit = _OBJECT_DATA.get((id(hand), id(obj)))
    if hit is not None and hit[0] is obj:
        return hit[1]
    pts, nrm = obj.sample_surface(_N_SURFACE, seed=0)
    obb = obj.mesh.bounding_box_oriented.primitive.transform
    fixed = [i for i, s in enumerate(hand.spheres) if s.finger is None and not s.is_tip]
    centers = np.array([hand.spheres[i].center_link for i in fixed]).reshape(-1, 3)
    radii = np.array([hand.spheres[i].radius for i in fixed])
    com, length = torque_reference(obj.mesh)
    data = _ObjectData(np.asarray(pts), np.asarray(nrm), com, length, np.asarray(obb)[:3, :3], centers, radii)
    _OBJECT_DATA[(id(hand), id(obj))] = (obj, data)
    return data


def _sample_pose(hand, obj, data, rng, guess) -> NDArray[np.float64]:
    """Object pose in the palm frame: OBB-aligned orientation with a tilt, centre in `hand.grasp_region`."""
    if guess is not None:
        T = np.asarray(guess, float)
        R = T[:3, :3] @ exp_so3(rng.normal(scale=0.12, size=3))
        t = T[:3, 3] + rng.normal(scale=0.008, size=3)
        return make_T(R, t)
    if rng.random() < 0.75:
        R = _PERMS[rng.integers(len(_PERMS))] @ data.R_obb.T
        R = exp_so3(rng.normal(scale=0.25, size=3)) @ R
    else:
        R = _random_rotation(rng)
    # the hand's grasp region (hand.yaml; Allegro: in front of the palm, between the thumb and the fingers)
    lower, upper = hand.grasp_region
    c = np.array([rng.uniform(lower[k], upper[k]) for k in range(3)])
    t = c - R @ data.com
    T = make_T(R, t)
    # push away from the palm until its fixed spheres clear the object by 5 mm
    for _ in range(20):
        d = obj.exact_signed_distance(transform_points(inv_T(T), data.palm_centers)) - data.palm_radii
        if np.min(d) >= 0.005:
            break
        T[0, 3] += 0.005 - float(np.min(d)) + 1e-3
    return T


def _pick_targets(hand, data, ws, T, rng, avoid, min_mean_distance, mu, tries: int = 12):
    """Target indices whose own contacts (surface points, face normals) are in force closure."""
    for _ in range(tries):
        idx = _pick_targets_once(hand, data, ws, T, rng, avoid, min_mean_distance)
        if idx is not None and force_closure_quality(data.points[idx], data.normals[idx], mu * _CONE_SHRINK,
                                                     data.com, data.length) > 2 * _MIN_QUALITY:
            return idx
    return None


def _pick_targets_once(hand, data, ws, T, rng, avoid, min_mean_distance):
    """Contact targets (surface point, normal) per finger, object frame; None if none fit.

    The non-thumb fingers get reachable targets ≥ `_TIP_SPACING` apart; the thumb gets a reachable target
    whose inward line of action passes near the fingers' centroid and whose normal opposes theirs.
    """
    fingers = list(hand.fingers)
    thumb = hand.thumb if hand.thumb is not None else fingers[-1]  # no thumb in the metadata: the last
    r = hand.tip_radius
    P = transform_points(T, data.points)
    N = data.normals @ T[:3, :3].T
    goals = P + r * N
    reach = {}
    for f in fingers:
        dist, _ = ws.trees[f].query(goals, k=1)
        ok = dist <= _REACH_TOL
        if avoid is not None:
            dd = np.linalg.norm(data.points - avoid[fingers.index(f)], axis=1)
            ok &= dd >= min_mean_distance
        reach[f] = np.nonzero(ok)[0]
        if len(reach[f]) == 0:
            return None
    chosen: dict[str, int] = {}
    for f in (f for f in fingers if f != thumb):
        cand = reach[f]
        for i in chosen.values():
            cand = cand[np.linalg.norm(goals[cand] - goals[i], axis=1) >= _TIP_SPACING]
        if len(chosen):
            n_mean = np.mean([N[i] for i in chosen.values()], axis=0)
            cand = cand[N[cand] @ n_mean >= 0.3]
        if len(cand) == 0:
            return None
        chosen[f] = int(rng.choice(cand))
    fi = list(chosen.values())
    centroid = P[fi].mean(axis=0)
    n_fingers = N[fi].mean(axis=0)
    n_fingers /= max(np.linalg.norm(n_fingers), 1e-9)
    cand = reach[thumb]
    gap = np.min(np.linalg.norm(goals[cand][:, None] - goals[fi][None], axis=2), axis=1)
    cand = cand[gap >= _TIP_SPACING]
    cand = cand[N[cand] @ n_fingers <= -0.5]
    if len(cand) == 0:
        return None
    v = centroid - P[cand]
    line_dist = np.linalg.norm(v - np.sum(v * -N[cand], axis=1, keepdims=True) * -N[cand], axis=1)
    best = cand[np.argsort(line_dist)[: max(3, len(cand) // 10)]]
    chosen[thumb] = int(rng.choice(best))
    idx = np.array([chosen[f] for f in fingers])
    return idx


def _initial_q(hand, ws, goals_palm, rng) -> NDArray[np.float64]:
    """Joint guess: each finger from a workspace sample near its target (random among the 8 nearest)."""
    q = 0.5 * (hand.q_lower + hand.q_upper)
    for i, f in enumerate(hand.fingers):
        _, j = ws.trees[f].query(goals_palm[i], k=8)
        pick = int(np.atleast_1d(j)[rng.integers(len(np.atleast_1d(j)))])
        idx = np.asarray(hand.finger_joints[f])
        q[idx] = ws.Q[pick, idx]
    return q


# --------------------------------------------------------------------------------------- attempt
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


@dataclass(frozen=True)
class _Check:
    """The exact checks at one solution (after the Newton polish of the tips, if it was made)."""

    x: NDArray[np.float64]
    T_palm_object: NDArray[np.float64]
    ex_tip: NDArray[np.float64]
    ex_sph: NDArray[np.float64]
    sd_tip: NDArray[np.float64]
    sd_sph: NDArray[np.float64]
    ok: bool


def _attempt(hand, obj, nlp, data, ws, rng, mu, guess, avoid, min_mean_distance) -> Grasp | None:
    T0 = _sample_pose(hand, obj, data, rng, guess)
    idx = _pick_targets(hand, data, ws, T0, rng, avoid, min_mean_distance, mu)
    if idx is None:
        _STATS["no_targets"] += 1
        return None
    targets_obj = data.points[idx] + hand.tip_radius * data.normals[idx]
    q0 = _initial_q(hand, ws, transform_points(T0, targets_obj), rng)
    check = _solve_exact(hand, obj, nlp, targets_obj, q0, T0)
    if check is None:
        return None
    q = np.clip(check.x[: nlp.n], hand.q_lower, hand.q_upper)
    try:
        grasp = Grasp.from_joints(hand, obj, q, check.T_palm_object, tol=SURFACE_TOL)
    except GraspError as exc:
        log.debug("rejected: %s", exc)
        return None
    if not _non_tip_clear(grasp, nlp.beta):
        _STATS["contact"] += 1
        return None
    quality = grasp_quality(grasp, mu * _CONE_SHRINK)
    if quality <= _MIN_QUALITY:
        log.debug("rejected: force-closure margin %.4g", quality)
        _STATS["force_closure"] += 1
        return None
    _STATS["ok"] += 1
    return grasp


def _solve_exact(hand, obj, nlp: _GraspNLP, targets_obj, q0, T0) -> _Check | None:
    """Solve the grasp NLP from (q0, T0) towards the tip targets, with exact-distance offset corrections
    and proximal re-centring, until the exact checks hold; None if they do not within the rounds."""
    r = hand.tip_radius

    def params(rnd: _Round):
        return nlp.pack(rnd.R0, rnd.t0, targets_obj, rnd.delta_tip, rnd.delta_sph, rnd.q_ref, rnd.weights)

    def evaluate(x, rnd: _Round) -> _Check:
        tips_obj, sph_obj, sd_tip, sd_sph = (np.asarray(v) for v in nlp.eval_points(x, params(rnd)))
        ex_tip = obj.exact_signed_distance(tips_obj.T)
        ex_sph = obj.exact_signed_distance(sph_obj.T)
        tip_ok = np.all(np.abs(ex_tip - r) <= 0.5 * SURFACE_TOL)
        sph_ok = np.all(ex_sph - nlp.radii >= nlp.beta + 2e-4)
        if sph_ok and not tip_ok and np.max(np.abs(ex_tip - r)) < 2e-3:
            q_pol = _polish_tips(hand, obj, x[: nlp.n], nlp.pose(x, rnd.R0, rnd.t0))
            if q_pol is not None:
                x = np.concatenate([q_pol, x[nlp.n:]])
                tip_ok = True
        return _Check(x, nlp.pose(x, rnd.R0, rnd.t0), ex_tip, ex_sph, sd_tip.ravel(), sd_sph.ravel(),
                      bool(tip_ok and sph_ok))

    def new_round(x, c: _Check, rnd: _Round) -> _Round:
        log.debug("tip error %.3g mm, min clearance %.3g mm", 1e3 * np.max(np.abs(c.ex_tip - r)),
                  1e3 * np.min(c.ex_sph - nlp.radii))
        # spheres near the object get the exact-minus-smooth offset (either sign); far ones only tighten
        near = c.ex_sph - nlp.radii < 0.005
        delta_sph = np.where(near, c.ex_sph - c.sd_sph, np.minimum(rnd.delta_sph, c.ex_sph - c.sd_sph))
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
        _STATS["nlp_" + corr.result.status] += 1
        return None
    if not corr.converged:
        _STATS["not_exact"] += 1
        return None
    return corr.evaluation


def _polish_tips(hand: Hand, obj: ObjectModel, q, T_palm_object, iters: int = 6):
    """Newton steps on the exact distance: move each tip centre along its contact normal by
    −(d_exact − r_tip) with a damped least-norm step of its finger's joints. Returns q, or None if the
    tips do not reach `SURFACE_TOL` / 2 within joint limits."""
    q = np.array(q, float)
    T_object_palm = inv_T(T_palm_object)
    R = np.asarray(T_palm_object)[:3, :3]
    for _ in range(iters):
        tips = transform_points(T_object_palm, np.asarray(hand.tip_positions(q)).reshape(-1, 3))
        closest, d = obj.closest_points(tips)
        err = np.asarray(d) - hand.tip_radius
        if np.max(np.abs(err)) <= 0.5 * SURFACE_TOL:
            return q
        for i, f in enumerate(hand.fingers):
            v = tips[i] - closest[i]
            nv = np.linalg.norm(v)
            n_obj = v / nv if nv > 1e-9 else obj.surface_normals(tips[i:i + 1])[0]
            idx = np.asarray(hand.finger_joints[f])
            J = np.asarray(hand.tip_jacobian(q, f))[:, idx]
            dq = J.T @ np.linalg.solve(J @ J.T + 1e-8 * np.eye(3), -err[i] * (R @ n_obj))
            q[idx] = np.clip(q[idx] + dq, np.asarray(hand.q_lower)[idx], np.asarray(hand.q_upper)[idx])
    return None


def _non_tip_clear(grasp: Grasp, beta: float) -> bool:
    hand = grasp.hand
    c_palm = np.asarray(hand.sphere_centers(grasp.q, None, include_tip=False))
    d = grasp.obj.exact_signed_distance(transform_points(inv_T(grasp.T_palm_object), c_palm))
    return bool(np.all(d - hand.sphere_radii(None, include_tip=False) >= beta))


# ------------------------------------------------------------------------------------ public API
def generate_grasps(
    hand: Hand,
    obj: ObjectModel,
    n: int = 1,
    seed: int = 0,
    *,
    mu: float = MU,
    beta: float = BETA,
    T_palm_object_guess: NDArray[np.float64] | None = None,
    max_attempts: int | None = None,
) -> list[Grasp]:
    """Feasible four-finger precision grasps on `obj` (see the module docstring for the method).

    Every returned grasp satisfies, with the exact mesh distance: each tip sphere on the surface within
    `SURFACE_TOL` (0.1 mm); every non-tip collision sphere (palm included) at least `beta` from the object;
    joints within limits; force closure with friction `mu` — the origin strictly inside the convex hull
    of the contact wrenches of 8-edge linearised friction cones, with a margin ε > 1e-3 computed with the
    shrunk coefficient μ·cos(π/8), so it holds for any orientation of the cone edges (torques about the
    centre of mass scaled by the object's bounding radius; see `grasp_quality`).

    Args:
        hand: the hand.
        obj: the object.
        n: number of grasps.
        seed: random seed; the same seed gives the same grasps.
        mu: Coulomb friction coefficient of the force-closure test.
        beta: clearance of the non-tip spheres, m.
        T_palm_object_guess: (4, 4) object pose in the palm frame to perturb (random poses if None).
        max_attempts: attempts before giving up (default 60·n).

    Returns:
        `n` grasps (with joints).

    Raises:
        GraspError: if fewer than `n` grasps were found within `max_attempts`.
    """
    return _generate(hand, obj, n, seed, mu, beta, T_palm_object_guess, max_attempts, None, 0.0)


def _generate(hand, obj, n, seed, mu, beta, guess, max_attempts, avoid, min_mean_distance) -> list[Grasp]:
    max_attempts = 60 * n if max_attempts is None else int(max_attempts)
    nlp = _grasp_nlp(hand, obj, beta)
    data = _object_data(hand, obj)
    ws = _workspace(hand)
    out: list[Grasp] = []
    for attempt in range(max_attempts):
        g = _attempt(hand, obj, nlp, data, ws, np.random.default_rng([seed, attempt]), mu, guess, avoid,
                     min_mean_distance)
        if g is not None and avoid is not None:
            if np.mean(np.linalg.norm(g.contacts_object - avoid, axis=1)) < min_mean_distance:
                g = None
        if g is not None:
            out.append(g)
            if len(out) == n:
                return out
    raise GraspError(f"found {len(out)} of {n} grasps on {obj.name!r} in {max_attempts} attempts "
                     f"(seed {seed})")


def generate_regrasp_pairs(
    hand: Hand,
    obj: ObjectModel,
    n_pairs: int,
    seed: int = 0,
    min_mean_distance: float = 0.03,
    *,
    mu: float = MU,
    beta: float = BETA,
    max_attempts: int = 40,
) -> list[tuple[Grasp, Grasp]]:
    """Pairs (initial grasp, desired grasp) for regrasp planning.

    Both grasps satisfy every property of `generate_grasps` at their own object pose. The desired grasp's
    pose is a perturbation of the initial one (≈ 7° and 8 mm rms) and its contacts are, on average over
    the fingers, at least `min_mean_distance` from the initial contacts (object frame), so reaching it
    needs finger gaits and reposing.

    Args:
        hand: the hand.
        obj: the object.
        n_pairs: number of pairs.
        seed: random seed (same seed, same pairs).
        min_mean_distance: minimum mean contact distance between the two grasps, m.
        mu: friction coefficient of the force-closure test.
        beta: non-tip clearance, m.
        max_attempts: attempts per desired grasp before drawing a new initial grasp.

    Returns:
        list of (grasp0, grasp_goal); both carry joints.

    Raises:
        GraspError: if the pairs could not be found.
    """
    pairs: list[tuple[Grasp, Grasp]] = []
    for i in range(20 * n_pairs):
        init = _generate(hand, obj, 1, seed * 100003 + i, mu, beta, None, 60, None, 0.0)[0]
        try:
            goal = _generate(hand, obj, 1, seed * 100003 + 50000 + i, mu, beta, init.T_palm_object,
                             max_attempts, init.contacts_object, min_mean_distance)[0]
        except GraspError:
            log.debug("pair %d: no desired grasp for this initial grasp", i)
            continue
        pairs.append((init, goal))
        if len(pairs) == n_pairs:
            return pairs
    raise GraspError(f"found {len(pairs)} of {n_pairs} regrasp pairs on {obj.name!r} (seed {seed})")
