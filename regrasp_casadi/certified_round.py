"""The planner's gait round when every step must hold the object (`PlannerOptions.stability` on).

One round moves each finger of the gait pattern P (not yet at its goal) once, as the paper's round does,
but only with a certified holding set (`holding.Holding`):

1. *pick* (before any solve: one certificate per candidate, cheap): the next finger of P whose lift
   leaves the others holding the object ("pattern"; "stability": the largest margin first; "search":
   the best progress + margin score, `search_score`); when no finger of the round can lift, the first
   that can *slide* (every finger holds, the slider dragging the object with kinetic friction along
   its way to its goal, `Holding.slide`); when none can, the round ends (the
   reposing follows);
2. *gait* (OPT1): while some finger farther than ζ from its goal can only slide, the finger goes where
   that slide stays certified and can advance (`_support_target`: a search over surface points, its
   certificates with 4-edge cones), else straight to its goal; with `HoldingOptions.lookahead`, a new
   contact that leaves a finger still to move (this round, else the next; farther than ζ from its goal)
   without the certified lift or slide it has now is refused and OPT1 is solved again with a halved
   step bound (η/2, η/4, ...; when none passes, the first solution is kept);
3. *slide*: the finger moves towards its goal in steps of at most `slide_step` (OPT1 with that step
   bound), each a plan step of kind "slide" whose tip stays within `slide_tol` of the surface at every
   sample of the joints' linear path and whose holding set is certified at both ends, until the tip
   has travelled η (one gait's worth), reached its goal, or cannot go on.

The functions take the planner's `_Run` (its grasp, NLPs, steps and bookkeeping).
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.staging import staging_error, staging_target, update_staging
from regrasp_casadi.surface_route import gait_target

if TYPE_CHECKING:
    from regrasp_casadi.certificates import Certificate
    from regrasp_casadi.finger_gait import FingerGaitResult
    from regrasp_casadi.planner import _Run

__all__ = ["certified_round", "accept_gait", "search_score", "slide_path_error"]

_log = logging.getLogger(__name__)

GAIT_RETRIES = 2
"""Gaits with half the step bound tried when a gait's path fails its checks (`accept_gait`)."""
_MIN_MOVE = 1e-5
"""A solve that moves the tip less than this, m, made no move."""
_PATH_SAMPLES = 8
"""Interior samples of a slide step's joint path checked against the surface."""


def certified_round(run: _Run) -> None:
    """One gait round of `run` with certified holding sets (see the module docstring)."""
    o = run.options
    update_staging(run)
    budget = {f: o.finger_gait.eta for f in run.gait}  # tip travel left to each finger this round, m
    slid = dict.fromkeys(run.gait, 0.0)  # slide travel of each finger this round, m
    blocked: set[str] = set()  # sliders that could not slide since another finger last moved
    while True:
        active = [f for f in run.gait if budget[f] > _MIN_MOVE and _to_go(run, f) > o.skip_tol]
        lifts = {f: run.holding.lift(run.q, run.T_palm_object, f) for f in active}
        order = _order(run, active, lifts)
        if run.holding.options.slide:
            for f in order:
                if f in blocked or run.holding.certified(lifts[f]):
                    continue
                cert = run.holding.slide(run.q, run.T_palm_object, f, _goal_way(run, run.q, f))
                room = run.holding.options.slide_budget * o.finger_gait.eta - slid[f]
                travelled = _slide(run, f, room) if run.holding.certified(cert) else 0.0
                slid[f] += travelled
                if travelled < _MIN_MOVE or room - travelled <= _MIN_MOVE:
                    blocked.add(f)
        lifts = {f: run.holding.lift(run.q, run.T_palm_object, f) for f in active}  # after the slides
        lifters = [f for f in order if run.holding.certified(lifts[f]) and budget[f] > _MIN_MOVE]
        if not lifters:
            return
        finger = lifters[0]
        rest = [f for f in active if f != finger and budget[f] > _MIN_MOVE]
        _gait(run, finger, lifts[finger], rest)
        budget[finger] = 0.0
        blocked.clear()


def _to_go(run: _Run, finger: str) -> float:
    """How far `finger` is from where this round sends it, m: its staging target (`staging`), else its
    goal contact."""
    staged = staging_error(run, finger)
    return float(run.steps[-1].contact_error[run.fingers.index(finger)]) if staged is None else staged


def _order(run: _Run, fingers: list[str], lifts: dict[str, Certificate]) -> list[str]:
    """`fingers` in the order the round tries them: the pattern's, the largest lift margin first
    ("stability") or the best `search_score` first ("search")."""
    order = list(fingers)
    if run.options.gait_order == "stability":
        order.sort(key=lambda f: -lifts[f].margin)
    elif run.options.gait_order == "search":
        order.sort(key=lambda f: -search_score(run, f, lifts[f]))
    return order


def search_score(run: _Run, finger: str, cert: Certificate) -> float:
    """Greedy score of a certified lift of `finger` ("search" order): the progress the gait can make,
    min(contact error, η) / η ∈ [0, 1], plus the holding margin relative to the certified minimum
    (force closure: ε / 0.05; gravity: (scale − 1) / 2), capped at 1."""
    r = run.fingers.index(finger)
    eta = run.options.finger_gait.eta
    progress = min(float(run.steps[-1].contact_error[r]), eta) / eta
    margin = cert.margin / 0.05 if cert.kind == "force_closure" else (cert.margin - 1.0) / 2.0
    return progress + float(np.clip(margin, 0.0, 1.0))


def _solve(run: _Run, finger: str, eta: float | None, target: NDArray | None = None
           ) -> FingerGaitResult | None:
    """OPT1 for `finger` from the current grasp towards `target` (3,), object frame, m (default its goal
    tip centre) with step bound `eta` (None: the options' η); a failed solve is recorded in
    `run.failures` and gives None."""
    r = run.fingers.index(finger)
    target = run.goal_tips[r] if target is None else target
    res = run.gait_nlps[finger].solve(run.q, run.T_palm_object, target, eta=eta)
    run.timing["opt1"] += res.solve_time
    run.solves["opt1"] += res.solves
    if res.success:
        return res
    run.failures.append(f"finger gait of {finger} at step {len(run.steps)} rejected by the exact checks "
                        f"(surface error {res.surface_error * 1e3:.3f} mm, clearance "
                        f"{res.min_clearance * 1e3:.3f} mm; IPOPT: {res.status})")
    _log.debug("%s; the finger stays", run.failures[-1])
    return None


def _tip_object(run: _Run, q: NDArray, finger: str) -> NDArray:
    """(3,) `finger`'s tip centre in the object frame (the run's object pose), m, hand at q (n,) rad."""
    T = run.T_palm_object
    return (np.asarray(run.hand.tip_positions(q), float)[run.fingers.index(finger)] - T[:3, 3]) @ T[:3, :3]


def _goal_way(run: _Run, q: NDArray, finger: str) -> NDArray:
    """(3,) object frame, m: from `finger`'s tip centre (hand at q) to its goal's, the way it would slide."""
    return run.goal_tips[run.fingers.index(finger)] - _tip_object(run, q, finger)


def _tip_move(run: _Run, finger: str, q_new: NDArray) -> float:
    r = run.fingers.index(finger)
    return float(np.linalg.norm(run.hand.tip_positions(q_new)[r] - run.hand.tip_positions(run.q)[r]))


def _gait(run: _Run, finger: str, cert: Certificate, todo: list[str]) -> None:
    """OPT1 for `finger` (its lift certified by `cert`), with the lookahead on the new contact."""
    ho = run.holding.options
    eta = run.options.finger_gait.eta
    err, zeta = run.steps[-1].contact_error, run.options.zeta
    away = [f for f in todo or run.fingers if f != finger and err[run.fingers.index(f)] > zeta]
    keep = _movable(run, run.q, away) if ho.lookahead else {}
    sliders = [f for f in away if not run.holding.certified(run.holding.lift(run.q, run.T_palm_object, f))]
    target = staging_target(run, finger)
    if target is None and sliders and ho.support_search and run.staging is None:
        target = _support_target(run, finger, sliders)
    if target is None:  # its goal, or η along its surface route: once, for every lookahead attempt
        target = gait_target(run, run.fingers.index(finger))
    first = None
    for attempt in range(max(1, ho.lookahead_tries) if ho.lookahead else 1):
        res = _solve(run, finger, None if attempt == 0 else eta, target)
        if res is None or _tip_move(run, finger, res.q) < _MIN_MOVE:
            break
        first = first or res
        if not ho.lookahead or all(_movable(run, res.q, [f for f, ok in keep.items() if ok]).values()):
            first = res
            break
        eta *= 0.5
    if first is not None:
        accept_gait(run, finger, first, cert)


def accept_gait(run: _Run, finger: str, res, certificate: Certificate | None = None) -> bool:
    """Take OPT1's result `res` (a `FingerGaitResult`) as a gait step of `finger` unless its path fails
    its checks (`_Run.unrealisable`, e.g. a transit through a rim or a touch-down into another finger).
    Then the same gait is solved again with half the step bound, at most `GAIT_RETRIES` times, and the
    first shorter gait whose path passes is taken (a shorter lift-transit-touch-down sweeps less of the
    finger past the object); none: the finger stays and the first reason goes to `run.failures`. True
    when a gait is taken. The paper's rounds use it too."""
    bad, path = run.unrealisable(res.q, run.T_palm_object, "gait", finger)
    shorter = res
    for _ in range(GAIT_RETRIES if bad and res.p_object_tip_goal is not None else 0):
        shorter = run.gait_nlps[finger].solve(run.q, run.T_palm_object, res.p_object_tip_goal,
                                              eta=0.5 * shorter.eta)
        run.timing["opt1"] += shorter.solve_time
        run.solves["opt1"] += shorter.solves
        if not shorter.success or _tip_move(run, finger, shorter.q) < _MIN_MOVE:
            break
        why, shorter_path = run.unrealisable(shorter.q, run.T_palm_object, "gait", finger)
        if not why:
            res, bad, path = shorter, "", shorter_path
            break
    if bad:
        run.failures.append(f"gait of {finger} at step {len(run.steps)} refused: {bad}")
        return False
    run.q = res.q
    run.add_step("gait", finger, res.status, res.solve_time, certificate, path)
    return True


def _support_target(run: _Run, finger: str, sliders: list[str]) -> NDArray | None:
    """Where the lifted `finger` should go so that the fingers that can only slide (`sliders`) keep their
    certified slides and one of them gains one towards its goal. Among `HoldingOptions.support_candidates`
    surface points about η away (the first towards the finger's goal) with the other fingers where they
    are: those that keep every slider that can slide now able to (`min_margin`, its contact) and let one
    of them slide (at its contact and `support_advance` on towards its goal); the one of most progress
    to the finger's goal.
    None such: the one that keeps them and lets a slider advance the most; none keeps them: the one of
    the largest least slider margin. Returns the tip-centre target (3,), object frame, m, or None for the
    finger's own goal (the first candidate)."""
    holding, ho, T = run.holding, run.holding.options, run.T_palm_object
    m, r, eta = len(run.fingers), float(run.hand.tip_radius), run.options.finger_gait.eta
    contacts, normals = holding.contacts(run.q, T)
    tips = contacts + r * normals
    i = run.fingers.index(finger)
    cand_tips, cand_c, cand_n = holding.surface_targets(tips[i], run.goal_tips[i], eta, ho.support_candidates)
    rows = [run.fingers.index(g) for g in sliders]
    can_now = [j for j in rows if holding.certified(holding.slide(run.q, T, run.fingers[j],
                                                                  run.goal_tips[j] - tips[j]))]
    ahead = {}
    for j in rows:
        a = min(ho.support_advance, float(np.linalg.norm(run.goal_tips[j] - tips[j])))
        _, c_adv, n_adv = holding.surface_targets(tips[j], run.goal_tips[j], a, 1)
        ahead[j] = (c_adv[0], n_adv[0])
    keep = np.full(len(cand_tips), np.inf)  # least margin, at their contacts, of the sliders that can now
    adv = np.full(len(cand_tips), -np.inf)  # best slider's margin at its contact and further on
    worst = np.full(len(cand_tips), np.inf)  # worst slider's margin at its contact and further on
    for k in range(len(cand_tips)):
        c, n = contacts.copy(), normals.copy()
        c[i], n[i] = cand_c[k], cand_n[k]
        for j in rows:
            slide = np.arange(m) == j
            n1 = n.copy()
            n1[j] = holding.sliding_normal(n[j], run.goal_tips[j] - tips[j])
            here = holding.hypothetical(c, n1, T, np.ones(m, bool), slide).margin
            if j in can_now:
                keep[k] = min(keep[k], here)
            c2, n2 = c.copy(), n.copy()
            c2[j], n2[j] = ahead[j][0], holding.sliding_normal(ahead[j][1], run.goal_tips[j] - tips[j])
            further = holding.hypothetical(c2, n2, T, np.ones(m, bool), slide).margin
            adv[k] = max(adv[k], min(here, further))
            worst[k] = min(worst[k], here, further)
    goal = run.goal_tips[i]
    progress = np.linalg.norm(tips[i] - goal) - np.linalg.norm(cand_tips - goal, axis=1)
    score = ho.support_score
    if ho.support_switch and (run.stalled // max(run.options.stall_escape, 1)) % 2 == 1:
        score = "best" if score == "worst" else "worst"
    if score == "worst":
        keep = np.minimum(keep, worst)
        adv = worst
    kept = keep >= ho.min_margin
    good = np.flatnonzero(kept & (adv >= ho.min_margin))
    if good.size:
        k = int(good[np.argmax(progress[good])])
    elif kept.any():
        k = int(np.flatnonzero(kept)[np.argmax(adv[kept])])
    else:
        k = int(np.argmax(keep))
    _log.debug("support target of %s for %s: candidate %d, keep %.4f, advance %.4f, progress %.2f mm", finger,
               sliders, k, keep[k], adv[k], progress[k] * 1e3)
    return None if k == 0 else cand_tips[k]


def _movable(run: _Run, q: NDArray, fingers: list[str]) -> dict[str, bool]:
    """Which of `fingers` can move with a certified holding set in the grasp (q, the current object
    pose): lift, or (when slides are allowed) slide; the lookahead keeps the ones that can now."""
    holding, T = run.holding, run.T_palm_object
    out = {}
    for f in fingers:
        ok = holding.certified(holding.lift(q, T, f))
        out[f] = ok or (holding.options.slide
                        and holding.certified(holding.slide(q, T, f, _goal_way(run, q, f))))
    return out


def _slide(run: _Run, finger: str, budget: float) -> float:
    """Slide `finger` towards its goal in certified steps of at most `slide_step` (see the module), the
    tip travelling at most `budget`, m; returns the distance travelled, m. A step goes straight to the
    goal when its end is certified, else to the surface point `slide_step` away of most progress whose
    end is (`_slide_target`); it is kept when both its ends are certified with the finger sliding along
    the step's motion (`Holding.slide`) and its path passes its checks (`_Run.unrealisable`)."""
    holding, ho = run.holding, run.holding.options
    r = run.fingers.index(finger)
    travelled, step = 0.0, ho.slide_step
    while budget - travelled > _MIN_MOVE and run.steps[-1].contact_error[r] > run.options.skip_tol:
        seg = min(step, budget - travelled)
        target = _slide_target(run, finger, seg)
        if target is False:
            break
        res = _solve(run, finger, seg, target)
        if res is None:
            break
        moved = _tip_move(run, finger, res.q)
        if moved < _MIN_MOVE:
            break
        way = _tip_object(run, res.q, finger) - _tip_object(run, run.q, finger)  # the slide's motion
        start, end = (holding.slide(q, run.T_palm_object, finger, way) for q in (run.q, res.q))
        ok = slide_path_error(run, finger, run.q, res.q) <= ho.slide_tol and holding.certified(start) \
            and holding.certified(end)
        bad, path = run.unrealisable(res.q, run.T_palm_object, "slide", finger) if ok else ("off", None)
        if bad:  # off the surface, not certified, or its path fails its checks: a shorter step
            step = 0.5 * min(step, moved)
            if step < 0.25 * ho.slide_step:
                break
            continue
        run.q = res.q
        run.add_step("slide", finger, res.status, res.solve_time, _weaker(start, end), path)
        travelled += moved
    return travelled


def _slide_target(run: _Run, finger: str, distance: float) -> NDArray | None | bool:
    """The tip-centre target (3,), object frame, m, of a slide step of `finger` of about `distance`, m:
    None (its goal) when the slide's end towards the goal is certified (search-cone certificate), else
    the certified one of `support_candidates` surface points of most progress to the goal; False when
    there is none."""
    holding, ho, T = run.holding, run.holding.options, run.T_palm_object
    m, r = len(run.fingers), float(run.hand.tip_radius)
    contacts, normals = holding.contacts(run.q, T)
    i = run.fingers.index(finger)
    tip, goal = contacts[i] + r * normals[i], run.goal_tips[i]
    cand_tips, cand_c, cand_n = holding.surface_targets(tip, goal, distance, ho.support_candidates)
    slide = np.arange(m) == i
    progress = np.linalg.norm(tip - goal) - np.linalg.norm(cand_tips - goal, axis=1)
    for k in np.argsort(-progress, kind="stable"):
        if k != 0 and progress[k] <= 0.0:
            break
        c, n = contacts.copy(), normals.copy()
        c[i], n[i] = cand_c[k], holding.sliding_normal(cand_n[k], cand_c[k] - contacts[i])
        if holding.certified(holding.hypothetical(c, n, T, np.ones(m, bool), slide)):
            return None if k == 0 else cand_tips[k]
    return False


def _weaker(a: Certificate, b: Certificate) -> Certificate:
    """The certificate of the smaller margin (a slide step's: the worse of its two ends)."""
    return a if a.margin <= b.margin else b


def slide_path_error(run: _Run, finger: str, q0: NDArray, q1: NDArray) -> float:
    """Largest |exact distance of `finger`'s tip centre − tip radius|, m, at `_PATH_SAMPLES` interior
    samples of the joints' linear path from `q0` to `q1` (n,) rad (the object still)."""
    r, T = run.fingers.index(finger), run.T_palm_object
    s = np.arange(1, _PATH_SAMPLES + 1) / (_PATH_SAMPLES + 1)
    tips = np.array([run.hand.tip_positions((1 - si) * q0 + si * q1)[r] for si in s])
    _, sd = run.obj.closest_points((tips - T[:3, 3]) @ T[:3, :3])
    return float(np.max(np.abs(np.asarray(sd, float) - run.hand.tip_radius)))
