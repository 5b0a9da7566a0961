"""Staging of a pinned finger: where the other fingers wait so that it can slide to its goal, certified.

With `PlannerOptions.stability` "force_closure", a finger that opposes all the others (the Allegro
thumb against index, middle and ring) can never lift: the three fingers left on one side are not in force
closure. It can only slide, and a sliding finger pushes along its normal and drags the object with kinetic
friction along its motion (`holding.Holding.slide`; the figures below were measured when it was taken
as frictionless). In most regrasps that slide is not certified at all: with the other fingers where they
are, or at their goals, a frictionless thumb on its path from its contact to its goal leaves the grasp
without force closure (measured on the shipped problems: margins −0.03 to −0.17 along the path, both
with the others where they start and with them at their goals). The greedy round then stalls: the other
fingers reach their goals and the thumb stays where it is.

The way out is a detour of the other fingers. This module searches, in contact space (force closure
depends on the contacts only, not on the hand's configuration), for a *support configuration*: contacts
S_j of the other fingers such that the pinned finger's whole straight surface path from its contact to
its goal is certified with it sliding and the others at S_j, and such that the moved fingers can
get to S one by one with certified lifts. The planner then aims the other fingers at S (their gaits,
each certified as usual), slides the pinned finger to its goal, and moves the others on to their goals.

Candidates: each other finger stays or moves (probability 0.6) to `λ·goal + (1 − λ)·current + N(0, σ²)`,
projected onto the exact surface, at most 3 cm (then 5 cm) from where it is. Among the certified ones,
the least cost: the detour Σ_j (|S_j − c_j| + |S_j − g_j| − |c_j − g_j|), plus 1 cm per finger that
could not then lift to its goal with the pinned finger at its goal, plus 10 × the IK shortfall of the
targets in the current object pose (`tip_ik`, joint limits only).

It is the planner's last resort (`HoldingOptions.staging`): a plan whose greedy certified rounds stall
for `stall_limit` iterations turns it on (`planner._Run.start_staging`) and gets `stall_limit` more; a
plan that converges without it is unchanged. Measured (shipped problems, force closure): 6 of 10 plans
converge with it, 4 of 10 without.

    >>> stage = find_staging(run, "thumb")      # None when no support configuration was found
    >>> stage.tips                               # (m, 3) tip-centre targets, object frame, m
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from regrasp_casadi.planner import _Run

__all__ = ["Staging", "find_staging", "path_margin", "pinned_finger", "update_staging"]

_log = logging.getLogger(__name__)

_PATH_SAMPLES = 9
"""Points of the pinned finger's surface path whose certificates are computed (both ends included)."""
_RETRY = 3
"""Iterations after a failed staging search before the same finger is searched again."""
_REACH = (0.03, 0.05)
"""How far (m) the staging search may move each other finger: the nearer first, the farther when the
nearer finds none."""
_UNREACHABLE_WEIGHT = 10.0
"""Weight of the IK shortfall (m per m) in the staging cost: a target 1 mm out of reach costs 1 cm of
detour."""
_PROGRESS = 1e-3
"""A staging makes progress when its fingers' total distance to their targets drops by this, m."""
_PATIENCE = 2
"""Rounds without progress after which a staging is given up (its finger is searched again later)."""
_REACHED = 1.5e-3
"""A finger within this distance of its staging target, m, is there."""


@dataclass
class Staging:
    """A support configuration for a pinned finger."""

    finger: str
    """The pinned finger (it slides to its goal once the others are in place)."""
    tips: NDArray[np.float64]
    """(m, 3) tip-centre targets, object frame, m: the other fingers' support positions; the pinned
    finger's row is its goal."""
    margin: float
    """The least certificate margin along the pinned finger's path with the others at `tips` (ε for
    force closure, the weight scale for gravity)."""
    iteration: int
    """The planner iteration the staging was found in."""
    last_error: float = np.inf
    """The pinned finger's contact error at the last round, m."""
    best_to_go: float = np.inf
    """The least total distance of the other fingers from their targets so far, m."""
    idle: int = 0
    """Rounds since that distance last dropped by more than `_PROGRESS`."""

    def finger_sliding(self, run: _Run) -> bool:
        """Whether the pinned finger came closer to its goal (by `_PROGRESS`) since the last round."""
        err = float(run.steps[-1].contact_error[run.fingers.index(self.finger)])
        moved = err < self.last_error - _PROGRESS
        self.last_error = min(err, self.last_error)
        return moved


def _surface(run: _Run, tips: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """Tip centres (k, 3) projected onto the exact surface: (tips on the surface, contacts, outward
    normals), each (k, 3), object frame, m."""
    contacts, sd = run.obj.closest_points(np.asarray(tips, float).reshape(-1, 3))
    away = (tips - contacts) * np.sign(np.where(np.asarray(sd) == 0, 1.0, sd))[:, None]
    normals = away / np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-12)
    return contacts + float(run.hand.tip_radius) * normals, np.asarray(contacts, float), normals


def path_margin(run: _Run, contacts: NDArray, normals: NDArray, finger: int, path_c: NDArray,
                path_n: NDArray, strict: bool = False) -> float | None:
    """The least certificate margin (ε for force closure, the weight scale for gravity) of the grasp
    (`contacts`, `normals` (m, 3), object frame) while finger `finger` (its row) slides along the surface
    points `path_c`, `path_n` (k, 3), dragging the object with kinetic friction along its motion from the
    previous point (`Holding.sliding_normal`); None as soon as a sample is not certified
    (`Holding.certified`; `strict`: a force-closure ε of at least twice `min_margin`)."""
    m, holding = len(contacts), run.holding
    slide = np.arange(m) == finger
    floor = 2.0 * holding.options.min_margin if strict and holding.kind == "force_closure" else -np.inf
    worst = np.inf
    path_c = np.asarray(path_c, float).reshape(-1, 3)
    ways = np.diff(np.vstack([contacts[finger], path_c]), axis=0)  # the slide's motion at each sample
    for c_k, n_k, way in zip(path_c, path_n, ways, strict=True):
        c, n = contacts.copy(), normals.copy()
        c[finger], n[finger] = c_k, holding.sliding_normal(n_k, way)
        cert = holding.hypothetical(c, n, run.T_palm_object, np.ones(m, bool), slide)
        if not holding.certified(cert) or cert.margin < floor:
            return None
        worst = min(worst, float(cert.margin))
    return float(worst)


def pinned_finger(run: _Run) -> str | None:
    """The finger farther than ζ from its goal that can neither lift nor slide its straight surface path
    to its goal with a certificate (the others where they are); the farthest such, None when none."""
    holding, T = run.holding, run.T_palm_object
    err = run.steps[-1].contact_error
    contacts, normals = holding.contacts(run.q, T)
    pinned = []
    for r, f in enumerate(run.fingers):
        if err[r] <= run.options.zeta or holding.certified(holding.lift(run.q, T, f)):
            continue
        path_c, path_n = _path(run, contacts, normals, r)
        if path_margin(run, contacts, normals, r, path_c, path_n) is None:
            pinned.append((err[r], f))
    return max(pinned)[1] if pinned else None


def _path(run: _Run, contacts: NDArray, normals: NDArray, r: int) -> tuple[NDArray, NDArray]:
    """The straight tip path of finger r from its contact to its goal, projected onto the surface:
    contacts and normals (`_PATH_SAMPLES`, 3), object frame."""
    tip = contacts[r] + float(run.hand.tip_radius) * normals[r]
    u = np.linspace(0.0, 1.0, _PATH_SAMPLES)[:, None]
    _, path_c, path_n = _surface(run, (1 - u) * tip + u * run.goal_tips[r])
    return path_c, path_n


def find_staging(run: _Run, finger: str, samples: int = 600, sigma: tuple[float, ...] = (0.01, 0.02, 0.03),
                 seed: int = 0, max_move: float = 0.03) -> Staging | None:
    """Search for a support configuration of the other fingers that certifies `finger`'s slide to its
    goal (see the module docstring): `samples` candidates in which each other finger either stays or
    moves (probability 0.6) to a point spread by the standard deviations `sigma` (m, in turn) about the
    segment from its contact to its goal, at most `max_move` (m) from where it is; seeded (the same run
    gives the same staging). A candidate counts when the whole path is certified and the moved fingers
    can get there one by one with certified lifts (`_entry_order`). None when none does."""
    holding, T, R = run.holding, run.T_palm_object, float(run.hand.tip_radius)
    m, i = len(run.fingers), run.fingers.index(finger)
    contacts, normals = holding.contacts(run.q, T)
    tips_now = contacts + R * normals
    path_c, path_n = _path(run, contacts, normals, i)
    rng = np.random.default_rng(seed)
    lam = rng.uniform(0.0, 1.0, size=(samples, m, 1))
    spread = np.resize(np.asarray(sigma, float), samples)[:, None, None]
    cand = (1 - lam) * tips_now + lam * run.goal_tips + spread * rng.normal(0.0, 1.0, (samples, m, 3))
    moves = rng.random((samples, m)) < 0.6
    moves[:, i] = False
    tips_s, c_s, n_s = (x.reshape(samples, m, 3) for x in _surface(run, cand.reshape(-1, 3)))  # one query
    found = []
    for k in range(samples):
        moved = np.flatnonzero(moves[k])
        if moved.size == 0:
            continue
        tips_k, c_k, n_k = tips_s[k, moved], c_s[k, moved], n_s[k, moved]
        if np.max(np.linalg.norm(tips_k - tips_now[moved], axis=1)) > max_move:
            continue
        c, n = contacts.copy(), normals.copy()
        c[moved], n[moved] = c_k, n_k
        worst = path_margin(run, c, n, i, path_c, path_n, strict=True)
        if worst is not None and _entry_order(run, contacts, normals, c, n, moved):
            t = tips_now.copy()
            t[moved], t[i] = tips_k, run.goal_tips[i]
            found.append((t, c, n, worst))
    if not found:
        _log.debug("staging of %s: none of %d support candidates certifies its path", finger, samples)
        return None
    best = min(found, key=lambda f: _staging_cost(run, f[0], f[1], f[2], i, tips_now))
    _log.debug("staging of %s: %d of %d candidates certify its path and can be reached; least margin %.4f",
               finger, len(found), samples, best[3])
    return Staging(finger, best[0], best[3], run.iterations)


def _entry_order(run: _Run, c_now: NDArray, n_now: NDArray, c_to: NDArray, n_to: NDArray,
                 moved: NDArray) -> bool:
    """Whether the fingers `moved` can go from (c_now, n_now) to (c_to, n_to) (m, 3), object frame, one
    at a time in some order, each lift certified (the ones moved before it at their new contacts)."""
    m = len(c_now)
    for order in itertools.permutations(moved.tolist()):
        c, n = c_now.copy(), n_now.copy()
        for j in order:
            hold = np.arange(m) != j
            cert = run.holding.hypothetical(c, n, run.T_palm_object, hold, np.zeros(m, bool))
            if not run.holding.certified(cert):
                break
            c[j], n[j] = c_to[j], n_to[j]
        else:
            return True
    return False


def _staging_cost(run: _Run, tips: NDArray, contacts: NDArray, normals: NDArray, i: int,
                  tips_now: NDArray) -> float:
    """Detour of the other fingers through `tips` (m), plus 1 cm per finger that cannot then lift to
    its goal with finger i at its goal (force closure of the rest)."""
    goal = run.goal_tips
    detour = np.linalg.norm(tips - tips_now, axis=1) + np.linalg.norm(tips - goal, axis=1) \
        - np.linalg.norm(tips_now - goal, axis=1)
    c, n = contacts.copy(), normals.copy()
    c[i] = run.goal_contacts[i]
    n[i] = (goal[i] - c[i]) / max(float(np.linalg.norm(goal[i] - c[i])), 1e-12)
    m = len(tips)
    stuck = 0
    for j in range(m):
        if j != i:
            hold = np.arange(m) != j
            stuck += not run.holding.certified(run.holding.hypothetical(c, n, run.T_palm_object, hold,
                                                                        np.zeros(m, bool)))
    short = _unreachable(run, tips, i)
    return float(np.sum(np.delete(detour, i)) + 0.01 * stuck + _UNREACHABLE_WEIGHT * short)


def _unreachable(run: _Run, tips: NDArray, i: int) -> float:
    """How far (m, summed) the fingers' tips fall short of the targets `tips` (m, 3), object frame, in
    the current object pose, by damped least-squares IK of each finger alone (`tip_ik`; joint limits
    only): the other fingers' staging targets and finger i's goal."""
    from regrasp_casadi.tip_ik import tip_ik

    T, hand = run.T_palm_object, run.hand
    targets = tips.copy()
    targets[i] = run.goal_tips[i]
    p_palm = targets @ T[:3, :3].T + T[:3, 3]
    now = run.tips_object()
    short = 0.0
    for j, f in enumerate(run.fingers):
        if np.linalg.norm(targets[j] - now[j]) < _REACHED:
            continue
        _, e = tip_ik(hand, run.q, [f], p_palm[j][None], hand.finger_joints[f], run.q)
        short += float(np.linalg.norm(e))
    return short


def update_staging(run: _Run) -> None:
    """Keep `run.staging` current at the start of a certified round: drop it when its finger is within ζ
    of its goal, or when its fingers have not come closer to their targets for `_PATIENCE` rounds
    (kinematics stop them; the finger is searched again `_RETRY` iterations later); else, when none is
    active, the planner has turned staging on (`_Run.start_staging`: the plan stalled) and some finger
    is pinned (`pinned_finger`), search one (`find_staging`)."""
    st = run.staging
    if st is not None:
        r = run.fingers.index(st.finger)
        to_go = sum(staging_error(run, f) or 0.0 for f in run.fingers)
        if to_go < st.best_to_go - _PROGRESS or st.finger_sliding(run):
            st.best_to_go, st.idle = min(to_go, st.best_to_go), 0
        else:
            st.idle += 1
        if run.steps[-1].contact_error[r] <= run.options.zeta:
            _log.debug("staging of %s ends (reached)", st.finger)
            run.staging = None
        elif st.idle > _PATIENCE:
            _log.debug("staging of %s given up (%.1f mm to go)", st.finger, to_go * 1e3)
            run.staging_failed[st.finger] = run.iterations
            run.staging = None
        return
    if not run.staging_on:
        return
    finger = pinned_finger(run)
    if finger is not None and run.iterations - run.staging_failed.get(finger, -_RETRY) >= _RETRY:
        for reach in _REACH:  # the nearest support configurations first
            run.staging = find_staging(run, finger, seed=run.iterations, max_move=reach)
            if run.staging is not None:
                break
        if run.staging is None:
            run.staging_failed[finger] = run.iterations


def staging_target(run: _Run, finger: str) -> NDArray | None:
    """The tip-centre target (3,), object frame, m, the active staging gives `finger` (None: none, or
    `finger` is the pinned one, which goes to its goal)."""
    st = run.staging
    if st is None or finger == st.finger:
        return None
    return st.tips[run.fingers.index(finger)]


def staging_error(run: _Run, finger: str) -> float | None:
    """Distance (m) of `finger`'s tip from its staging target (None without one); below `_REACHED`: 0."""
    target = staging_target(run, finger)
    if target is None:
        return None
    d = float(np.linalg.norm(run.tips_object()[run.fingers.index(finger)] - target))
    return 0.0 if d < _REACHED else d
