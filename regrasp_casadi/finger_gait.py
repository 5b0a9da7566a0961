"""OPT1 — finger gait: move one finger's contact towards its goal while the others hold the object.

    >>> nlp = FingerGaitNLP(hand, obj, "index")           # built once per (hand, object, finger)
    >>> result = nlp.solve(q, T_palm_object, p_object_tip_goal)
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from regrasp_casadi import signed_distance, terms
from regrasp_casadi import solver as _solver
from regrasp_casadi.constants import ETA
from regrasp_casadi.convex import LOCAL_PIECES, LOCAL_PLANES, select_local_planes_batch
from regrasp_casadi.self_collision import SelfCollisionConstraint
from regrasp_casadi.signed_distance import DEFAULT_TAU

if TYPE_CHECKING:
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel

__all__ = ["FingerGaitOptions", "FingerGaitResult", "FingerGaitNLP"]

_log = logging.getLogger(__name__)

_CM2 = 1e4  # objective scale: m² → cm²
_MM = 1e3  # distance-constraint scale: m → mm


@dataclass(frozen=True)
class FingerGaitOptions(_solver.NLPOptions):
    """Knobs of OPT1 (paper §III-A), beyond the NLPs' common ones (β, τ, ...); SI units."""

    eta: float = ETA
    """η, bound on the fingertip displacement of one gait, m (paper: 1 cm)."""
    surface_tol: float = 5e-5
    """Exact-contact tolerance: re-solve with a corrected offset until |SD_exact(tip) − r| ≤ this, m."""
    max_corrections: int = 4
    """Re-solves of the exact-contact correction after the first solve."""
    clearance_pieces: int = 2
    """Convex pieces in each non-tip sphere's local plane set (`convex.select_local_planes_batch`)."""
    clearance_local_planes: int = 16
    """Planes per piece in each non-tip sphere's local plane set."""


@dataclass(frozen=True)
class FingerGaitResult(_solver.SolveStats):
    """The outcome of one finger gait; `success`: it satisfies OPT1's constraints with the exact
    geometry."""

    q: NDArray[np.float64]
    """Joint angles after the gait, (n,) rad; only the finger's joints differ from the input."""
    p_object_tip: NDArray[np.float64]
    """Tip-sphere centre after the gait, (3,) object frame, m."""
    solves: int
    """Number of solves (1 + exact-contact corrections)."""
    surface_error: float
    """|SD_exact(tip centre) − tip radius| at the result, m."""
    min_clearance: float
    """Smallest exact distance of the finger's other spheres to the object, m."""
    min_self_clearance: float = float("inf")
    """Smallest surface distance of the finger's spheres to the other fingers' and the palm's spheres
    (the constrained pairs), m (inf without self-collision constraints)."""
    p_object_tip_goal: NDArray[np.float64] | None = None
    """The goal tip-sphere centre the gait was solved towards, (3,) object frame, m."""
    eta: float = ETA
    """The step bound of the solve, m (the options' η or the shorter one asked for)."""


def _param_layout(n: int, k: int, n_planes: int, n_sphere_planes: int) -> _solver.ParamLayout:
    """OPT1's parameters for a hand of `n` joints, a finger of `k` non-tip spheres, `n_planes` local
    planes near the tip and `n_sphere_planes` near each other sphere."""
    return _solver.ParamLayout([
        ("q_all", (n,)),  # joints at the start of the gait, rad (the other fingers keep them)
        ("R_palm_object", (3, 3)),  # object pose, palm frame
        ("t_palm_object", (3,)),  # m
        ("p_object_tip_goal", (3,)),  # goal tip-sphere centre, object frame, m
        ("delta_tip", (1,)),  # exact-distance offset of the tip, m
        ("delta_l", (k,)),  # exact-distance offsets of the finger's other spheres, m
        ("normals_tip", (3 * n_planes,)),  # local planes near the tip, as local_signed_distance
        ("offsets_tip", (n_planes,)),  # reads them (C order of ObjectModel.local_planes), object frame
        ("normals_l", (3 * n_sphere_planes, k)),  # each column: the local planes near one other sphere,
        ("offsets_l", (n_sphere_planes, k)),  # (C order of convex.select_local_planes), object frame
    ])


@dataclass(frozen=True)
class _Evaluation:
    """The finger at one point of the correction loop."""

    p_object_tip: NDArray[np.float64]
    """Tip-sphere centre, (3,) object frame, m."""
    exact: NDArray[np.float64]
    """Exact signed distances (1 + k,) of the tip and the finger's other spheres, m."""
    smooth: NDArray[np.float64]
    """Smooth model distances (1 + k,) of the same points, without offsets, m."""


class FingerGaitNLP:
    r"""OPT1, the finger-gait NLP of Sundaralingam & Hermans (ICRA 2018, §III-A), for one finger r:

    .. math::
        \min_{\Theta^r} \; \| c_{r,g} - T_{O}^{-1} FK_r(\Theta^r) \|^2
        \quad \text{s.t.} \quad
        \Theta^r_{min} \preceq \Theta^r \preceq \Theta^r_{max}, \;
        SD(T_O^{-1} FK_r(\Theta^r), M) + \delta_r = \rho, \;
        SD(T_O^{-1} FK_l(\Theta^r), M) + \delta_l - \rho_l \ge \beta \;\; \forall l \in L_r, \;
        \| FK_r(\Theta^r_0) - FK_r(\Theta^r) \|^2 \le \eta^2

    `FK_r` is the centre of the fingertip contact sphere (radius ρ), so the paper's point-contact cost
    ``||f_{r,g} − FK_r||²`` becomes the distance to the goal tip centre ``c_{r,g} = f_{r,g} + ρ n(f_{r,g})``
    (n the outward surface normal); `L_r` are the finger's other collision spheres (radius ρ_l); SD is the
    smooth signed distance of `ObjectModel`: for the tip, from the planes near its path
    (`ObjectModel.local_planes`, passed as parameters, so the NLP does not grow with the mesh); for each
    other sphere, from its own local plane set (`clearance_pieces` nearest pieces, `clearance_local_planes`
    planes each, `convex.select_local_planes_batch`: parameters, taken at the spheres' centres at the start
    and at every solution of the correction loop, as OPT2's `local_clearance`). Until 2026-12-06 these were
    the object's coarse pieces, 16 planes each, in the graph: on the 4-piece YCB models a third of the
    Hessian's instructions (125,590 → 77,445 for the index on mustard) and OPT1 7.3 → 6.3 ms per call on
    the paper benchmark (benchmarks/README). With 8 planes per piece (2026-12-06) the cup's SVD plan
    stalled behind the rim; 16 converge it (2026-12-07). A piece left out of a set may become the nearest
    one away from where it was taken: the exact check at the solution corrects the offsets or rejects the
    gait, as for the tip. The offsets δ (parameters) make contacts exact: after a solve, δ = SD_exact −
    SD_smooth at the solution and the NLP is solved again (warm started) until the tip sits on the real
    mesh within `surface_tol`. Where that loop does not settle (the offsets of one solution do not fit the
    next), the iterate nearest the goal whose other spheres are clear is moved onto the exact surface by
    Newton steps of the tip (`_polished`).
    A sphere l already closer than β at the start (OPT2's moves accept down to β/2) keeps at least its
    start clearance instead (β replaced by min(β, its start value)): with β held, IPOPT started
    infeasible and spent up to 300 iterations restoring it (paper benchmark: 18–33 such solves).

    Self-collision (not in the paper; `options.self_clearance` = c, None: off): every sphere a of the
    finger (tip included) keeps ``|c_a(Θ^r) − c_b| − ρ_a − ρ_b ≥ c`` from every sphere b of the other
    fingers and the palm (fixed during the gait, so functions of the parameters), for the pairs
    `Hand.self_collision_pairs(finger, within=c)`, one smooth minimum per rigid-body pair
    (`self_collision.SelfCollisionConstraint`); a pair already closer than c at the start keeps at least
    its start value (no worse).

    Decision variables: the finger's joints (n_r,). Parameters (`layout`): the full joint vector (n,),
    the object pose (R (3, 3), t (3,)), the goal tip centre (3,) object frame, δ_tip (1,), δ_l (k,), the
    tip's local planes (normals, offsets) and the other spheres' (one column each).
    The objective is in cm² and the distance constraints in mm, for IPOPT's tolerances.
    """

    def __init__(self, hand: Hand, obj: ObjectModel, finger: str, options: FingerGaitOptions | None = None):
        self.hand, self.obj, self.finger = hand, obj, finger
        self.options = options or FingerGaitOptions()
        o = self.options
        if finger not in hand.fingers:
            raise ValueError(f"unknown finger {finger!r}; the hand has {hand.fingers}")
        idx = np.asarray(hand.finger_joints[finger], dtype=int)
        self._idx = idx
        n = hand.n_joints
        radii = np.asarray(hand.sphere_radii(finger), dtype=float)
        k = radii.size
        self._radii = radii
        # exact distances are needed only for points that may be within a sphere radius + 1 cm
        self._near = np.concatenate([[hand.tip_radius], radii]) + 0.01
        tau = float(DEFAULT_TAU if o.tau is None else o.tau)
        n_local = self._n_local = min(LOCAL_PIECES, len(obj.pieces))  # pieces per local plane set
        self._sphere_sets = (int(o.clearance_pieces), int(o.clearance_local_planes))  # the other spheres'

        # decision variables
        q_r = ca.SX.sym("q_r", idx.size)
        # parameters
        self.layout = _param_layout(n, k, n_local * LOCAL_PLANES,
                                    o.clearance_pieces * o.clearance_local_planes)
        p, P = self.layout.symbols()
        q_all, R, t = P["q_all"], P["R_palm_object"], P["t_palm_object"]

        q_full = terms.substitute_joints(q_all, idx, q_r)
        tip_fun = hand.tip_position_function(finger)
        c_palm = tip_fun(q_full)
        c_palm0 = tip_fun(q_all)
        c_obj = terms.to_object_frame(R, t, c_palm)
        if k:
            s_obj = terms.to_object_frame(R, t, hand.sphere_centers_function(finger)(q_full))
            N_l, H_l = P["normals_l"], P["offsets_l"]
            sd_l = ca.vertcat(*[signed_distance.local_signed_distance(
                N_l[:, i], H_l[:, i], s_obj[:, i], o.clearance_pieces, tau) for i in range(k)])
        else:
            s_obj = ca.SX(3, 0)
            sd_l = ca.SX(0, 1)
        sd_tip = signed_distance.local_signed_distance(P["normals_tip"], P["offsets_tip"], c_obj, n_local,
                                                       tau)

        # objective
        f = _CM2 * ca.sumsqr(c_obj - P["p_object_tip_goal"])
        # constraints
        g = ca.vertcat(
            _MM * (sd_tip + P["delta_tip"] - hand.tip_radius),
            _MM * (sd_l + P["delta_l"] - ca.DM(radii)),
            _CM2 * ca.sumsqr(c_palm - c_palm0),
        )
        lbg = np.concatenate([[0.0], np.full(k, _MM * o.beta), [-np.inf]])
        ubg = np.concatenate([[0.0], np.full(k, np.inf), [_CM2 * o.eta**2]])
        # self-collision: the moving finger's spheres (variables) against the others' (parameters)
        self.self_collision = SelfCollisionConstraint.build(hand, finger, o.self_clearance)
        """The self-collision constraints (None: `self_clearance` None)."""
        if self.self_collision is not None:
            g, lbg, ubg = self.self_collision.extend(g, lbg, ubg, q_full, _MM)
        # bounds
        self._bounds = _solver.Bounds(
            lbx=np.asarray(hand.q_lower, float)[idx], ubx=np.asarray(hand.q_upper, float)[idx],
            lbg=lbg, ubg=ubg)
        # solver
        nlp = {"x": q_r, "p": p, "f": f, "g": g}
        curved = None if o.clearance_curvature else np.r_[0, np.arange(1 + k, len(lbg))]  # tip, η, self
        self._solver = _solver.build_solver(f"finger_gait_{finger}", nlp, o.solver_options(), curved)
        # numeric helper: tip and sphere points (object frame) and their smooth distances, no offsets
        self._points = ca.Function("gait_points", [q_r, p], [c_obj, s_obj, sd_tip, sd_l],
                                   ["q_r", "p"], ["p_object_tip", "p_object_spheres", "sd_tip", "sd_l"])
        self._k = k
        self.warm_start = _solver.WarmStart()
        """Multipliers of the last successful solve, for the next one."""

    def reset(self) -> None:
        """Forget the warm-start multipliers (a new plan starts cold, so plans are reproducible)."""
        self.warm_start.reset()

    def _params(self, q, T, c_goal, delta, planes) -> NDArray[np.float64]:
        """p of a solve from (`q`, `T`) towards `c_goal` with offsets `delta` (1 + k,) (tip, then the
        other spheres) and the local `planes` (`_planes`)."""
        return self.layout.pack(q_all=q, R_palm_object=T[:3, :3], t_palm_object=T[:3, 3],
                                p_object_tip_goal=c_goal, delta_tip=delta[:1], delta_l=delta[1:],
                                normals_tip=planes[0].ravel(), offsets_tip=planes[1].ravel(),
                                normals_l=planes[2], offsets_l=planes[3])

    def _planes(self, tip_points: list[NDArray], sphere_points: list[NDArray]) -> tuple[NDArray, ...]:
        """The local plane sets of a solve: the tip's near `tip_points` ((3,) each, object frame, m) and
        each other sphere's near its centres in `sphere_points` ((k, 3) each): (normals, offsets) of the
        tip (`ObjectModel.local_planes`), then of the spheres ((3·n, k), (n, k) blocks)."""
        N_tip, H_tip = self.obj.local_planes(tip_points, self._n_local)
        n_pieces, n_planes = self._sphere_sets
        if not self._k:
            return N_tip, H_tip, np.zeros((3 * n_pieces * n_planes, 0)), np.zeros((n_pieces * n_planes, 0))
        pts = np.stack([np.asarray(c, float) for c in sphere_points], axis=1)  # (k, s, 3)
        N, H = select_local_planes_batch(self.obj.pieces, pts, n_pieces, n_planes)
        return N_tip, H_tip, N.reshape(self._k, -1).T.copy(), H.reshape(self._k, -1).T.copy()

    def _sphere_centres(self, q, T, x) -> NDArray[np.float64]:
        """(k, 3) centres of the finger's other spheres, object frame, m, with its joints at `x` (n_r,)."""
        q_full = np.array(q, dtype=float)
        q_full[self._idx] = x
        return (np.asarray(self.hand.sphere_centers(q_full, self.finger), float) - T[:3, 3]) @ T[:3, :3]

    def _evaluate(self, q_r, p) -> _Evaluation:
        """Tip centre (object frame) and the exact and smooth (no offsets) distances (1 + k,) of the tip
        and the finger's spheres at the finger joints `q_r` and parameters `p`."""
        c_obj, s_obj, sd_tip, sd_l = self._points(q_r, p)
        pts = np.vstack([np.asarray(c_obj).reshape(1, 3), np.asarray(s_obj).T.reshape(-1, 3)])
        exact = np.asarray(self.obj.near_signed_distance(pts, self._near), float).ravel()
        smooth = np.concatenate([np.asarray(sd_tip).ravel(), np.asarray(sd_l).ravel()])
        return _Evaluation(np.asarray(c_obj).ravel(), exact, smooth)

    def _smooth(self, q_r, p):
        """Smooth distances (1 + k,) of the tip and the finger's spheres (no offsets)."""
        _, _, sd_tip, sd_l = self._points(q_r, p)
        return np.concatenate([np.asarray(sd_tip).ravel(), np.asarray(sd_l).ravel()])

    def solve(self, q: ArrayLike, T_palm_object: ArrayLike, p_object_tip_goal: ArrayLike,
              eta: float | None = None, q_init: ArrayLike | None = None) -> FingerGaitResult:
        """Move the finger's tip towards `p_object_tip_goal` (3,) (goal tip-sphere centre, object frame, m)
        from the grasp (`q` (n,) rad, `T_palm_object` (4, 4)); never raises on a failed solve. `eta`: another
        step bound than the options' η for this solve, m (a bound, not a rebuild: e.g. a shortened gait or
        one step of a slide). `q_init`: (n,) rad, the first iterate of the finger's joints (default: q's;
        e.g. the finger's IK at its goal, `long_gait`); the constraints are q's either way."""
        o = self.options if eta is None else replace(self.options, eta=float(eta))
        q = np.asarray(q, dtype=float).copy()
        T = np.asarray(T_palm_object, dtype=float)
        c_goal = np.asarray(p_object_tip_goal, dtype=float).reshape(3)
        x0 = q[self._idx]
        r = self.hand.fingers.index(self.finger)
        c0 = (self.hand.tip_positions(q)[r] - T[:3, 3]) @ T[:3, :3]  # tip centre, object frame
        reach = min(1.0, 1.5 * o.eta / max(float(np.linalg.norm(c_goal - c0)), 1e-12))
        selection = [c0 + s * reach * (c_goal - c0) for s in (0.0, 0.25, 0.5, 0.75, 1.0)]
        spheres = [self._sphere_centres(q, T, x0)] + (  # the spheres' planes: at the start (and the init)
            [self._sphere_centres(q, T, np.asarray(q_init, float)[self._idx])] if q_init is not None else [])
        planes = self._planes(selection, spheres)  # the planes that matter along the way

        def params(delta, planes):
            return self._params(q, T, c_goal, delta, planes)

        sc = self.self_collision
        bounds, floor = (self._bounds, None) if sc is None else sc.bounds(self._bounds, q, _MM)
        if eta is not None:
            bounds = self._step_bounds(bounds, o.eta)

        def solve_with(x, offsets):
            return self.warm_start.solve(self._solver, bounds, x0=x, p=params(*offsets))

        def done(ev: _Evaluation) -> bool:
            clear_ok = self._k == 0 or np.min(ev.exact[1:] - self._radii) >= 0.5 * o.beta
            return abs(ev.exact[0] - self.hand.tip_radius) <= o.surface_tol and clear_ok

        def new_offsets(x, ev: _Evaluation, offsets):
            selection.append(ev.p_object_tip)  # re-select the planes with the solution point
            spheres.append(self._sphere_centres(q, T, x))
            planes = self._planes(selection, spheres)
            return ev.exact - self._smooth(x, params(np.zeros(1 + self._k), planes)), planes

        iterates: list[tuple[NDArray[np.float64], _Evaluation]] = []

        def evaluate(x, offsets) -> _Evaluation:
            ev = self._evaluate(x, params(*offsets))
            iterates.append((np.array(x, dtype=float), ev))
            return ev

        start = self._evaluate(x0, params(np.zeros(1 + self._k), planes))
        if self._k:  # a sphere closer than β at the start (OPT2 accepts down to β/2) may get no closer
            lbg = bounds.lbg.copy()
            lbg[1:1 + self._k] = _MM * _solver.no_worse(o.beta, start.exact[1:] - self._radii)
            bounds = replace(bounds, lbg=lbg)
        x_first, first = x0, start  # the first iterate and its evaluation (judged as the result if unsolved)
        if q_init is not None:
            x_first = np.asarray(q_init, dtype=float)[self._idx]
            first = self._evaluate(x_first, params(np.zeros(1 + self._k), planes))
        corr = _solver.correct_offsets(solve_with, evaluate,
                                       done, new_offsets, offsets=(start.exact - start.smooth, planes),
                                       x=x_first, evaluation=first, max_solves=o.max_corrections + 1,
                                       accept=_solver.clipped_if_finite(self._bounds))
        if not corr.converged:
            corr = self._polished(corr, iterates, q=q, T=T, c0=c0, c_goal=c_goal,
                                  p=params(np.zeros(1 + self._k), planes), done=done, o=o)
        return replace(self._result(q, c0, corr, floor, o), p_object_tip_goal=c_goal, eta=float(o.eta))

    def _polished(self, corr: _solver.Correction[_Evaluation],
                  iterates: list[tuple[NDArray[np.float64], _Evaluation]], *, q, T, c0, c_goal, p, done,
                  o: FingerGaitOptions) -> _solver.Correction[_Evaluation]:
        """`corr` with its point replaced by the first of the correction loop's iterates (nearest the goal
        tip centre `c_goal` (3,), object frame, m, first) whose tip, moved onto the exact surface along its
        exact normal (`_polish_tip`), passes `done`, ends closer to `c_goal` than the start tip centre `c0`
        (3,) and within the step bound η of it; `corr` itself when none does.

        Why: where the smooth model's error changes quickly along the surface (a rounded rim a few mm
        across, under a 14 mm tip sphere), the offsets δ = exact − smooth of one iterate do not fit the
        next one, and the loop alternates between two points (tip 0.5 mm into the wall, then a link
        0.7 mm into it, ...) until `max_corrections`. One of them is usually clear of the object with
        the tip off the surface by a fraction of a millimetre, which a few Newton steps on the exact
        distance correct. `p`: parameters of the smooth evaluation (offsets unused by it)."""
        for x, ev in sorted(iterates, key=lambda it: float(np.linalg.norm(it[1].p_object_tip - c_goal))):
            if self._k and np.min(ev.exact[1:] - self._radii) < 0.5 * o.beta:
                continue  # a link in the object: moving the tip does not clear it
            polished = self._polish_tip(q, T, x, ev, p, ball=(c0, o.eta))
            if polished is None:
                continue
            x_new, ev_new = polished
            closer = np.linalg.norm(ev_new.p_object_tip - c_goal) < np.linalg.norm(c0 - c_goal)
            if done(ev_new) and closer and np.linalg.norm(ev_new.p_object_tip - c0) <= o.eta + 1e-6:
                _log.debug("gait %s: correction loop polished onto the exact surface", self.finger)
                return replace(corr, x=x_new, evaluation=ev_new, converged=True)
        return corr

    def _polish_tip(self, q, T, x, ev: _Evaluation, p, *, iters: int = 5, max_error: float = 2e-3,
                    ball: tuple[NDArray[np.float64], float] | None = None
                    ) -> tuple[NDArray[np.float64], _Evaluation] | None:
        """Newton steps moving the tip centre along its exact contact normal by −(SD_exact − ρ) with the
        finger's joints (`tip_ik`, within the joint limits), from the finger joints `x` (n_r,) rad of the
        grasp (`q` (n,) rad, `T` (4, 4) palm ← object); `p`: the smooth evaluation's parameters.
        `ball` = (c0 (3,), η): each step's target is kept within η (m, less 0.1 %) of the start tip centre
        c0 (object frame, m), the gait's step bound: the solutions the loop leaves on the bound (a step of
        η) would otherwise end 0.1–0.4 mm beyond it after the step along the normal (mug seed 7, SVD).
        Returns (joints (n_r,), evaluation) once the tip is within `surface_tol` (m) of the surface, None
        when it is not after `iters` steps or starts farther than `max_error` (m) from it."""
        from regrasp_casadi.tip_ik import tip_ik

        rho, tol = self.hand.tip_radius, self.options.surface_tol
        if abs(ev.exact[0] - rho) > max_error:
            return None
        q_full = np.array(q, dtype=float)
        for _ in range(iters):
            err = float(ev.exact[0] - rho)
            if abs(err) <= tol:
                return np.asarray(x, dtype=float), ev
            closest, _ = self.obj.closest_points(ev.p_object_tip[None])
            normal = ev.p_object_tip - closest[0]  # outward: the tip centre is outside the mesh
            normal /= max(float(np.linalg.norm(normal)), 1e-12)
            q_full[self._idx] = x
            p_target = ev.p_object_tip - err * normal  # object frame, m
            if ball is not None:  # back into the step bound, towards its centre
                step = p_target - ball[0]
                length = max(float(np.linalg.norm(step)), 1e-12)
                p_target = ball[0] + step * min(1.0, 0.999 * ball[1] / length)
            target = T[:3, :3] @ p_target + T[:3, 3]  # palm frame, m
            q_new, _ = tip_ik(self.hand, q_full, [self.finger], target[None], self._idx, q_full, max_iters=10)
            x = q_new[self._idx]
            ev = self._evaluate(x, p)
        return (np.asarray(x, dtype=float), ev) if abs(ev.exact[0] - rho) <= tol else None

    def _step_bounds(self, bounds: _solver.Bounds, eta: float) -> _solver.Bounds:
        """`bounds` with the step bound `eta`, m (constraint row 1 + k: the tip's squared step, cm²)."""
        ubg = np.array(bounds.ubg, dtype=float)
        ubg[1 + self._k] = _CM2 * eta**2
        return replace(bounds, ubg=ubg)

    def _result(self, q, c0, corr: _solver.Correction[_Evaluation], floor, o: FingerGaitOptions
                ) -> FingerGaitResult:
        """The gait's result from the correction loop's last point, judged with the exact distances (and
        the step bound of `o`)."""
        ev = corr.evaluation
        q_new = q.copy()
        q_new[self._idx] = corr.x
        surface_error = float(abs(ev.exact[0] - self.hand.tip_radius))
        min_clear = float(np.min(ev.exact[1:] - self._radii)) if self._k else float("inf")
        step = float(np.linalg.norm(ev.p_object_tip - c0))  # the object does not move during a gait
        feasible = (surface_error <= max(o.surface_tol, 1e-4) and min_clear >= 0.0
                    and step <= o.eta + 1e-6)
        sc, min_self = self.self_collision, float("inf")
        if sc is not None:
            min_self = sc.min_distance(q_new)
            feasible = feasible and sc.holds(q_new, floor)
        if not feasible:
            _log.debug("gait %s infeasible: status %s surface %.2e clearance %.2e self %.2e step %.4f",
                       self.finger, corr.status, surface_error, min_clear, min_self, step)
        return FingerGaitResult(q=q_new, p_object_tip=ev.p_object_tip, status=corr.status,
                                success=bool(feasible), iterations=corr.iterations, solves=corr.solves,
                                solve_time=corr.solve_time, surface_error=surface_error,
                                min_clearance=min_clear, min_self_clearance=min_self)
