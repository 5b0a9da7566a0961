"""Hand: a tree-structured URDF turned into cached CasADi SX kinematics and collision spheres.

The URDF is parsed with lxml (no ROS, no urdf2casadi). Every link gets a symbolic homogeneous transform
``T_palm_<link>(q)`` built once; tip positions, Jacobians and sphere centres are ``ca.Function`` objects
(SX inside, ``cse=True``) cached on the instance, callable on numbers, SX or MX.

    >>> hand = Hand.allegro_right()
    >>> q = 0.5 * (hand.q_lower + hand.q_upper)
    >>> p_palm_tips = hand.tip_positions(q)          # (4, 3), contact-sphere centres, palm frame, m
    >>> J = hand.tip_jacobian(q, "index")              # (3, 16)
"""

from __future__ import annotations

import functools
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from regrasp_casadi.errors import ModelError
from regrasp_casadi.transforms import rpy_to_R

__all__ = ["CollisionSphere", "Hand"]

logger = logging.getLogger(__name__)

MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
ALLEGRO_RIGHT_URDF = MODELS_DIR / "allegro_right" / "allegro_right.urdf"
ALLEGRO_FINGERS = {
    "index": "link_3.0_tip",
    "middle": "link_7.0_tip",
    "ring": "link_11.0_tip",
    "thumb": "link_15.0_tip",
}
_SUPPORTED = ("revolute", "continuous", "prismatic", "fixed")


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


@dataclass(frozen=True)
class _Joint:
    name: str
    type: str
    parent: str
    child: str
    T_parent_joint: NDArray[np.float64]  # (4, 4) origin
    axis: NDArray[np.float64]  # (3,) unit
    lower: float
    upper: float
    mimic: tuple[str, float, float] | None  # (joint, multiplier, offset)


def _floats(text: str | None, n: int, default: tuple[float, ...], where: str) -> NDArray[np.float64]:
    if text is None:
        return np.array(default, dtype=float)
    try:
        vals = [float(v) for v in text.split()]
    except ValueError as exc:
        raise ModelError(f"{where}: cannot parse numbers from {text!r}") from exc
    if len(vals) != n:
        raise ModelError(f"{where}: expected {n} numbers, got {text!r}")
    return np.array(vals)


def _origin(elem, where: str) -> NDArray[np.float64]:
    T = np.eye(4)
    o = elem.find("origin")
    if o is not None:
        T[:3, 3] = _floats(o.get("xyz"), 3, (0.0, 0.0, 0.0), where + " <origin xyz>")
        T[:3, :3] = rpy_to_R(*_floats(o.get("rpy"), 3, (0.0, 0.0, 0.0), where + " <origin rpy>"))
    return T


def _parse_urdf(path: Path):
    """Parse a URDF file into (robot name, link names, joints, link spheres); raises ModelError."""
    from lxml import etree

    if not path.is_file():
        raise ModelError(f"URDF file not found: {path}")
    try:
        root = etree.parse(str(path)).getroot()
    except etree.XMLSyntaxError as exc:
        raise ModelError(f"{path}: malformed XML: {exc}") from exc
    if root.tag != "robot":
        raise ModelError(f"{path}: root element is <{root.tag}>, expected <robot>")
    links = [el.get("name") for el in root.findall("link")]
    if any(n is None for n in links):
        raise ModelError(f"{path}: a <link> has no name attribute")
    if len(set(links)) != len(links):
        dup = sorted({n for n in links if links.count(n) > 1})
        raise ModelError(f"{path}: duplicate link names {dup}")
    spheres: dict[str, list[tuple[str | None, NDArray[np.float64], float]]] = {n: [] for n in links}
    for el in root.findall("link"):
        for col in el.findall("collision"):
            s = col.find("geometry/sphere")
            if s is None:
                continue
            where = f"{path}: link {el.get('name')!r} <collision>"
            r = _floats(s.get("radius"), 1, (math.nan,), where + " <sphere radius>")[0]
            if not r >= 0.0:
                raise ModelError(f"{where}: sphere radius missing or negative")
            spheres[el.get("name")].append((col.get("name"), _origin(col, where)[:3, 3], float(r)))
    joints = []
    for el in root.findall("joint"):
        name, jtype = el.get("name"), el.get("type")
        where = f"{path}: joint {name!r}"
        if jtype not in _SUPPORTED:
            raise ModelError(
                f"{where}: joint type {jtype!r} is not supported (supported: {', '.join(_SUPPORTED)})"
            )
        parent, child = el.find("parent"), el.find("child")
        if parent is None or child is None or parent.get("link") is None or child.get("link") is None:
            raise ModelError(f"{where}: missing <parent link> or <child link>")
        for tag, ln in (("parent", parent.get("link")), ("child", child.get("link"))):
            if ln not in spheres:
                raise ModelError(f"{where}: {tag} link {ln!r} is not a <link> of the file")
        ax = el.find("axis")
        axis = _floats(None if ax is None else ax.get("xyz"), 3, (1.0, 0.0, 0.0), where + " <axis xyz>")
        if jtype != "fixed":
            nrm = np.linalg.norm(axis)
            if nrm < 1e-12:
                raise ModelError(f"{where}: zero <axis>")
            axis = axis / nrm
        lower, upper = -math.inf, math.inf
        if jtype in ("revolute", "prismatic"):
            lim = el.find("limit")
            if lim is None:
                raise ModelError(f"{where}: {jtype} joint without <limit>")
            lower = float(_floats(lim.get("lower"), 1, (0.0,), where + " <limit lower>")[0])
            upper = float(_floats(lim.get("upper"), 1, (0.0,), where + " <limit upper>")[0])
            if lower > upper:
                raise ModelError(f"{where}: <limit> lower {lower} > upper {upper}")
        mimic = None
        mel = el.find("mimic")
        if mel is not None and jtype != "fixed":
            mimic = (mel.get("joint"), float(mel.get("multiplier", 1.0)), float(mel.get("offset", 0.0)))
        joints.append(
            _Joint(
                name,
                jtype,
                parent.get("link"),
                child.get("link"),
                _origin(el, where),
                axis,
                lower,
                upper,
                mimic,
            )
        )
    return root.get("name") or path.stem, links, joints, spheres


class Hand:
    """Kinematic and collision model of a multi-fingered hand from a tree-structured URDF.

    Frames: ``palm`` is the URDF root link; ``T_palm_<link>`` maps link coordinates to palm coordinates.
    ``q`` is the (n_joints,) vector of actuated joints in URDF order (rad, or m for prismatic joints).
    """

    def __init__(self, urdf_path: str | Path, fingers: dict[str, str] | None = None) -> None:
        """Read ``urdf_path``; ``fingers`` maps finger name -> tip link (default: the leaf links).

        Raises:
            ModelError: missing/malformed file, unsupported joint, not a tree, unknown tip link.
        """
        path = Path(urdf_path).expanduser().resolve()
        name, links, joints, link_spheres = _parse_urdf(path)
        self.urdf_path: Path = path
        """Absolute path of the URDF."""
        self.name: str = name
        """Robot name from the URDF (``"allegro_right"`` for the shipped model)."""

        parent_joint: dict[str, _Joint] = {}
        for j in joints:
            if j.child in parent_joint:
                raise ModelError(
                    f"{path}: link {j.child!r} has two parents (joints "
                    f"{parent_joint[j.child].name!r} and {j.name!r}); only trees are supported"
                )
            parent_joint[j.child] = j
        if len({j.name for j in joints}) != len(joints):
            raise ModelError(f"{path}: duplicate joint names")
        roots = [ln for ln in links if ln not in parent_joint]
        if len(roots) != 1:
            raise ModelError(
                f"{path}: expected exactly one root link, found {roots} (a kinematic loop or "
                "disconnected links)"
            )
        self.root_link: str = roots[0]
        """Root link (the palm frame)."""
        children: dict[str, list[_Joint]] = {ln: [] for ln in links}
        for j in joints:
            children[j.parent].append(j)
        order, stack = [], [self.root_link]  # depth-first, children in file order
        while stack:
            ln = stack.pop()
            order.append(ln)
            stack.extend(j.child for j in reversed(children[ln]))
        if len(order) != len(links):
            missing = sorted(set(links) - set(order))
            raise ModelError(f"{path}: links {missing} are not reachable from root {self.root_link!r} (loop)")
        self.link_names: tuple[str, ...] = tuple(order)
        """Every link, parents before children."""

        self._joints = joints
        self._parent_joint = parent_joint
        actuated = [j for j in joints if j.type != "fixed" and j.mimic is None]
        self.joint_names: tuple[str, ...] = tuple(j.name for j in actuated)
        """Actuated joints = order of q (URDF order)."""
        jidx = {n: i for i, n in enumerate(self.joint_names)}
        for j in joints:
            if j.mimic is not None and j.mimic[0] not in jidx:
                raise ModelError(
                    f"{path}: joint {j.name!r} mimics {j.mimic[0]!r}, which is not an actuated joint"
                )
        self._jidx = jidx
        self.q_lower: NDArray[np.float64] = np.array([j.lower for j in actuated])
        """(n,) lower joint limits, rad or m (-inf for continuous joints)."""
        self.q_upper: NDArray[np.float64] = np.array([j.upper for j in actuated])
        """(n,) upper joint limits, rad or m (+inf for continuous joints)."""

        leaves = [ln for ln in order if not children[ln]]
        fingers = dict(fingers) if fingers is not None else {ln: ln for ln in leaves}
        for f, tip in fingers.items():
            if tip not in children:
                raise ModelError(f"{path}: finger {f!r}: tip link {tip!r} is not a link of the URDF")
        self.fingers: tuple[str, ...] = tuple(fingers)
        """Finger names, in the order used by ``tip_positions``."""
        self.tip_links: dict[str, str] = fingers
        """finger -> tip link."""
        self.finger_joints: dict[str, NDArray[np.int64]] = {}
        """finger -> sorted int indices into q of the joints on the path root -> tip."""
        path_links: dict[str, set[str]] = {}
        for f, tip in fingers.items():
            chain, ln = [], tip
            path_links[f] = {tip}
            while ln in parent_joint:
                j = parent_joint[ln]
                if j.name in jidx:
                    chain.append(jidx[j.name])
                elif j.mimic is not None:
                    chain.append(jidx[j.mimic[0]])
                ln = j.parent
                path_links[f].add(ln)
            self.finger_joints[f] = np.array(sorted(set(chain)), dtype=np.int64)

        def finger_of(link: str) -> str | None:
            ln, moved = link, False
            while ln in parent_joint and not moved:
                moved = parent_joint[ln].type != "fixed"
                ln = parent_joint[ln].parent
            if not moved:  # fixed to the root: palm
                return None
            ln = link
            while True:
                owners = [f for f in self.fingers if ln in path_links[f]]
                if len(owners) == 1:
                    return owners[0]
                if owners or ln not in parent_joint:
                    return None
                ln = parent_joint[ln].parent

        spheres: list[CollisionSphere] = []
        tip_sphere: dict[str, CollisionSphere] = {}
        tip_by_link = {tip: f for f, tip in fingers.items()}
        for ln in order:
            items = link_spheres[ln]
            tip_k = None
            if ln in tip_by_link:
                named = [k for k, s in enumerate(items) if s[0] == "tip_contact"]
                tip_k = named[0] if named else (0 if items else None)
                if tip_k is None:
                    logger.warning("%s: tip link %r has no collision sphere; using a point tip", path, ln)
                    tip_sphere[tip_by_link[ln]] = CollisionSphere(
                        ln, np.zeros(3), 0.0, tip_by_link[ln], True, f"{ln}#tip"
                    )
            owner = finger_of(ln)
            k_nontip = 0
            for k, (_, c, r) in enumerate(items):
                if k == tip_k:
                    tip_sphere[tip_by_link[ln]] = CollisionSphere(
                        ln, c, r, tip_by_link[ln], True, f"{ln}#tip"
                    )
                else:
                    spheres.append(CollisionSphere(ln, c, r, owner, False, f"{ln}#{k_nontip}"))
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
            logger.warning("%s: fingertip radii differ %s; tip_radius is their maximum", path, self.tip_radii)
        self.tip_radius: float = max(radii) if radii else 0.0
        """Radius of the fingertip contact sphere, m."""
        self._spec_fingers = None if fingers == {ln: ln for ln in leaves} else dict(fingers)
        self._fn_cache: dict[tuple, ca.Function] = {}
        self._fast_cache: dict[str, tuple] = {}

    # ------------------------------------------------------------------ construction helpers
    @classmethod
    def from_urdf(cls, path: str | Path, fingers: dict[str, str] | None = None) -> Hand:
        """Build a Hand from a URDF file; ``fingers`` maps finger name -> tip link (default: leaf links)."""
        return cls(path, fingers)

    @classmethod
    def allegro_right(cls) -> Hand:
        """The shipped Allegro hand v4 (right) model, ``models/allegro_right/allegro_right.urdf``."""
        return cls(ALLEGRO_RIGHT_URDF, ALLEGRO_FINGERS)

    def spec(self) -> dict:
        """How to rebuild this hand: ``{"model": "allegro_right"}`` or ``{"urdf": "/abs/path"}``."""
        if self.urdf_path == ALLEGRO_RIGHT_URDF.resolve() and self.tip_links == ALLEGRO_FINGERS:
            return {"model": "allegro_right"}
        spec: dict = {"urdf": str(self.urdf_path)}
        if self._spec_fingers is not None:
            spec["fingers"] = dict(self._spec_fingers)
        return spec

    @classmethod
    def from_spec(cls, spec: dict) -> Hand:
        """Inverse of ``spec()``. Raises ModelError for an unknown model or a malformed spec."""
        if spec.get("model") == "allegro_right":
            return cls.allegro_right()
        if "model" in spec:
            raise ModelError(f"unknown hand model {spec['model']!r} (known: 'allegro_right')")
        if "urdf" not in spec:
            raise ModelError(f"hand spec needs 'model' or 'urdf', got {spec!r}")
        return cls(spec["urdf"], spec.get("fingers"))

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

    def _cached(self, key: tuple, build) -> ca.Function:
        """Build a function once per key; outputs are made dense (fixed numeric layout, fast buffers)."""
        fn = self._fn_cache.get(key)
        if fn is None:
            fn = build()
            if not all(fn.sparsity_out(i).is_dense() for i in range(fn.n_out())):
                outs = [ca.densify(o) for o in fn.call([self._q])]
                fn = ca.Function(fn.name(), [self._q], outs, fn.name_in(), fn.name_out(), {"cse": True})
            self._fn_cache[key] = fn
        return fn

    def _eval(self, fn: ca.Function, q: ArrayLike) -> NDArray[np.float64]:
        """Evaluate a cached single-output function numerically through a preallocated CasADi buffer
        (≈ 1-3 µs instead of ≈ 20 µs for a regular call). Not thread-safe; returns a copy."""
        if fn.numel_out(0) == 0:
            self._as_q(q)
            return np.zeros(fn.size_out(0))
        fast = self._fast_cache.get(fn.name())
        if fast is None or fast[0] is not fn:
            q_buf = np.zeros(self.n_joints)
            rows, cols = fn.size_out(0)
            out_buf = np.zeros((cols, rows))  # CasADi is column-major: out_buf.T is the (rows, cols) result
            buf, evaluate = fn.buffer()
            buf.set_arg(0, memoryview(q_buf))
            buf.set_res(0, memoryview(out_buf))
            fast = self._fast_cache[fn.name()] = (fn, buf, evaluate, q_buf, out_buf)
        _, _, evaluate, q_buf, out_buf = fast
        q_buf[:] = self._as_q(q)
        evaluate()
        return out_buf.T.copy()

    def fk_function(self) -> ca.Function:
        """``fk``: q (n,) -> one (4, 4) ``T_palm_<link>`` output per link, in ``link_names`` order."""
        names = [f"T_palm_{ln}" for ln in self.link_names]
        return self._cached(
            ("fk",),
            lambda: ca.Function(
                "fk",
                [self._q],
                [self._T_palm_link[ln] for ln in self.link_names],
                ["q"],
                names,
                {"cse": True},
            ),
        )

    def _fk_stacked_function(self) -> ca.Function:
        """q -> (4, 4 * n_links) horizontally stacked transforms (one output: fast numeric calls)."""
        return self._cached(
            ("fk_stacked",),
            lambda: ca.Function(
                "fk_stacked",
                [self._q],
                [ca.horzcat(*[self._T_palm_link[ln] for ln in self.link_names])],
                ["q"],
                ["T_palm_links"],
                {"cse": True},
            ),
        )

    def _check_finger(self, finger: str | None) -> None:
        if finger is not None and finger not in self.tip_links:
            raise KeyError(f"unknown finger {finger!r}; fingers are {self.fingers}")

    def _center_expr(self, s: CollisionSphere) -> ca.SX:
        T = self._T_palm_link[s.link]
        return T[:3, :3] @ ca.DM(s.center_link) + T[:3, 3]

    def tip_position_function(self, finger: str) -> ca.Function:
        """``tip_<finger>``: q (n,) -> p_palm_tip (3,), tip contact-sphere CENTRE, palm frame, m."""
        self._check_finger(finger)
        return self._cached(
            ("tip", finger),
            lambda: ca.Function(
                _function_name("tip", finger),
                [self._q],
                [self._center_expr(self._tip_sphere[finger])],
                ["q"],
                ["p_palm_tip"],
                {"cse": True},
            ),
        )

    def tip_positions_function(self) -> ca.Function:
        """``tips``: q (n,) -> p_palm_tips (3, m), columns in ``fingers`` order."""
        return self._cached(
            ("tips",),
            lambda: ca.Function(
                "tips",
                [self._q],
                [ca.horzcat(*[self._center_expr(self._tip_sphere[f]) for f in self.fingers])],
                ["q"],
                ["p_palm_tips"],
                {"cse": True},
            ),
        )

    def tip_jacobian_function(self, finger: str) -> ca.Function:
        """``J_tip_<finger>``: q (n,) -> J (3, n) = d p_palm_tip / d q."""
        self._check_finger(finger)

        def build():
            p = self._center_expr(self._tip_sphere[finger])
            return ca.Function(
                _function_name("J_tip", finger), [self._q], [ca.jacobian(p, self._q)], ["q"], ["J_palm_tip"],
                {"cse": True},
            )

        return self._cached(("jac", finger), build)

    def link_rotation_function(self, link: str) -> ca.Function:
        """``R_<link>``: q (n,) -> R_palm_link (3, 3)."""
        if link not in self._parent_joint and link != self.root_link:
            raise KeyError(f"unknown link {link!r}")
        return self._cached(
            ("rot", link),
            lambda: ca.Function(
                _function_name("R", link),
                [self._q],
                [self._T_palm_link[link][:3, :3]],
                ["q"],
                ["R_palm_link"],
                {"cse": True},
            ),
        )

    def _select_spheres(self, finger: str | None, include_tip: bool) -> list[CollisionSphere]:
        self._check_finger(finger)
        sel = [s for s in self.spheres if not s.is_tip and (finger is None or s.finger == finger)]
        if include_tip:
            sel += [self._tip_sphere[f] for f in (self.fingers if finger is None else (finger,))]
        return sel

    def sphere_centers_function(self, finger: str | None = None, include_tip: bool = False) -> ca.Function:
        """q (n,) -> p_palm_spheres (3, k): centres of the non-tip spheres of ``finger`` (None: all, palm
        included), palm frame, m; ``include_tip`` appends the tip sphere(s). Order = ``sphere_labels``."""

        def build():
            sel = self._select_spheres(finger, include_tip)
            expr = ca.horzcat(*[self._center_expr(s) for s in sel]) if sel else ca.SX(3, 0)
            return ca.Function(
                f"spheres_{finger or 'all'}{'_tip' if include_tip else ''}",
                [self._q],
                [expr],
                ["q"],
                ["p_palm_spheres"],
                {"cse": True},
            )

        return self._cached(("spheres", finger, include_tip), build)

    def sphere_radii(self, finger: str | None = None, include_tip: bool = False) -> NDArray[np.float64]:
        """(k,) radii, m, in the order of ``sphere_centers_function(finger, include_tip)``."""
        return np.array([s.radius for s in self._select_spheres(finger, include_tip)], dtype=float)

    def sphere_labels(self, finger: str | None = None, include_tip: bool = False) -> list[str]:
        """Labels (``"link_2.0#1"``, ``"link_3.0_tip#tip"``) in the order of ``sphere_centers_function``."""
        return [s.label for s in self._select_spheres(finger, include_tip)]

    # ------------------------------------------------------------------ numeric conveniences
    def _as_q(self, q: ArrayLike) -> NDArray[np.float64]:
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
        return self._eval(self.tip_positions_function(), q).T

    def tip_jacobian(self, q: ArrayLike, finger: str) -> NDArray[np.float64]:
        """(3, n) Jacobian of the tip contact-sphere centre (palm frame) of ``finger`` w.r.t. q."""
        return self._eval(self.tip_jacobian_function(finger), q)

    def sphere_centers(self, q: ArrayLike, finger: str | None = None, include_tip: bool = False) -> NDArray:
        """(k, 3) sphere centres, palm frame, m (see ``sphere_centers_function``)."""
        return self._eval(self.sphere_centers_function(finger, include_tip), q).T

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


def _joint_motion(j: _Joint, qi) -> ca.SX:
    """(4, 4) SX transform of a moving joint at value ``qi``: rotation about / translation along ``axis``."""
    M = ca.SX.eye(4)
    if j.type == "prismatic":
        M[:3, 3] = ca.DM(j.axis) * qi
        return M
    x, y, z = (float(v) for v in j.axis)
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    M[:3, :3] = ca.DM(np.eye(3)) + ca.sin(qi) * ca.DM(K) + (1 - ca.cos(qi)) * ca.DM(K @ K)
    return M
