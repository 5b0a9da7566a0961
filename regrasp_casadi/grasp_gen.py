"""Grasp generation: feasible four-finger precision grasps on any object, and regrasp pairs.

A generated grasp G = (X, o, Θ) satisfies, checked with the *exact* mesh distance (never the smooth one):

* every fingertip contact sphere touches the surface: |d_exact(tip centre) − r_tip| ≤ `SURFACE_TOL`
  (0.1 mm);
* no other hand–object contact: every non-tip collision sphere of the hand (palm included) keeps
  d_exact(centre) − radius ≥ β (1 mm by default);
* no self-collision: the collision spheres of different fingers, and of a finger and the palm, keep the
  self-clearance (1 mm by default; `Hand.self_collision_pairs`, pairs that touch at a joint excepted);
* joints within their limits;
* the grasp can hold the object: **force closure** with Coulomb friction μ (0.5), see `grasp_quality`;
* every finger can lift off its contact, and so touch down on it, the way a gait's path does
  (`gait_path.lift_problem`: 5 mm along the contact normal within 45°, within the joint limits):
  a grasp whose finger the limits hold on the surface is one no gait reaches or leaves (measured: the
  ring of bowl seed 9's desired grasp, at its flexion limits on the bowl's floor, could rise 0.25 mm
  short of 5 mm only 73.8° off the normal; its plans stalled with the ring 48–64 mm from it).

How (one attempt): sample an object pose in front of the palm (an orientation aligned with the object's
oriented bounding box plus a random tilt, a random position where the fingertip workspaces reach it),
pick one contact target per finger among sampled surface points that the finger can reach with its
links clear of the object (tip workspace samples over the joint limits whose non-tip spheres clear a
grid of the object's distance bound at that pose, `grasp_workspace`; the start joints come from the same
samples, so no link starts across a thin wall), with the fingers on one side and the thumb (`hand.thumb`)
opposite them, keeping only target sets that are themselves in force closure, then solve the grasp NLP
of `grasp_nlp` (tips on the smooth surface, other spheres clear, with exact-distance corrections and a
final Newton polish of the tips on the exact distance). The NLP is built once per (hand, object, β) and
re-solved from different seeds. Same seed → same grasps (for the same hand and object models).

    >>> grasps = generate_grasps(Hand.allegro_right(), ObjectModel.box((0.06, 0.06, 0.12)), n=3, seed=0)
    >>> pairs = generate_regrasp_pairs(hand, obj, n_pairs=2, seed=0)
"""

from __future__ import annotations

import collections
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.certificates import force_closure_certificate
from regrasp_casadi.constants import BETA, MU, SELF_CLEARANCE
from regrasp_casadi.errors import GraspError
from regrasp_casadi.gait_path import lift_problem
from regrasp_casadi.grasp import Grasp
from regrasp_casadi.grasp_feasibility import TIP_SPACING, UngraspableError, check_graspable
from regrasp_casadi.grasp_nlp import SURFACE_TOL, GraspNLP, grasp_nlp, solve_exact
from regrasp_casadi.grasp_workspace import (
    ClearanceGrid,
    ClearSamples,
    Workspace,
    clear_samples,
    clearance_grid,
    workspace,
)
from regrasp_casadi.hand import Hand
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.stability import FRICTION_EDGES, force_closure_quality, tangent_bases, torque_reference
from regrasp_casadi.trajectory import TrajectoryOptions, motion_context
from regrasp_casadi.transforms import exp_so3, inv_T, make_T, transform_points

__all__ = [
    "SURFACE_TOL",
    "UngraspableError",
    "force_closure_quality",
    "grasp_quality",
    "generate_grasps",
    "generate_regrasp_pairs",
]

log = logging.getLogger(__name__)

_N_SURFACE = 3000  # surface samples for contact targets
_REACH_TOL = 0.006  # a target is reachable if a workspace sample lies within this distance, m
_TIP_SPACING = TIP_SPACING  # minimum distance between two fingertip targets, m (0.03)
_MIN_QUALITY = 1e-3  # force-closure margin a generated grasp must exceed
_PRECHECK = 2.0  # the targets (surface points, face normals) must exceed _PRECHECK · _MIN_QUALITY
_MIN_OPEN = 0.5  # contact targets: at least this fraction of their approach cone is open (`open_fraction`)
_CAVITY_SHARE = 0.2
"""... on objects where at least this share of the surface samples is closed (cup, mug: 45 %); elsewhere
(holed box 8 %, bowl 2 %, convex and YCB-like shapes 0 %) every sample stays a target, as before."""
_CONE_SHRINK = float(np.cos(np.pi / FRICTION_EDGES))
"""Generated grasps are tested with μ·cos(π/8): the circle of that radius lies inside every 8-edge
polygon of radius μ, so the grasp is in force closure however the linearised cones are turned."""


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


def open_fraction(mesh, points: NDArray[np.float64], normals: NDArray[np.float64], tip_radius: float,
                  half_angles=(0.0, 25.0, 50.0), per_ring: int = 8) -> NDArray[np.float64]:
    """How open the approach to each surface point is: the fraction of rays from the tip centre it would
    have (point + (r_tip + 1 mm)·normal) within a cone about the normal (the axis, and `per_ring` rays at
    each of `half_angles` degrees) that leave the mesh without hitting it (embree/trimesh ray tests).

    A convex object's points are all open (1.0); on a cup the deep inside of the wall is closed (its rays
    hit the opposite wall), the rims and the outside are open. Points (n, 3), unit normals (n, 3), object
    frame, m. Returns (n,) in [0, 1].
    """
    p = np.asarray(points, float)
    n = np.asarray(normals, float)
    e1, e2 = np.moveaxis(tangent_bases(n), 1, 0)  # (n, 3) each: (n, e1, e2) orthonormal
    dirs = []
    for a in np.radians(np.asarray(half_angles, float)):
        for b in (np.arange(per_ring) * 2 * np.pi / per_ring if a > 0 else [0.0]):
            dirs.append(np.cos(a) * n + np.sin(a) * (np.cos(b) * e1 + np.sin(b) * e2))
    D = np.stack(dirs, axis=1)  # (n, rays, 3)
    origins = np.repeat((p + (tip_radius + 1e-3) * n)[:, None, :], D.shape[1], axis=1)
    hit = mesh.ray.intersects_any(origins.reshape(-1, 3), D.reshape(-1, 3)).reshape(len(p), -1)
    return 1.0 - hit.mean(axis=1)


_STATS: collections.Counter = collections.Counter()
"""Outcome counts of generation attempts in this process (diagnostics)."""


# ------------------------------------------------------------------------------ sampling helpers
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
    keep = open_fraction(obj.mesh, pts, nrm, hand.tip_radius) >= _MIN_OPEN
    if np.mean(~keep) >= _CAVITY_SHARE:  # a container: no targets deep inside it
        pts, nrm = pts[keep], nrm[keep]
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


class _Away(NamedTuple):
    """What a desired grasp must keep from the initial one: its contacts (object frame, m) on average
    at least `min_mean_distance` (m) from `contacts_object` (m, 3)."""

    contacts_object: NDArray[np.float64]
    min_mean_distance: float

    def keeps(self, contacts_object: NDArray[np.float64]) -> bool:
        """Whether the contacts (m, 3) (object frame, m) keep the mean distance."""
        distances = np.linalg.norm(contacts_object - self.contacts_object, axis=1)
        return bool(np.mean(distances) >= self.min_mean_distance)


@dataclass(frozen=True)
class _Search:
    """What the attempts of a generation share: the models, the grasp NLP, the object's surface samples,
    the hand's workspace samples, the object's clearance grid and the friction coefficient of the
    force-closure tests."""

    hand: Hand
    obj: ObjectModel
    nlp: GraspNLP
    data: _ObjectData
    ws: Workspace
    grid: ClearanceGrid
    mu: float
    motion: Any
    """`trajectory.motion_context` of the models, for the lift-off rule (`gait_path.lift_problem`)."""


def _search(hand: Hand, obj: ObjectModel, mu: float, beta: float, self_clearance: float | None) -> _Search:
    """The (cached) NLP and samples of (`hand`, `obj`, β = `beta` m, `self_clearance` m or None) and
    friction `mu`."""
    motion = motion_context(hand, obj, TrajectoryOptions(self_clearance=self_clearance))
    return _Search(hand, obj, grasp_nlp(hand, obj, beta, self_clearance), _object_data(hand, obj),
                   workspace(hand), clearance_grid(obj), mu, motion)


def _pick_targets(search: _Search, clear: dict[str, ClearSamples], T, rng, away: _Away | None,
                  tries: int = 12):
    """Target indices whose own contacts (surface points, face normals) are in force closure, each
    reachable by a workspace sample of `clear` (links clear of the object at pose T)."""
    data = search.data
    reach = _Reach.at(search.hand, data, clear, T, away)
    if reach is None:
        return None
    for _ in range(tries):
        idx = _pick_targets_once(search.hand, reach, rng)
        if idx is not None and force_closure_quality(data.points[idx], data.normals[idx],
                                                     search.mu * _CONE_SHRINK, data.com,
                                                     data.length) > _PRECHECK * _MIN_QUALITY:
            return idx
    return None


class _Reach(NamedTuple):
    """The surface samples in the palm frame at one object pose — points P (s, 3), normals N (s, 3),
    tip-centre goals P + r·N (m) — and, per finger, the indices of the samples it can reach."""

    P: NDArray[np.float64]
    N: NDArray[np.float64]
    goals: NDArray[np.float64]
    by_finger: dict[str, NDArray[np.int64]]

    @staticmethod
    def at(hand: Hand, data: _ObjectData, clear: dict[str, ClearSamples], T, away: _Away | None):
        """The reach at pose T (4, 4): a goal within `_REACH_TOL` of a clear workspace sample's tip (and,
        with `away`, ≥ its distance from the finger's initial contact); None if a finger reaches none."""
        P = transform_points(T, data.points)
        N = data.normals @ T[:3, :3].T
        goals = P + hand.tip_radius * N
        by_finger = {}
        for i, f in enumerate(hand.fingers):
            dist, _ = clear[f].nearest(goals, 1)
            ok = dist <= _REACH_TOL
            if away is not None:
                ok &= np.linalg.norm(data.points - away.contacts_object[i], axis=1) >= away.min_mean_distance
            by_finger[f] = np.nonzero(ok)[0]
            if len(by_finger[f]) == 0:
                return None
        return _Reach(P, N, goals, by_finger)


def _pick_targets_once(hand: Hand, reach: _Reach, rng):
    """Contact targets (surface sample indices) per finger among those each finger can reach; None if
    none fit.

    The non-thumb fingers get reachable targets ≥ `_TIP_SPACING` apart; the thumb gets a reachable target
    whose inward line of action passes near the fingers' centroid and whose normal opposes theirs.
    """
    fingers = list(hand.fingers)
    thumb = hand.thumb if hand.thumb is not None else fingers[-1]  # no thumb in the metadata: the last
    P, N, goals = reach.P, reach.N, reach.goals
    chosen: dict[str, int] = {}
    for f in (f for f in fingers if f != thumb):
        cand = reach.by_finger[f]
        for i in chosen.values():
            cand = cand[np.linalg.norm(goals[cand] - goals[i], axis=1) >= _TIP_SPACING]
        if chosen:
            n_mean = np.mean([N[i] for i in chosen.values()], axis=0)
            cand = cand[N[cand] @ n_mean >= 0.3]
        if len(cand) == 0:
            return None
        chosen[f] = int(rng.choice(cand))
    fi = list(chosen.values())
    centroid = P[fi].mean(axis=0)
    n_fingers = N[fi].mean(axis=0)
    n_fingers /= max(np.linalg.norm(n_fingers), 1e-9)
    cand = reach.by_finger[thumb]
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


def _initial_q(hand, ws: Workspace, clear: dict[str, ClearSamples], goals_palm, rng) -> NDArray[np.float64]:
    """Joint guess: each finger from a workspace sample of `clear` (its links clear of the object) whose
    tip is near the finger's target (goals_palm (m, 3), palm frame, m): random among the 8 nearest."""
    q = 0.5 * (hand.q_lower + hand.q_upper)
    for i, f in enumerate(hand.fingers):
        _, j = clear[f].nearest(goals_palm[i], 8)
        j = np.atleast_1d(j)
        idx = np.asarray(hand.finger_joints[f])
        q[idx] = ws.Q[int(j[rng.integers(len(j))]), idx]
    return q


# --------------------------------------------------------------------------------------- attempt
def _attempt(search: _Search, rng, guess, away: _Away | None) -> Grasp | None:
    """One attempt (the module docstring's "How"): a grasp, or None (the reason counted in `_STATS`)."""
    hand, obj, nlp, data = search.hand, search.obj, search.nlp, search.data
    T0 = _sample_pose(hand, obj, data, rng, guess)
    clear = clear_samples(search.ws, search.grid, T0)
    idx = _pick_targets(search, clear, T0, rng, away)
    if idx is None:
        _STATS["no_targets"] += 1
        return None
    targets_obj = data.points[idx] + hand.tip_radius * data.normals[idx]
    q0 = _initial_q(hand, search.ws, clear, transform_points(T0, targets_obj), rng)
    check, why_not = solve_exact(nlp, targets_obj, q0, T0)
    if check is None:
        _STATS[why_not] += 1
        return None
    q = np.clip(check.x[: nlp.n], hand.q_lower, hand.q_upper)
    try:
        grasp = Grasp.from_joints(hand, obj, q, check.T_palm_object, tol=SURFACE_TOL)
    except GraspError as exc:
        log.debug("rejected: %s", exc)
        return None
    problem = _broken_rule(search, grasp)
    _STATS[problem or "ok"] += 1
    return None if problem else grasp


def _broken_rule(search: _Search, grasp: Grasp) -> str:
    """The first rule of the module docstring `grasp` breaks, past its tips on the surface: "contact",
    "self_collision" (`_clearance_problem`), "force_closure" or "lift"; "" when it keeps them all."""
    problem = _clearance_problem(grasp, search.nlp)
    if problem:
        return problem
    if not _force_closure(grasp, search.mu):
        return "force_closure"
    if any(lift_problem(search.motion, grasp.q, grasp.T_palm_object, f) for f in search.hand.fingers):
        return "lift"
    return ""


def _force_closure(grasp: Grasp, mu: float) -> bool:
    """The stability rule: the Ferrari–Canny margin (`grasp_quality`, μ·cos(π/8)) exceeds `_MIN_QUALITY`
    and the force-closure LP of `certificates.force_closure_certificate` (same contacts, normals, shrunk
    μ, torque reference) certifies the grasp."""
    quality = grasp_quality(grasp, mu * _CONE_SHRINK)
    if quality <= _MIN_QUALITY:
        log.debug("rejected: force-closure margin %.4g", quality)
        return False
    c = np.asarray(grasp.contacts_object, float)
    normals = np.asarray(grasp.tip_centers_object, float) - c
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    com, length = torque_reference(grasp.obj.mesh)
    cert = force_closure_certificate(c, normals, mu * _CONE_SHRINK, com, length)
    if not cert.ok:
        log.debug("rejected: %s", cert.detail)
    return cert.ok


def _clearance_problem(grasp: Grasp, nlp: GraspNLP) -> str:
    """"contact" (a non-tip sphere within β of the object), "self_collision" (two fingers, or a finger and
    the palm, within the self-clearance) or "" (clear)."""
    if not _non_tip_clear(grasp, nlp.beta):
        return "contact"
    return "" if nlp.self_clear(grasp.q) else "self_collision"


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
    progress: Callable[[int, int], None] | None = None,
    self_clearance: float | None = SELF_CLEARANCE,
) -> list[Grasp]:
    """Feasible four-finger precision grasps on `obj` (see the module docstring for the method).

    Every returned grasp satisfies, with the exact mesh distance: each tip sphere on the surface within
    `SURFACE_TOL` (0.1 mm); every non-tip collision sphere (palm included) at least `beta` from the object;
    the spheres of different fingers, and of a finger and the palm, at least `self_clearance` apart;
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
        progress: optional callable ``progress(found, attempts)`` called after every attempt.
        self_clearance: clearance between the collision spheres of different fingers and of a finger
            and the palm, m (`Hand.self_collision_pairs`); None: no self-collision constraint (the
            grasps of earlier versions).

    Returns:
        `n` grasps (with joints).

    Raises:
        UngraspableError: before any solve, if the object is too small, too large or too thin for a
            precision grasp of the hand (`grasp_feasibility.check_graspable`; `reason` names which).
        GraspError: if fewer than `n` grasps were found within `max_attempts`.
    """
    check_graspable(hand, obj, self_clearance)
    return _generate(_search(hand, obj, mu, beta, self_clearance), n, seed, T_palm_object_guess,
                     max_attempts, progress=progress)


def _generate(search: _Search, n: int, seed: int, guess, max_attempts: int | None, *,
              away: _Away | None = None, progress=None, deadline: float | None = None) -> list[Grasp]:
    """`n` grasps from the attempts seeded (`seed`, attempt); see `generate_grasps`. No attempt starts
    after `deadline` (`time.monotonic()`, s; None: no deadline)."""
    max_attempts = 60 * n if max_attempts is None else int(max_attempts)
    out: list[Grasp] = []
    for attempt in range(max_attempts):
        if deadline is not None and time.monotonic() > deadline:
            break
        g = _attempt(search, np.random.default_rng([seed, attempt]), guess, away)
        if g is not None and away is not None and not away.keeps(g.contacts_object):
            g = None
        if g is not None:
            out.append(g)
        if progress is not None:
            progress(len(out), attempt + 1)
        if len(out) == n:
            return out
    raise GraspError(f"found {len(out)} of {n} grasps on {search.obj.name!r} in {max_attempts} attempts "
                     f"(seed {seed})")


def generate_regrasp_pairs(  # noqa: PLR0913 (the models, the count and keyword-only knobs)
    hand: Hand,
    obj: ObjectModel,
    n_pairs: int,
    seed: int = 0,
    min_mean_distance: float = 0.03,
    *,
    mu: float = MU,
    beta: float = BETA,
    max_attempts: int = 40,
    progress: Callable[[int, int], None] | None = None,
    self_clearance: float | None = SELF_CLEARANCE,
    max_seconds: float | None = None,
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
        progress: optional callable ``progress(found, attempts)`` called after every initial grasp tried.
        self_clearance: self-clearance of both grasps, m (see `generate_grasps`); None: unconstrained.
        max_seconds: wall-time budget, s: no new initial grasp is drawn after it (None: no budget).

    Returns:
        list of (grasp0, grasp_goal); both carry joints.

    Raises:
        UngraspableError: before any solve, if the object is too small, too large or too thin for a
            precision grasp of the hand (`grasp_feasibility.check_graspable`).
        GraspError: if the pairs could not be found (within `max_seconds`, if given).
    """
    check_graspable(hand, obj, self_clearance)
    t_end = None if max_seconds is None else time.monotonic() + float(max_seconds)
    search = _search(hand, obj, mu, beta, self_clearance)
    pairs: list[tuple[Grasp, Grasp]] = []
    def out_of_time(i: int) -> GraspError:
        return GraspError(f"found {len(pairs)} of {n_pairs} regrasp pairs on {obj.name!r} in the "
                          f"{max_seconds:g} s budget (seed {seed}, {i} initial grasps tried)")

    for i in range(20 * n_pairs):
        if t_end is not None and time.monotonic() > t_end:
            raise out_of_time(i)
        try:
            init = _generate(search, 1, seed * 100003 + i, None, 60, deadline=t_end)[0]
        except GraspError:
            if t_end is not None and time.monotonic() > t_end:
                raise out_of_time(i) from None
            raise
        try:
            goal = _generate(search, 1, seed * 100003 + 50000 + i, init.T_palm_object, max_attempts,
                             away=_Away(init.contacts_object, min_mean_distance), deadline=t_end)[0]
        except GraspError:
            log.debug("pair %d: no desired grasp for this initial grasp", i)
            goal = None
        if goal is not None:
            pairs.append((init, goal))
        if progress is not None:
            progress(len(pairs), i + 1)
        if len(pairs) == n_pairs:
            return pairs
    raise GraspError(f"found {len(pairs)} of {n_pairs} regrasp pairs on {obj.name!r} (seed {seed})")
