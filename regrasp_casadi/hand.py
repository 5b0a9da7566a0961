"""Hand: a tree-structured URDF turned into cached CasADi SX kinematics and collision spheres.

The URDF and the hand's metadata file are read by `regrasp_casadi.hand_model` (yourdfpy parses the URDF;
no ROS, no urdf2casadi). Here every link gets a symbolic homogeneous transform ``T_palm_<link>(q)`` built
once; tip positions, Jacobians and sphere centres are ``ca.Function`` objects (SX inside, ``cse=True``)
cached on the instance, callable on numbers, SX or MX.

    >>> hand = Hand.from_model("allegro_right")      # = Hand.allegro_right()
    >>> q = 0.5 * (hand.q_lower + hand.q_upper)
    >>> p_palm_tips = hand.tip_positions(q)          # (4, 3), contact-sphere centres, palm frame, m
    >>> J = hand.tip_jacobian(q, "index")              # (3, 16)
    >>> hand.thumb, hand.gait_forward                  # from models/allegro_right/hand.yaml
    >>> hand.self_collision_distances(q).min()        # spheres of different fingers / palm, m

Self-collision pairs (which count, which are excluded or pruned): `regrasp_casadi.self_collision`.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from regrasp_casadi.errors import ModelError
from regrasp_casadi.hand_model import (
    DEFAULT_MODEL,
    HandMetadata,
    JointModel,
    UrdfModel,
    fallback_metadata,
    load_metadata,
    model_urdf,
    models_dir,
    read_urdf,
)

__all__ = ["CollisionSphere", "Hand"]

logger = logging.getLogger(__name__)


def _function_name(prefix: str, name: str) -> str:
    """A valid CasADi Function name from a URDF name (letters, digits, single underscores)."""
    return prefix + "_" + re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_")


@dataclass(frozen=True)
class CollisionSphere:
    """One collision sphere rigidly attached to a link."""

    link: str
    """Link the sphere is fixed to."""
    center_link: NDArray[np.float64]
    """(3,) centre in the link frame, m."""
    radius: float
    """Radius, m."""
    finger: str | None
    """Finger whose joints move it (None: palm / fixed to the root)."""
    is_tip: bool
    """True for the fingertip contact sphere."""
    label: str = ""
    """Readable label ``"<link>#<k>"`` (k: index among the link's spheres) or ``"<link>#tip"``."""


class Hand:
    """Kinematic and collision model of a multi-fingered hand from a tree-structured URDF.

    Frames: ``palm`` is the URDF root link; ``T_palm_<link>`` maps link coordinates to palm coordinates.
    ``q`` is the (n_joints,) vector of actuated joints in URDF order (rad, or m for prismatic joints).
    """

    def __init__(self, urdf_path: str | Path, fingers: dict[str, str] | None = None) -> None:
        """Read ``urdf_path`` and the ``hand.yaml`` beside it (if that file describes this URDF).

        ``fingers`` maps finger name -> tip link; default: the metadata file's fingers, else the leaf
        links. Fingers that differ from the metadata file's drop its finger-level entries (no thumb, gait
        order = finger order), see `hand_model.fallback_metadata`.

        Raises:
            ModelError: missing/malformed file, unsupported joint, not a tree, unknown tip link, invalid
                metadata file.
        """
        model = read_urdf(urdf_path)
        self.urdf_path: Path = model.path
        """Absolute path of the URDF."""
        self.name: str = model.name
        """Robot name from the URDF (``"allegro_right"`` for the shipped model)."""
        self.root_link: str = model.root_link
        """Root link (the palm frame)."""
        self.link_names: tuple[str, ...] = model.link_names
        """Every link, parents before children."""
        self._parent_joint: dict[str, JointModel] = model.parent_joint
        self._init_joints(model)
        file_meta = load_metadata(model)
        default = dict(file_meta.fingers) if file_meta is not None else {ln: ln for ln in model.leaves}
        fingers = dict(fingers) if fingers is not None else default
        for f, tip in fingers.items():
            if tip not in model.children:
                raise ModelError(f"{model.path}: finger {f!r}: tip link {tip!r} is not a link of the URDF")
        same = file_meta is not None and list(fingers.items()) == list(file_meta.fingers.items())
        self.metadata: HandMetadata = file_meta if same else fallback_metadata(fingers, file_meta)
        """The hand's metadata (``hand.yaml``, or the fallback for a URDF without one)."""
        self._init_fingers(model, fingers)
        self._init_spheres(model)
        self._spec_fingers = None if list(fingers.items()) == list(default.items()) else dict(fingers)
        in_models = same and file_meta.source.parent.parent == models_dir().resolve()
        self._model_name: str | None = file_meta.source.parent.name if in_models else None
        self._fn_cache: dict[tuple, ca.Function] = {}
        self._fast_cache: dict[int, tuple] = {}

    def _init_joints(self, model: UrdfModel) -> None:
        actuated = [j for j in model.joints if j.type != "fixed" and j.mimic is None]
        self.joint_names: tuple[str, ...] = tuple(j.name for j in actuated)
        """Actuated joints = order of q (URDF order)."""
        self._jidx = {n: i for i, n in enumerate(self.joint_names)}
        self.q_lower: NDArray[np.float64] = np.array([j.lower for j in actuated])
        """(n,) lower joint limits, rad or m (-inf for continuous joints)."""
        self.q_upper: NDArray[np.float64] = np.array([j.upper for j in actuated])
        """(n,) upper joint limits, rad or m (+inf for continuous joints)."""

    def _init_fingers(self, model: UrdfModel, fingers: dict[str, str]) -> None:
        self.fingers: tuple[str, ...] = tuple(fingers)
        """Finger names, in the order used by ``tip_positions``."""
        self.tip_links: dict[str, str] = fingers
        """finger -> tip link."""
        self.finger_joints: dict[str, NDArray[np.int64]] = {}
        """finger -> sorted int indices into q of the joints on the path root -> tip."""
        self._path_links: dict[str, set[str]] = {}  # finger -> links on the path root -> tip
        for f, tip in fingers.items():
            chain, ln = [], tip
            self._path_links[f] = {tip}
            while ln in model.parent_joint:
                j = model.parent_joint[ln]
                if j.name in self._jidx:
                    chain.append(self._jidx[j.name])
                elif j.mimic is not None:
                    chain.append(self._jidx[j.mimic[0]])
                ln = j.parent
                self._path_links[f].add(ln)
            self.finger_joints[f] = np.array(sorted(set(chain)), dtype=np.int64)

    def _finger_of(self, link: str) -> str | None:
        """The finger whose joints move `link` (None: fixed to the root, or shared by several fingers)."""
        parent_joint = self._parent_joint
        ln, moved = link, False
        while ln in parent_joint and not moved:
            moved = parent_joint[ln].type != "fixed"
            ln = parent_joint[ln].parent
        if not moved:  # fixed to the root: palm
            return None
        ln = link
        while True:
            owners = [f for f in self.fingers if ln in self._path_links[f]]
            if len(owners) == 1:
                return owners[0]
            if owners or ln not in parent_joint:
                return None
            ln = parent_joint[ln].parent

    def _init_spheres(self, model: UrdfModel) -> None:
        """Sphere assignment: each link's spheres to the finger that moves it; one tip sphere per finger
        (the ``tip_contact`` sphere of the tip link, else its first sphere, else a point)."""
        spheres: list[CollisionSphere] = []
        tip_sphere: dict[str, CollisionSphere] = {}
        tip_by_link = {tip: f for f, tip in self.tip_links.items()}
        for ln in self.link_names:
            items = model.spheres[ln]
            tip_k = None
            if ln in tip_by_link:
                named = [k for k, s in enumerate(items) if s.name == "tip_contact"]
                tip_k = named[0] if named else (0 if items else None)
                if tip_k is None:
                    logger.warning("%s: tip link %r has no collision sphere; using a point tip",
                                   model.path, ln)
                    tip_sphere[tip_by_link[ln]] = CollisionSphere(
                        ln, np.zeros(3), 0.0, tip_by_link[ln], True, f"{ln}#tip"
                    )
            owner = self._finger_of(ln)
            k_nontip = 0
            for k, s in enumerate(items):
                if k == tip_k:
                    tip_sphere[tip_by_link[ln]] = CollisionSphere(
                        ln, s.center_link, s.radius, tip_by_link[ln], True, f"{ln}#tip"
                    )
                else:
                    spheres.append(
                        CollisionSphere(ln, s.center_link, s.radius, owner, False, f"{ln}#{k_nontip}")
                    )
                    k_nontip += 1
        self._tip_sphere = tip_sphere
        self.spheres: tuple[CollisionSphere, ...] = tuple(spheres) + tuple(
            tip_sphere[f] for f in self.fingers
        )
        """Every collision sphere: non-tip spheres (link order) then the tip spheres (finger order)."""
        self.tip_radii: dict[str, float] = {f: tip_sphere[f].radius for f in self.fingers}
        """finger -> radius of its tip contact sphere, m."""
        radii = set(self.tip_radii.values())
        if len(radii) > 1:
            logger.warning("%s: fingertip radii differ %s; tip_radius is their maximum", model.path,
                           self.tip_radii)
        self.tip_radius: float = max(radii) if radii else 0.0
        """Radius of the fingertip contact sphere, m."""

    # ------------------------------------------------------------------ construction helpers
    @classmethod
    def from_urdf(cls, path: str | Path, fingers: dict[str, str] | None = None) -> Hand:
        """Build a Hand from a URDF file; ``fingers`` maps finger name -> tip link (default: the
        ``hand.yaml`` beside the URDF, else the leaf links).

        Raises:
            TypeError: `path` is not a path (str or os.PathLike).
            ModelError: as `Hand`.
        """
        if not isinstance(path, (str, os.PathLike)):
            raise TypeError(f"path: expected a URDF file path, got {type(path).__name__}")
        return cls(path, fingers)

    @classmethod
    def from_model(cls, model: str | Path) -> Hand:
        """A hand model: a shipped model's name (``"allegro_right"``) or a model folder (URDF + hand.yaml).

        Raises:
            ModelError: unknown model, no ``hand.yaml``, or an invalid URDF or metadata file.
        """
        return cls(model_urdf(model))

    @classmethod
    def allegro_right(cls) -> Hand:
        """The shipped Allegro hand v4 (right) model, ``models/allegro_right``."""
        return cls.from_model("allegro_right")

    @classmethod
    def default(cls) -> Hand:
        """The default hand model (`hand_model.DEFAULT_MODEL`)."""
        return cls.from_model(DEFAULT_MODEL)

    def spec(self) -> dict:
        """How to rebuild this hand: ``{"model": "allegro_right"}`` (a shipped model with its own fingers)
        or ``{"urdf": "/abs/path"}`` (plus ``"fingers"`` when they are not the default ones)."""
        if self._model_name is not None:
            return {"model": self._model_name}
        spec: dict = {"urdf": str(self.urdf_path)}
        if self._spec_fingers is not None:
            spec["fingers"] = dict(self._spec_fingers)
        return spec

    @classmethod
    def from_spec(cls, spec: dict) -> Hand:
        """Inverse of ``spec()``. Raises ModelError for an unknown model or a malformed spec."""
        if "model" in spec:
            return cls.from_model(spec["model"])
        if "urdf" not in spec:
            raise ModelError(f"hand spec needs 'model' or 'urdf', got {spec!r}")
        return cls(spec["urdf"], spec.get("fingers"))

    # ------------------------------------------------------------------ metadata
    @property
    def thumb(self) -> str | None:
        """The finger that opposes the others (``hand.yaml``'s ``thumb``; None: no thumb)."""
        return self.metadata.thumb

    @property
    def gait_forward(self) -> tuple[str, ...]:
        """The forward gait order (``hand.yaml``'s ``gait.forward``; default: finger order)."""
        return self.metadata.gait_forward

    @functools.cached_property
    def grasp_region(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lower (3,), upper (3,)), palm frame, m: the box where grasp generation samples the object
        centre. ``hand.yaml``'s ``grasp_region``, else the box spanned by the fingertip centres at
        mid-range joints."""
        if self.metadata.grasp_region is not None:
            lower, upper = self.metadata.grasp_region
            return np.array(lower), np.array(upper)
        p_palm_tips = self.tip_positions(self.q_mid())
        return p_palm_tips.min(axis=0), p_palm_tips.max(axis=0)

    @property
    def n_joints(self) -> int:
        """Number of actuated joints (length of q)."""
        return len(self.joint_names)

    def __repr__(self) -> str:
        return f"Hand({self.name!r}, {self.n_joints} joints, {self.fingers}, {len(self.spheres)} spheres)"

    # ------------------------------------------------------------------ symbolic kinematics
    @functools.cached_property
    def _q(self) -> ca.SX:
        return ca.SX.sym("q", self.n_joints)

    @functools.cached_property
    def _T_palm_link(self) -> dict[str, ca.SX]:
        """Symbolic (4, 4) T_palm_<link>(q) for every link, built once."""
        q = self._q
        T = {self.root_link: ca.SX.eye(4)}
        for ln in self.link_names[1:]:
            j = self._parent_joint[ln]
            if j.type == "fixed":
                qi = None
            elif j.mimic is not None:
                qi = j.mimic[1] * q[self._jidx[j.mimic[0]]] + j.mimic[2]
            else:
                qi = q[self._jidx[j.name]]
            M = ca.SX(j.T_parent_joint)
            if qi is not None:
                M = M @ _joint_motion(j, qi)
            T[ln] = T[j.parent] @ M
        return T

    def _q_function(self, key: tuple, name: str, outputs: Callable[[], dict[str, ca.SX]]) -> ca.Function:
        """The function `name`: q (n,) -> the expressions of `outputs()` (output name -> SX of ``self._q``),
        with ``cse``; built once per `key`. Sparse outputs are made dense (a fixed numeric layout for the
        fast buffers of `_eval`)."""
        fn = self._fn_cache.get(key)
        if fn is None:
            named = outputs()
            fn = ca.Function(name, [self._q], list(named.values()), ["q"], list(named), {"cse": True})
            if not all(fn.sparsity_out(i).is_dense() for i in range(fn.n_out())):
                outs = [ca.densify(o) for o in fn.call([self._q])]
                fn = ca.Function(name, [self._q], outs, ["q"], list(named), {"cse": True})
            self._fn_cache[key] = fn
        return fn

    def _eval(self, fn: ca.Function, q: ArrayLike) -> NDArray[np.float64]:
        """Evaluate a cached single-output function numerically through a preallocated CasADi buffer
        (≈ 1-3 µs instead of ≈ 20 µs for a regular call). Not thread-safe; returns a copy."""
        fast = self._fast_cache.get(id(fn))
        if fast is None or fast[0] is not fn:  # (the entry holds fn: its id is not reused meanwhile)
            fast = self._fast_cache[id(fn)] = self._fast_entry(fn)
        _, _, evaluate, q_buf, out_buf = fast
        if evaluate is None:  # an empty output
            self._as_q(q)
            return np.zeros(out_buf.shape)
        q_buf[:] = self._as_q(q)
        evaluate()
        return out_buf.T.copy()

    def _fast_entry(self, fn: ca.Function) -> tuple:
        """(fn, its buffer, evaluate (None: an empty output), q buffer (n,), output buffer (cols, rows) or
        the empty output) of `_eval`."""
        rows, cols = fn.size_out(0)
        if fn.numel_out(0) == 0:
            return fn, None, None, None, np.zeros((rows, cols))
        q_buf = np.zeros(self.n_joints)
        out_buf = np.zeros((cols, rows))  # CasADi is column-major: out_buf.T is the (rows, cols) result
        buf, evaluate = fn.buffer()
        buf.set_arg(0, memoryview(q_buf))
        buf.set_res(0, memoryview(out_buf))
        return fn, buf, evaluate, q_buf, out_buf

    def fk_function(self) -> ca.Function:
        """``fk``: q (n,) -> one (4, 4) ``T_palm_<link>`` output per link, in ``link_names`` order."""
        return self._q_function(("fk",), "fk",
                                lambda: {f"T_palm_{ln}": self._T_palm_link[ln] for ln in self.link_names})

    def _fk_stacked_function(self) -> ca.Function:
        """q -> (4, 4 * n_links) horizontally stacked transforms (one output: fast numeric calls)."""
        return self._q_function(("fk_stacked",), "fk_stacked", lambda: {
            "T_palm_links": ca.horzcat(*[self._T_palm_link[ln] for ln in self.link_names])})

    def _check_finger(self, finger: str | None) -> None:
        if finger is not None and finger not in self.tip_links:
            raise KeyError(f"unknown finger {finger!r}; fingers are {self.fingers}")

    def _center_expr(self, s: CollisionSphere) -> ca.SX:
        T = self._T_palm_link[s.link]
        return T[:3, :3] @ ca.DM(s.center_link) + T[:3, 3]

    def tip_position_function(self, finger: str) -> ca.Function:
        """``tip_<finger>``: q (n,) -> p_palm_tip (3,), tip contact-sphere CENTRE, palm frame, m."""
        self._check_finger(finger)
        return self._q_function(("tip", finger), _function_name("tip", finger),
                                lambda: {"p_palm_tip": self._center_expr(self._tip_sphere[finger])})

    def tip_positions_function(self) -> ca.Function:
        """``tips``: q (n,) -> p_palm_tips (3, m), columns in ``fingers`` order."""
        return self._q_function(("tips",), "tips", lambda: {
            "p_palm_tips": ca.horzcat(*[self._center_expr(self._tip_sphere[f]) for f in self.fingers])})

    def tip_jacobian_function(self, finger: str) -> ca.Function:
        """``J_tip_<finger>``: q (n,) -> J (3, n) = d p_palm_tip / d q."""
        self._check_finger(finger)
        return self._q_function(("jac", finger), _function_name("J_tip", finger), lambda: {
            "J_palm_tip": ca.jacobian(self._center_expr(self._tip_sphere[finger]), self._q)})

    def tip_rotations_function(self) -> ca.Function:
        """``R_tips``: q (n,) -> R_palm_tiplinks (3, 3m), the tip links' rotations side by side, in
        ``fingers`` order."""
        links = [self.tip_links[f] for f in self.fingers]
        return self._q_function(("tip_rotations",), "R_tips", lambda: {
            "R_palm_tiplinks": ca.horzcat(*[self._T_palm_link[link][:3, :3] for link in links])})

    def tips_jacobian_function(self) -> ca.Function:
        """``J_tips``: q (n,) -> J (3m, n) = d p_palm_tips / d q, rows 3i..3i+2 the tip of ``fingers[i]``."""
        return self._q_function(("jac_tips",), "J_tips", lambda: {"J_palm_tips": ca.jacobian(
            ca.vertcat(*[self._center_expr(self._tip_sphere[f]) for f in self.fingers]), self._q)})

    def link_rotation_function(self, link: str) -> ca.Function:
        """``R_<link>``: q (n,) -> R_palm_link (3, 3)."""
        if link not in self._parent_joint and link != self.root_link:
            raise KeyError(f"unknown link {link!r}")
        return self._q_function(("rot", link), _function_name("R", link),
                                lambda: {"R_palm_link": self._T_palm_link[link][:3, :3]})

    def _select_spheres(self, finger: str | None, include_tip: bool) -> list[CollisionSphere]:
        self._check_finger(finger)
        sel = [s for s in self.spheres if not s.is_tip and (finger is None or s.finger == finger)]
        if include_tip:
            sel += [self._tip_sphere[f] for f in (self.fingers if finger is None else (finger,))]
        return sel

    def sphere_centers_function(self, finger: str | None = None, include_tip: bool = False) -> ca.Function:
        """q (n,) -> p_palm_spheres (3, k): centres of the non-tip spheres of ``finger`` (None: all, palm
        included), palm frame, m; ``include_tip`` appends the tip sphere(s). Order = ``sphere_labels``."""

        def outputs() -> dict[str, ca.SX]:
            sel = self._select_spheres(finger, include_tip)
            centers = ca.horzcat(*[self._center_expr(s) for s in sel]) if sel else ca.SX(3, 0)
            return {"p_palm_spheres": centers}

        return self._q_function(("spheres", finger, include_tip),
                                f"spheres_{finger or 'all'}{'_tip' if include_tip else ''}", outputs)

    def sphere_radii(self, finger: str | None = None, include_tip: bool = False) -> NDArray[np.float64]:
        """(k,) radii, m, in the order of ``sphere_centers_function(finger, include_tip)``."""
        return np.array([s.radius for s in self._select_spheres(finger, include_tip)], dtype=float)

    def sphere_labels(self, finger: str | None = None, include_tip: bool = False) -> list[str]:
        """Labels (``"link_2.0#1"``, ``"link_3.0_tip#tip"``) in the order of ``sphere_centers_function``."""
        return [s.label for s in self._select_spheres(finger, include_tip)]

    # ------------------------------------------------------------------ self-collision
    def parent_link(self, link: str) -> str | None:
        """The link `link` hangs on (None for the root)."""
        return self._parent_joint[link].parent if link in self._parent_joint else None

    def rigid_body(self, link: str) -> str:
        """The link that `link` is rigidly fixed to: up its fixed joints (the link itself if it moves)."""
        while link in self._parent_joint and self._parent_joint[link].type == "fixed":
            link = self._parent_joint[link].parent
        return link

    @functools.cached_property
    def self_collision_excluded(self) -> frozenset[tuple[int, int]]:
        """Pairs (a, b), a < b, of indices into `spheres` that always touch at a joint, never checked
        (`self_collision.excluded_pairs`; ModelError for a bad ``hand.yaml`` entry)."""
        from regrasp_casadi.self_collision import excluded_pairs

        return excluded_pairs(self)

    @functools.cached_property
    def _self_collision_bounds(self) -> dict[tuple[int, int], float]:
        """Every pair that is not excluded -> the sampled lower bound (m) of its surface distance."""
        from regrasp_casadi.self_collision import pair_lower_bounds

        pairs = self.self_collision_pairs()
        return dict(zip(pairs, pair_lower_bounds(self, pairs).tolist(), strict=True))

    def self_collision_pairs(self, finger: str | None = None,
                             within: float | None = None) -> tuple[tuple[int, int], ...]:
        """Sphere pairs (a, b), a < b, indices into `spheres`, whose self-collision counts: different
        fingers or a finger and the palm, not excluded (`self_collision_excluded`). `finger`: only the
        pairs with a sphere of that finger; `within` (m): only the pairs whose sampled lower bound over
        the joint limits is ≤ `within` + `self_collision.PRUNE_MARGIN` (the others cannot come that close:
        no constraint needed). See `regrasp_casadi.self_collision`."""
        from regrasp_casadi.self_collision import PRUNE_MARGIN, candidate_pairs

        self._check_finger(finger)
        pairs = [p for p in candidate_pairs(self) if p not in self.self_collision_excluded
                 and (finger is None or finger in (self.spheres[p[0]].finger, self.spheres[p[1]].finger))]
        if within is not None:
            pairs = [p for p in pairs if self._self_collision_bounds[p] <= within + PRUNE_MARGIN]
        return tuple(pairs)

    def sphere_pair_distance_function(self, pairs, tau: float | None = None) -> ca.Function:
        """``self_distances``: q (n,) -> d (P,), m: the surface distances |c_a − c_b| − r_a − r_b of the
        sphere pairs `pairs` ((a, b) indices into `spheres`; √(|c_a − c_b|² + 1e-12), smooth). With `tau`
        (m): ``self_min``, q -> (G,), one smooth minimum −τ·log Σ exp(−d_i/τ) ∈ [min d_i − τ·log size,
        min d_i] per rigid-body pair (groups of `self_collision.body_groups`): d ≥ c implies d_i ≥ c."""
        pairs = tuple((int(a), int(b)) for a, b in pairs)

        def outputs():
            from regrasp_casadi.self_collision import body_groups
            from regrasp_casadi.signed_distance import smooth_min

            c, r = [self._center_expr(s) for s in self.spheres], [s.radius for s in self.spheres]
            d = ca.vertcat(*[ca.sqrt(ca.sumsqr(c[a] - c[b]) + 1e-12) - r[a] - r[b] for a, b in pairs])
            if tau is not None:
                d = ca.vertcat(*[smooth_min(d[list(g)], tau) for g in body_groups(self, pairs)])
            return {"d_self": d if pairs else ca.SX(0, 1)}

        name = "self_distances" if tau is None else "self_min"
        return self._q_function(("pair_distances", pairs, tau), name, outputs)

    def self_collision_distances(self, q: ArrayLike, pairs=None) -> NDArray[np.float64]:
        """(P,) surface distances (m, < 0: overlap) of `pairs` (default: `self_collision_pairs()`) at q."""
        from regrasp_casadi.self_collision import pair_distances

        pairs = self.self_collision_pairs() if pairs is None else pairs
        return pair_distances(self, self.sphere_centers(q, None, include_tip=True), pairs)

    # ------------------------------------------------------------------ numeric conveniences
    def _as_q(self, q: ArrayLike) -> NDArray[np.float64]:
        if type(q) is np.ndarray and q.dtype == np.float64 and q.shape == (self.n_joints,):
            return q  # the common case, without the conversions below
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape[0] != self.n_joints:
            raise ValueError(f"q has {q.shape[0]} entries, the hand has {self.n_joints} joints")
        return q

    def fk(self, q: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Numeric FK: link -> (4, 4) T_palm_link for q (n,)."""
        M = self._eval(self._fk_stacked_function(), q)
        return {ln: M[:, 4 * i : 4 * i + 4] for i, ln in enumerate(self.link_names)}

    def tip_positions(self, q: ArrayLike) -> NDArray[np.float64]:
        """(m, 3) tip contact-sphere centres, palm frame, m, rows in ``fingers`` order."""
        fn = self._fn_cache.get(("tips",)) or self.tip_positions_function()  # (built: no checks again)
        return self._eval(fn, q).T

    def tips_jacobian(self, q: ArrayLike) -> NDArray[np.float64]:
        """(m, 3, n) Jacobians of every tip contact-sphere centre (palm frame) w.r.t. q, ``fingers`` order."""
        fn = self._fn_cache.get(("jac_tips",)) or self.tips_jacobian_function()
        return self._eval(fn, q).reshape(len(self.fingers), 3, -1)

    def tip_rotations(self, q: ArrayLike) -> NDArray[np.float64]:
        """(m, 3, 3) R_palm_tiplink of every finger's tip link, in ``fingers`` order."""
        fn = self._fn_cache.get(("tip_rotations",)) or self.tip_rotations_function()
        return self._eval(fn, q).reshape(3, -1, 3).transpose(1, 0, 2)

    def tip_jacobian(self, q: ArrayLike, finger: str) -> NDArray[np.float64]:
        """(3, n) Jacobian of the tip contact-sphere centre (palm frame) of ``finger`` w.r.t. q."""
        fn = self._fn_cache.get(("jac", finger)) or self.tip_jacobian_function(finger)
        return self._eval(fn, q)

    def sphere_centers(self, q: ArrayLike, finger: str | None = None, include_tip: bool = False) -> NDArray:
        """(k, 3) sphere centres, palm frame, m (see ``sphere_centers_function``)."""
        fn = self._fn_cache.get(("spheres", finger, include_tip)) or self.sphere_centers_function(finger,
                                                                                                  include_tip)
        return self._eval(fn, q).T

    def q_mid(self) -> NDArray[np.float64]:
        """(n,) mid-range configuration (0 for unbounded joints)."""
        lo, hi = self._finite_limits()
        return 0.5 * (lo + hi)

    def _finite_limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        lo = np.where(np.isfinite(self.q_lower), self.q_lower, -math.pi)
        hi = np.where(np.isfinite(self.q_upper), self.q_upper, math.pi)
        return lo, hi

    def tip_workspace_samples(self, finger: str, n: int = 4000, seed: int = 0) -> NDArray[np.float64]:
        """(n, 3) tip centres (palm frame, m) with the finger's joints uniform in their limits (continuous
        joints in [-pi, pi]) and every other joint at mid-range."""
        self._check_finger(finger)
        lo, hi = self._finite_limits()
        rng = np.random.default_rng(seed)
        Q = np.tile(0.5 * (lo + hi), (n, 1))
        idx = self.finger_joints[finger]
        Q[:, idx] = rng.uniform(lo[idx], hi[idx], size=(n, len(idx)))
        return np.asarray(self.tip_position_function(finger)(Q.T)).T.reshape(n, 3)

    def clip(self, q: ArrayLike) -> NDArray[np.float64]:
        """q (n,) clipped into the joint limits."""
        return np.clip(self._as_q(q), self.q_lower, self.q_upper)

    def check_limits(self, q: ArrayLike, tol: float = 1e-9) -> list[tuple[str, float, float, float]]:
        """Joint-limit violations larger than ``tol``: list of (joint_name, value, lower, upper)."""
        q = self._as_q(q)
        bad = np.flatnonzero((q < self.q_lower - tol) | (q > self.q_upper + tol))
        return [
            (self.joint_names[i], float(q[i]), float(self.q_lower[i]), float(self.q_upper[i])) for i in bad
        ]


def _joint_motion(j: JointModel, qi) -> ca.SX:
    """(4, 4) SX transform of a moving joint at value ``qi``: rotation about / translation along ``axis``."""
    M = ca.SX.eye(4)
    if j.type == "prismatic":
        M[:3, 3] = ca.DM(j.axis) * qi
        return M
    x, y, z = (float(v) for v in j.axis)
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    M[:3, :3] = ca.DM(np.eye(3)) + ca.sin(qi) * ca.DM(K) + (1 - ca.cos(qi)) * ca.DM(K @ K)
    return M
