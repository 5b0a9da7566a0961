"""Self-collision of the hand's collision spheres: which sphere pairs count, and their distances.

A *self-collision pair* is two collision spheres (tips included) on different bodies: two different
fingers, or a finger and the palm (a sphere whose link no finger's joints move; `CollisionSphere.finger`
is None). Spheres of one finger are never paired (its links are a chain that the joint limits keep
apart, and its sphere cover overlaps at every joint by construction).

Two kinds of pairs are left out:

* **excluded** pairs "always touch at a joint" — they never count, neither in an NLP nor in `verify`. The
  rule (`touching_pairs`), over `TOUCH_SAMPLES` seeded in-limit configurations (`sample_configurations`):
  a pair whose links are joined by one joint (the palm and a finger's first link: adjacent links, as in
  MoveIt's collision matrix), or a pair that comes within the clearance at some sample while its surface
  distance never exceeds `TOUCH_SPAN` at any sample (the two spheres stay within 2 cm of each other over
  the whole joint range: they sit on either side of a joint, like a finger's second link and the palm,
  whose joint axes are 16 mm apart on the Allegro). A shipped model stores the result in its
  ``hand.yaml`` (``self_collision.exclude``: link-name pairs for the adjacent links, sphere-label pairs
  for the others; for the Allegro written by ``models/allegro_right/self_collision.py``), so the list is
  data; a hand without that entry gets the rule at run time.
* **pruned** pairs cannot come within the clearance anywhere in the joint limits, so an NLP needs no
  constraint for them (`Hand.self_collision_pairs(within=clearance)`). The bound is sampled: the
  smallest surface distance over `PRUNE_SAMPLES` in-limit configurations, of which each joint is at one
  of its limits with probability `LIMIT_FRACTION` (distances between links are smallest at the limits);
  a pair is kept when that bound is ≤ clearance + `PRUNE_MARGIN`. Measured on the Allegro against local
  minimisation (the least of 20,000 samples and of L-BFGS-B from 6 random starts; 738 pairs, not excluded):
  the bound of these 8,000 samples is at most 1.4 mm above the minimum (p99 1.1 mm; 5,000 samples with
  each joint at a limit with probability 0.6: 5.5 mm; 4,000 uniform samples: 19 mm), hence the 5 mm margin.

Distances are between sphere surfaces: |c_a − c_b| − r_a − r_b, m (negative: the spheres overlap).

    >>> pairs = hand.self_collision_pairs("index", within=0.001)     # (a, b) indices into hand.spheres
    >>> d = hand.sphere_pair_distance_function(pairs)(q)              # (P,) m, symbolic or numeric
"""

from __future__ import annotations

import dataclasses
import itertools
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from regrasp_casadi.hand import Hand

__all__ = [
    "LIMIT_FRACTION",
    "PRUNE_MARGIN",
    "PRUNE_SAMPLES",
    "SELF_TAU",
    "SelfCollisionConstraint",
    "TOUCH_SAMPLES",
    "TOUCH_SPAN",
    "body_groups",
    "candidate_pairs",
    "closest_per_link_pair",
    "distance_extremes",
    "excluded_pairs",
    "natural_key",
    "pair_distances",
    "pair_lower_bounds",
    "sample_configurations",
    "touching_pairs",
]

TOUCH_SAMPLES = 20000
"""Configurations of the exclusion rule (`touching_pairs`)."""
TOUCH_SPAN = 0.02
"""A pair whose surface distance stays ≤ this over every sample sits at a joint (exclusion rule), m."""
PRUNE_SAMPLES = 8000
"""Configurations of the sampled lower bound of the pruning (`pair_lower_bounds`)."""
PRUNE_MARGIN = 0.005
"""A pair is a constraint when its sampled bound is ≤ clearance + this, m (> 3 × the 1.4 mm measured gap)."""
LIMIT_FRACTION = 0.7
"""Probability that a sampled joint sits at one of its limits (half at each)."""
SELF_TAU = 2e-4
"""Temperature of the smooth minimum over the sphere pairs of one rigid-body pair in the NLPs, m: the
constraint is stricter than the hard minimum by at most τ·log(pairs of the bodies)."""
_CHUNK = 500  # configurations per block of the distance extremes (memory: chunk × pairs floats)


def sample_configurations(hand: Hand, n: int, seed: int = 0,
                          limit_fraction: float = LIMIT_FRACTION) -> NDArray[np.float64]:
    """(n, n_joints) in-limit configurations: each joint at its lower or upper limit with probability
    `limit_fraction` / 2 each, else uniform in its limits (continuous joints in [-π, π]), rad."""
    lo, hi = hand._finite_limits()
    rng = np.random.default_rng(seed)
    Q = rng.uniform(lo, hi, size=(n, hand.n_joints))
    u = rng.random((n, hand.n_joints))
    return np.where(u < 0.5 * limit_fraction, lo, np.where(u < limit_fraction, hi, Q))


def candidate_pairs(hand: Hand) -> tuple[tuple[int, int], ...]:
    """Every pair (a, b), a < b, of indices into `hand.spheres` on different bodies (two fingers, or a
    finger and the palm), excluded or not."""
    owner = [s.finger for s in hand.spheres]
    k = len(owner)
    return tuple((a, b) for a in range(k) for b in range(a + 1, k) if owner[a] != owner[b])


def body_groups(hand: Hand, pairs) -> tuple[tuple[int, ...], ...]:
    """Indices into `pairs` grouped by rigid-body pair (`Hand.rigid_body` of both spheres' links), in
    the order of first appearance."""
    groups: dict[tuple[str, str], list[int]] = {}
    for i, (a, b) in enumerate(pairs):
        key = tuple(sorted((hand.rigid_body(hand.spheres[a].link), hand.rigid_body(hand.spheres[b].link))))
        groups.setdefault(key, []).append(i)
    return tuple(tuple(g) for g in groups.values())


def closest_per_link_pair(hand: Hand, pairs, distances: NDArray) -> list[int]:
    """Indices into `pairs` of the closest sphere pair of each link pair, by `distances` (P,), closest
    first."""
    best: dict[tuple[str, str], int] = {}
    for i in np.argsort(distances, kind="stable"):
        a, b = pairs[i]
        best.setdefault((hand.spheres[a].link, hand.spheres[b].link), int(i))
    return list(best.values())


def pair_distances(hand: Hand, centers: NDArray, pairs) -> NDArray[np.float64]:
    """Surface distances (..., P) of `pairs` (P pairs (a, b) of indices into `hand.spheres`) for sphere
    centres `centers` (..., k, 3) in `hand.spheres` order, m."""
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    radii = np.array([s.radius for s in hand.spheres])
    a, b = pairs[:, 0], pairs[:, 1]
    d = np.moveaxis(centers, -1, 0)  # (3, ..., k): sums of squares per coordinate plane take half the
    d = d[..., a] - d[..., b]  # time of np.linalg.norm over the last axis (8000 x 1653 pairs: 0.28 / 0.58 s)
    return np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - (radii[a] + radii[b])


def distance_extremes(hand: Hand, pairs, Q: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(smallest (P,), largest (P,)) surface distance of `pairs` over the configurations `Q` (N, n), m."""
    P = len(pairs)
    lo, hi = np.full(P, np.inf), np.full(P, -np.inf)
    for start in range(0, len(Q), _CHUNK):
        C = np.stack([hand.sphere_centers(q, None, include_tip=True) for q in Q[start:start + _CHUNK]])
        D = pair_distances(hand, C, pairs)
        lo, hi = np.minimum(lo, D.min(axis=0)), np.maximum(hi, D.max(axis=0))
    return lo, hi


def pair_lower_bounds(hand: Hand, pairs, n: int = PRUNE_SAMPLES, seed: int = 0) -> NDArray[np.float64]:
    """Sampled lower bound (P,) of the surface distance of each pair over the joint limits, m (the
    smallest over `n` limit-biased samples; see the module docstring for its accuracy)."""
    lo, _ = distance_extremes(hand, pairs, sample_configurations(hand, n, seed))
    return lo


def touching_pairs(hand: Hand, clearance: float, n: int = TOUCH_SAMPLES,
                   seed: int = 0) -> tuple[tuple[str, str], ...]:
    """The exclusion rule (module docstring), sorted: link-name pairs of the links joined by one joint
    (every sphere of one against every sphere of the other), then sphere-label pairs of the other pairs
    that come within `clearance` (m) at some sample while never more than `TOUCH_SPAN` apart."""
    spheres = hand.spheres
    pairs = candidate_pairs(hand)
    lo, hi = distance_extremes(hand, pairs, sample_configurations(hand, n, seed))
    links, labels = set(), set()
    for (a, b), d_min, d_max in zip(pairs, lo, hi, strict=True):
        la, lb = spheres[a].link, spheres[b].link
        if hand.parent_link(la) == lb or hand.parent_link(lb) == la:
            links.add(tuple(sorted((la, lb), key=natural_key)))
        elif d_min <= clearance and d_max <= TOUCH_SPAN:
            labels.add(tuple(sorted((spheres[a].label, spheres[b].label), key=natural_key)))
    return tuple(sorted(links, key=_pair_key)) + tuple(sorted(labels, key=_pair_key))


def natural_key(name: str) -> tuple:
    """Sort key of a link name or sphere label with its numbers compared as numbers (``#2`` < ``#10``)."""
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))


def _pair_key(pair: tuple[str, str]) -> tuple:
    return natural_key(pair[0]), natural_key(pair[1])


def excluded_pairs(hand: Hand) -> frozenset[tuple[int, int]]:
    """The excluded pairs (a, b), a < b, indices into `hand.spheres`: the metadata's label pairs
    (``hand.yaml``'s ``self_collision.exclude``), else the rule `touching_pairs`.

    Raises:
        ModelError: the metadata names an unknown sphere label or a pair on one body.
    """
    from regrasp_casadi.constants import SELF_CLEARANCE
    from regrasp_casadi.errors import ModelError

    names = hand.metadata.self_collision_exclude
    if names is None:
        names = touching_pairs(hand, SELF_CLEARANCE)
    index: dict[str, list[int]] = {}  # sphere label or link name -> sphere indices
    for i, s in enumerate(hand.spheres):
        index.setdefault(s.label, []).append(i)
        index.setdefault(s.link, []).append(i)
    out = set()
    for pair in names:
        where = f"{hand.metadata.source}: self_collision.exclude: {pair[0]}: {pair[1]}"
        unknown = [x for x in pair if x not in index]
        if unknown:
            raise ModelError(f"{where}: {unknown[0]!r} is neither a sphere label nor a link with spheres")
        for a, b in itertools.product(index[pair[0]], index[pair[1]]):
            if hand.spheres[a].finger == hand.spheres[b].finger:
                raise ModelError(f"{where}: {hand.spheres[a].label} and {hand.spheres[b].label} are on one "
                                 "body")
            out.add((min(a, b), max(a, b)))
    return frozenset(out)


HOLD_TOL = 1e-5
"""How far below its floor a solve's result may be and still hold, m (IPOPT's acceptable points may
violate a little)."""


@dataclass(frozen=True)
class SelfCollisionConstraint:
    """The self-collision constraints of one NLP: one smooth minimum per rigid-body pair of `pairs`
    (`Hand.sphere_pair_distance_function` with `SELF_TAU`), each ≥ its floor: the clearance, or the
    body pair's value at the start of a solve where that is smaller (a grasp that starts in
    self-collision may not get worse)."""

    hand: Hand
    pairs: tuple[tuple[int, int], ...]
    """The sphere pairs (indices into `hand.spheres`)."""
    function: ca.Function
    """q (n,) -> (G,) smooth minimum per rigid-body pair, m."""
    clearance: float
    """The clearance, m."""

    @classmethod
    def build(cls, hand: Hand, finger: str | None, clearance: float | None) -> SelfCollisionConstraint | None:
        """The constraints of `finger`'s spheres against the others (None: every pair) for `clearance`
        (m; None: no constraint, returns None), over `Hand.self_collision_pairs(finger, within=clearance)`."""
        if clearance is None:
            return None
        pairs = hand.self_collision_pairs(finger, within=clearance)
        return cls(hand, pairs, hand.sphere_pair_distance_function(pairs, SELF_TAU), float(clearance))

    def extend(self, g, lbg: NDArray, ubg: NDArray, q, scale: float):
        """(g, lbg, ubg) with the constraints at the joint expression `q` appended, scaled by `scale`
        (the NLP's distance unit per m); the lower bounds are the clearance (see `bounds` per solve)."""
        d = self.function(q)
        size = d.shape[0]
        return (ca.vertcat(g, scale * d), np.concatenate([lbg, np.full(size, scale * self.clearance)]),
                np.concatenate([ubg, np.full(size, np.inf)]))

    def floor(self, q: ArrayLike) -> NDArray[np.float64]:
        """(G,) lower bounds, m, of the solves that start at the joints `q`: the clearance, or the start's
        value + `HOLD_TOL` where that is smaller (so that a start `holds` let `HOLD_TOL` below its own
        floor does not lower the next floor: 100 reposings in a row eroded 1 mm to 0.958 mm, measured)."""
        return np.minimum(self.clearance, self.values(q) + HOLD_TOL)

    def values(self, q: ArrayLike) -> NDArray[np.float64]:
        """(G,) the constrained smooth minima at the joints `q`, m."""
        return np.asarray(self.function(np.asarray(q, float)), float).ravel()

    def bounds(self, bounds, q: ArrayLike, scale: float):
        """`bounds` (a `solver.Bounds` whose last G constraints are these) with the floors of the
        solves from `q`, and those floors (G,) m."""
        floor = self.floor(q)
        lbg = bounds.lbg.copy()
        lbg[lbg.size - floor.size:] = scale * floor
        return dataclasses.replace(bounds, lbg=lbg), floor

    def holds(self, q: ArrayLike, floor: NDArray, tol: float = HOLD_TOL) -> bool:
        """Every constraint at `q` at least its `floor` − `tol` (m; IPOPT's acceptable points may
        violate a little)."""
        return bool(np.all(self.values(q) >= floor - tol))

    def min_distance(self, q: ArrayLike) -> float:
        """The smallest surface distance of the constrained sphere pairs at `q`, m (inf: none)."""
        d = self.hand.self_collision_distances(q, self.pairs)
        return float(np.min(d, initial=np.inf))
