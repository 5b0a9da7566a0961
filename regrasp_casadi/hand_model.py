"""Reading a hand model: its URDF (parsed with yourdfpy) and its metadata file ``hand.yaml``.

A hand model is a folder: the URDF plus ``hand.yaml``, the facts about the hand that a URDF does not say
(which links are fingertips and what the fingers are called, which finger opposes the others, the gait
order, where grasps are sampled, how the viewer looks at the hand). A second hand is a second folder; no
code names a finger. The shipped models are package data (`regrasp_casadi.resources`); any folder works
with ``Hand.from_model(path)``, and ``Hand.from_urdf(path)`` reads the ``hand.yaml`` beside the URDF when
that file describes this URDF.

``hand.yaml`` (schema version 1; every key but ``schema_version``, ``urdf`` and ``fingers`` optional)::

    schema_version: 1
    urdf: allegro_right.urdf            # the URDF this file describes, in the same folder
    fingers:                            # finger name: tip link, in finger order (rows of per-finger arrays)
      index: link_3.0_tip
      thumb: link_15.0_tip
    thumb: thumb                        # the finger that opposes the others (none: no thumb)
    gait:
      forward: [index, thumb]           # a permutation of the fingers (default: finger order)
      reversible: true                  # the paper's rule may reverse it (default: false)
    grasp_region:                       # palm frame, m: box of object centres for grasp generation
      lower: [0.06, -0.02, 0.0]
      upper: [0.12, 0.05, 0.07]
    viewer:
      toward_palm_side: 0.6             # how far the camera turns from the grasp's side towards the palm
      lift: [0.0, 0.0, 0.3]             # palm-frame vector added to the viewing direction
      colors:                           # replay colours "#rrggbb" (quoted: # starts a YAML comment):
        palm: "#8d939c"                 #   the palm and links fixed to it, and any finger by name
        index: "#d1495b"
    self_collision:
      exclude:                          # pairs that always touch at a joint (never checked): a link
        palm_link: [link_0.0]           #   name (all its spheres) or a sphere label: the links / labels
        link_1.0#1: [palm_link#4]       #   it is not checked against

A URDF without such a file gets `fallback_metadata`: the fingers given (default: the leaf links), no thumb,
gait order = finger order (never reversed), no grasp region (the Hand derives one), the default camera
and colours (`regrasp_casadi.hand_visuals`), no stored self-collision exclusions (the Hand applies the
rule of `regrasp_casadi.self_collision`). Sphere labels are `Hand`'s (``"<link>#<k>"``, ``"<link>#tip"``);
the Hand checks them.

Every error is a `ModelError` naming the file and the joint, link or key.
"""

from __future__ import annotations

import dataclasses
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.errors import ModelError

__all__ = [
    "DEFAULT_MODEL",
    "METADATA_FILE",
    "PALM",
    "SUPPORTED_JOINTS",
    "CameraHint",
    "HandMetadata",
    "JointModel",
    "LinkSphere",
    "UrdfModel",
    "fallback_metadata",
    "known_models",
    "load_hand",
    "load_metadata",
    "model_urdf",
    "models_dir",
    "read_metadata",
    "read_urdf",
]

DEFAULT_MODEL = "allegro_right"
"""The hand used when none is named (the CLI's `grasps` on a bare mesh, the demo's fallback problem)."""
METADATA_FILE = "hand.yaml"
"""Name of the metadata file in a model folder."""
METADATA_SCHEMA_VERSION = 1
SUPPORTED_JOINTS = ("revolute", "continuous", "prismatic", "fixed")

PALM = "palm"
"""The name of the hand's non-finger part in ``viewer.colors``."""

_META_KEYS = ("schema_version", "urdf", "fingers", "thumb", "gait", "grasp_region", "viewer",
              "self_collision")


# ------------------------------------------------------------------------------------------------- URDF
@dataclass(frozen=True)
class JointModel:
    """One URDF joint, as the kinematics use it."""

    name: str
    type: str
    """One of `SUPPORTED_JOINTS`."""
    parent: str
    child: str
    T_parent_joint: NDArray[np.float64]
    """(4, 4) joint origin in the parent link frame (m)."""
    axis: NDArray[np.float64]
    """(3,) unit axis in the joint frame (as written for a fixed joint)."""
    lower: float
    """Lower limit, rad or m (-inf for continuous joints)."""
    upper: float
    """Upper limit, rad or m (+inf for continuous joints)."""
    mimic: tuple[str, float, float] | None
    """(joint, multiplier, offset): q = multiplier * q_joint + offset; None for an independent joint."""


@dataclass(frozen=True)
class LinkSphere:
    """A ``<collision>`` sphere of a link."""

    name: str | None
    """The ``<collision name>`` (``"tip_contact"`` marks the fingertip contact sphere)."""
    center_link: NDArray[np.float64]
    """(3,) centre in the link frame, m."""
    radius: float
    """Radius, m."""


@dataclass(frozen=True)
class UrdfModel:
    """A tree-structured URDF: links, joints, the tree and the collision spheres."""

    path: Path
    """Absolute path of the URDF."""
    name: str
    """Robot name (the file stem when the URDF gives none)."""
    root_link: str
    """The one link without a parent (the palm frame)."""
    link_names: tuple[str, ...]
    """Every link, parents before children (depth first, children in file order)."""
    joints: tuple[JointModel, ...]
    """Every joint, in file order."""
    parent_joint: dict[str, JointModel]
    """child link -> the joint whose child it is (every link but the root)."""
    children: dict[str, tuple[JointModel, ...]]
    """link -> the joints whose parent it is, in file order."""
    spheres: dict[str, tuple[LinkSphere, ...]]
    """link -> its collision spheres, in file order (other collision geometry is ignored)."""

    @property
    def leaves(self) -> tuple[str, ...]:
        """Links without children, in `link_names` order."""
        return tuple(ln for ln in self.link_names if not self.children[ln])


def load_hand(name: str):
    """The `hand.Hand` that `name` names (a command's ``--hand``): a URDF file (``*.urdf``,
    `Hand.from_urdf`), else a shipped model's name or a model folder (`Hand.from_model`).

    Raises:
        ModelError: an unknown model, or a model or URDF that does not load.
    """
    from regrasp_casadi.hand import Hand  # (hand imports this module)

    return Hand.from_urdf(name) if name.lower().endswith(".urdf") else Hand.from_model(name)


def read_urdf(path: str | Path) -> UrdfModel:
    """Read a tree-structured URDF with yourdfpy and check it.

    Raises:
        ModelError: naming the file (and the joint or link): missing file, malformed XML, an element
            yourdfpy cannot read, an unsupported joint type, a revolute/prismatic joint without limits,
            a zero axis, a mimic of a non-actuated joint, duplicate names, a link with two parents, no
            single root, unreachable links.
    """
    path = Path(path).expanduser().resolve()
    robot = _yourdfpy_robot(path)
    links = [link.name for link in robot.links]
    if len(set(links)) != len(links):
        raise ModelError(f"{path}: duplicate link names {sorted({n for n in links if links.count(n) > 1})}")
    spheres = {link.name: _link_spheres(path, link) for link in robot.links}
    joints = tuple(_joint_model(path, j, spheres) for j in robot.joints)
    if len({j.name for j in joints}) != len(joints):
        raise ModelError(f"{path}: duplicate joint names")
    root, order, parent_joint, children = _tree(path, links, joints)
    actuated = {j.name for j in joints if j.type != "fixed" and j.mimic is None}
    for j in joints:
        if j.mimic is not None and j.mimic[0] not in actuated:
            raise ModelError(
                f"{path}: joint {j.name!r} mimics {j.mimic[0]!r}, which is not an actuated joint"
            )
    return UrdfModel(path, robot.name, root, order, joints, parent_joint, children, spheres)


def _yourdfpy_robot(path: Path):
    """The yourdfpy ``Robot`` of the file. The XML is checked with lxml first: yourdfpy silently recovers
    from malformed XML, which must be an error here."""
    import yourdfpy
    from lxml import etree

    if not path.is_file():
        raise ModelError(f"URDF file not found: {path}")
    try:
        root = etree.parse(str(path)).getroot()
    except etree.XMLSyntaxError as exc:
        raise ModelError(f"{path}: malformed XML: {exc}") from exc
    if root.tag != "robot":
        raise ModelError(f"{path}: root element is <{root.tag}>, expected <robot>")
    for tag in ("link", "joint"):
        if any(el.get("name") is None for el in root.findall(tag)):
            raise ModelError(f"{path}: a <{tag}> has no name attribute")
    for el in root.findall("joint"):
        if el.find("parent") is None or el.find("child") is None:
            raise ModelError(f"{path}: joint {el.get('name')!r}: missing <parent link> or <child link>")
    _check_origins(path, root)
    if root.get("name") is None:
        root.set("name", path.stem)
    try:
        urdf = yourdfpy.URDF.load(io.BytesIO(etree.tostring(root)), build_scene_graph=False,
                                  build_collision_scene_graph=False, load_meshes=False,
                                  load_collision_meshes=False)
    except Exception as exc:  # noqa: BLE001 - any parse failure of yourdfpy becomes a ModelError
        raise ModelError(f"{path}: {_bad_element(root)}cannot be read: {type(exc).__name__}: {exc}") from exc
    return urdf.robot


def _bad_element(root) -> str:
    """``"joint 'x': "`` for the first link or joint that yourdfpy's element parsers reject (``""`` if
    none does), so that a parse error names its element."""
    import yourdfpy

    for tag, parser in (("link", "_parse_link"), ("joint", "_parse_joint")):
        parse = getattr(yourdfpy.URDF, parser, None)  # yourdfpy's per-element parsers (not public API)
        if parse is None:
            continue
        for el in root.findall(tag):
            try:
                parse(el)
            except Exception:  # noqa: BLE001
                return f"{tag} {el.get('name')!r}: "
    return ""


def _check_origins(path: Path, root) -> None:
    """Every ``<origin>`` gives 3 numbers in ``xyz`` and ``rpy`` (yourdfpy would drop extra ones)."""
    for el in root.iter("origin"):
        for attr in ("xyz", "rpy"):
            text = el.get(attr)
            if text is not None and len(text.split()) != 3:
                owner = el.getparent()
                while owner is not None and owner.tag not in ("joint", "link"):
                    owner = owner.getparent()
                where = f"{owner.tag} {owner.get('name')!r}" if owner is not None else "<origin>"
                raise ModelError(f"{path}: {where} <origin {attr}>: expected 3 numbers, got {text!r}")


def _vector(values, n: int, where: str) -> NDArray[np.float64]:
    v = np.asarray(values, dtype=float)
    if v.shape != (n,):
        raise ModelError(f"{where}: expected {n} numbers, got {v.size}")
    return v


def _link_spheres(path: Path, link) -> tuple[LinkSphere, ...]:
    out = []
    for col in link.collisions:
        if col.geometry is None or col.geometry.sphere is None:
            continue
        where = f"{path}: link {link.name!r} <collision>"
        r = col.geometry.sphere.radius
        if not (r is not None and r >= 0.0):
            raise ModelError(f"{where}: sphere radius missing or negative")
        center = np.zeros(3) if col.origin is None else np.array(col.origin[:3, 3], dtype=float)
        out.append(LinkSphere(col.name, center, float(r)))
    return tuple(out)


def _joint_model(path: Path, j, links: dict) -> JointModel:
    """Our joint record from a yourdfpy ``Joint``, checked."""
    where = f"{path}: joint {j.name!r}"
    if j.type not in SUPPORTED_JOINTS:
        raise ModelError(f"{where}: joint type {j.type!r} is not supported "
                         f"(supported: {', '.join(SUPPORTED_JOINTS)})")
    if j.parent is None or j.child is None:
        raise ModelError(f"{where}: missing <parent link> or <child link>")
    for tag, ln in (("parent", j.parent), ("child", j.child)):
        if ln not in links:
            raise ModelError(f"{where}: {tag} link {ln!r} is not a <link> of the file")
    axis = _vector(j.axis, 3, where + " <axis xyz>")
    if j.type != "fixed":
        nrm = np.linalg.norm(axis)
        if nrm < 1e-12:
            raise ModelError(f"{where}: zero <axis>")
        axis = axis / nrm
    lower, upper = -math.inf, math.inf
    if j.type in ("revolute", "prismatic"):
        if j.limit is None:
            raise ModelError(f"{where}: {j.type} joint without <limit>")
        lower = 0.0 if j.limit.lower is None else float(j.limit.lower)  # URDF default 0
        upper = 0.0 if j.limit.upper is None else float(j.limit.upper)
        if lower > upper:
            raise ModelError(f"{where}: <limit> lower {lower} > upper {upper}")
    mimic = None
    if j.mimic is not None and j.type != "fixed":
        mult = 1.0 if j.mimic.multiplier is None else float(j.mimic.multiplier)
        offset = 0.0 if j.mimic.offset is None else float(j.mimic.offset)
        mimic = (j.mimic.joint, mult, offset)
    T = np.eye(4) if j.origin is None else np.array(j.origin, dtype=float)
    return JointModel(j.name, j.type, j.parent, j.child, T, axis, lower, upper, mimic)


def _tree(path: Path, links: list[str], joints: tuple[JointModel, ...]):
    """(root, links parents-first, child -> parent joint, link -> child joints); raises unless a tree."""
    parent_joint: dict[str, JointModel] = {}
    for j in joints:
        if j.child in parent_joint:
            raise ModelError(f"{path}: link {j.child!r} has two parents (joints "
                             f"{parent_joint[j.child].name!r} and {j.name!r}); only trees are supported")
        parent_joint[j.child] = j
    roots = [ln for ln in links if ln not in parent_joint]
    if len(roots) != 1:
        raise ModelError(f"{path}: expected exactly one root link, found {roots} (a kinematic loop or "
                         "disconnected links)")
    children: dict[str, list[JointModel]] = {ln: [] for ln in links}
    for j in joints:
        children[j.parent].append(j)
    order, stack = [], [roots[0]]  # depth-first, children in file order
    while stack:
        ln = stack.pop()
        order.append(ln)
        stack.extend(j.child for j in reversed(children[ln]))
    if len(order) != len(links):
        missing = sorted(set(links) - set(order))
        raise ModelError(f"{path}: links {missing} are not reachable from root {roots[0]!r} (loop)")
    return roots[0], tuple(order), parent_joint, {ln: tuple(js) for ln, js in children.items()}


# --------------------------------------------------------------------------------------------- metadata
@dataclass(frozen=True)
class CameraHint:
    """How the viewer places its camera (see `regrasp_casadi.viewer.camera_offset`)."""

    toward_palm_side: float = 0.6
    """How much the camera turns from the grasp's side towards the palm side (weight of palm -> object)."""
    lift_palm: tuple[float, float, float] = (0.0, 0.0, 0.3)
    """Palm-frame vector added to the (unit) viewing direction before normalising: raises the camera."""


@dataclass(frozen=True)
class HandMetadata:
    """What the code must know about a hand beyond its URDF (``hand.yaml``, or `fallback_metadata`)."""

    fingers: dict[str, str]
    """finger name -> tip link, in finger order."""
    thumb: str | None = None
    """The finger that opposes the others (grasp generation places it opposite them; the viewer looks
    across it); None: no thumb."""
    gait_forward: tuple[str, ...] = ()
    """The forward gait order (a permutation of the fingers)."""
    gait_reversible: bool = False
    """True: the planner's rule (paper §IV) may reverse `gait_forward`; False: always `gait_forward`."""
    grasp_region: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    """(lower, upper) corners, palm frame, m, of the box where grasp generation samples the object centre;
    None: the Hand derives one from its fingertips."""
    camera: CameraHint = field(default_factory=CameraHint)
    """The viewer's camera placement."""
    colors: dict[str, str] = field(default_factory=dict)
    """Replay colours ``"#rrggbb"`` by part: ``"palm"`` and finger names (``viewer.colors``); a part not
    named gets the viewer's default (`regrasp_casadi.hand_visuals.hand_colors`)."""
    source: Path | None = None
    """The ``hand.yaml`` read (None: fallback metadata)."""
    self_collision_exclude: tuple[tuple[str, str], ...] | None = None
    """Pairs of link names (every sphere of each) or sphere labels that always touch at a joint, never
    checked for self-collision (``hand.yaml``'s ``self_collision.exclude``); None: not given (the Hand
    applies `self_collision.touching_pairs`)."""


def fallback_metadata(fingers: dict[str, str], base: HandMetadata | None = None) -> HandMetadata:
    """Metadata for `fingers` without a metadata file: no thumb, gait order = finger order (never reversed).

    `base` (the metadata file of the URDF, whose fingers differ from `fingers`) lends its hand-level
    entries, which do not name fingers: the grasp region, the camera, the source, and the colours of the
    palm and of the fingers that keep their names (not its self-collision exclusions: the spheres'
    fingers change with the fingers).
    """
    base = base if base is not None else HandMetadata(fingers={})
    colors = {k: c for k, c in base.colors.items() if k == PALM or k in fingers}
    return dataclasses.replace(base, fingers=dict(fingers), thumb=None, gait_forward=tuple(fingers),
                               gait_reversible=False, colors=colors,
                               self_collision_exclude=None)


def load_metadata(urdf: UrdfModel) -> HandMetadata | None:
    """The ``hand.yaml`` beside the URDF, if there is one and its ``urdf`` key names this file; else None."""
    meta_path = urdf.path.parent / METADATA_FILE
    if not meta_path.is_file():
        return None
    raw = _read_yaml(meta_path)
    if raw.get("urdf") != urdf.path.name:
        return None
    return read_metadata(meta_path, urdf, raw)


def read_metadata(path: str | Path, urdf: UrdfModel, raw: dict | None = None) -> HandMetadata:
    """Read and check a ``hand.yaml`` against the URDF it describes (`raw`: its already parsed content).

    Raises:
        ModelError: ``<path>: <key>: <what is wrong>`` for invalid YAML, an unknown or missing key, a tip
            link that is not a link of the URDF, a thumb or gait finger that is not a finger, a gait order
            that is not a permutation of the fingers, a malformed grasp region or camera entry.
    """
    path = Path(path)
    raw = _read_yaml(path) if raw is None else raw

    def error(key: str, msg: str) -> ModelError:
        return ModelError(f"{path}: {key}: {msg}")

    unknown = [k for k in raw if k not in _META_KEYS]
    if unknown:
        raise error(unknown[0], f"unknown key (allowed: {', '.join(_META_KEYS)})")
    for k in ("schema_version", "urdf", "fingers"):
        if k not in raw:
            raise error(k, "missing key")
    if raw["schema_version"] != METADATA_SCHEMA_VERSION or isinstance(raw["schema_version"], bool):
        raise error("schema_version", f"expected {METADATA_SCHEMA_VERSION}, found {raw['schema_version']!r}")
    fingers = _fingers(error, raw["fingers"], urdf)
    thumb = raw.get("thumb")
    if thumb is not None and thumb not in fingers:
        raise error("thumb", f"{thumb!r} is not a finger (fingers: {', '.join(fingers)})")
    forward, reversible = _gait(error, raw.get("gait", {}), fingers)
    region = _region(error, raw["grasp_region"]) if "grasp_region" in raw else None
    camera, colors = _viewer(error, raw.get("viewer", {}), fingers)
    exclude = _self_collision(error, raw["self_collision"]) if "self_collision" in raw else None
    return HandMetadata(fingers, thumb, forward, reversible, region, camera, colors=colors,
                        source=path.resolve(), self_collision_exclude=exclude)


def _read_yaml(path: Path) -> dict:
    import yaml

    try:
        raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ModelError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        raise ModelError(f"{path}: invalid YAML: {exc}") from None
    if not isinstance(raw, dict):
        raise ModelError(f"{path}: expected a mapping at the top level")
    return raw


def _fingers(error, v: Any, urdf: UrdfModel) -> dict[str, str]:
    if not (isinstance(v, dict) and v and all(isinstance(x, str) for x in [*v, *v.values()])):
        raise error("fingers", "expected a non-empty mapping {finger name: tip link name}")
    for f, tip in v.items():
        if tip not in urdf.children:
            raise error(f"fingers.{f}", f"tip link {tip!r} is not a link of {urdf.path.name}")
    return dict(v)


def _gait(error, v: Any, fingers: dict[str, str]) -> tuple[tuple[str, ...], bool]:
    if not isinstance(v, dict) or any(k not in ("forward", "reversible") for k in v):
        raise error("gait", "expected a mapping with the keys forward and reversible")
    forward = v.get("forward", list(fingers))
    if not isinstance(forward, list) or sorted(map(str, forward)) != sorted(fingers):
        raise error("gait.forward", f"expected a permutation of the fingers {list(fingers)}, got {forward!r}")
    reversible = v.get("reversible", False)
    if not isinstance(reversible, bool):
        raise error("gait.reversible", f"expected true or false, got {reversible!r}")
    return tuple(forward), reversible


def _numbers(error, key: str, v: Any, n: int) -> tuple[float, ...]:
    ok = isinstance(v, list) and len(v) == n and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)
    if not ok:
        raise error(key, f"expected a list of {n} finite numbers, got {v!r}")
    return tuple(float(x) for x in v)


def _region(error, v: Any):
    if not isinstance(v, dict) or sorted(v) != ["lower", "upper"]:
        raise error("grasp_region", "expected a mapping with the keys lower and upper")
    lower = _numbers(error, "grasp_region.lower", v["lower"], 3)
    upper = _numbers(error, "grasp_region.upper", v["upper"], 3)
    if any(lo > hi for lo, hi in zip(lower, upper, strict=True)):
        raise error("grasp_region", f"lower {list(lower)} exceeds upper {list(upper)}")
    return lower, upper


def _viewer(error, v: Any, fingers: dict[str, str]) -> tuple[CameraHint, dict[str, str]]:
    """The ``viewer`` section: the camera hint and the colours (checked ``"#rrggbb"``, lower case)."""
    if not isinstance(v, dict) or any(k not in ("toward_palm_side", "lift", "colors") for k in v):
        raise error("viewer", "expected a mapping with the keys toward_palm_side, lift and colors")
    default = CameraHint()
    toward = _numbers(error, "viewer.toward_palm_side", [v.get("toward_palm_side", default.toward_palm_side)],
                      1)[0]
    lift = _numbers(error, "viewer.lift", v.get("lift", list(default.lift_palm)), 3)
    colors = v.get("colors", {})
    if not isinstance(colors, dict):
        raise error("viewer.colors", f"expected a mapping {{part: '#rrggbb'}}, got {colors!r}")
    for part, color in colors.items():
        if part != PALM and part not in fingers:
            raise error(f"viewer.colors.{part}",
                        f"not a part of the hand (parts: {PALM}, {', '.join(fingers)})")
        if not (isinstance(color, str) and re.fullmatch(r"#[0-9A-Fa-f]{6}", color)):
            hint = " (quote it: # starts a YAML comment)" if color is None else ""
            raise error(f"viewer.colors.{part}", f"expected a colour '#rrggbb', got {color!r}{hint}")
    return CameraHint(toward, lift), {str(k): c.lower() for k, c in colors.items()}


def _self_collision(error, v: Any) -> tuple[tuple[str, str], ...]:
    """``self_collision: {exclude: {name: [name, ...]}}`` -> name pairs (link names or sphere labels)."""
    if not isinstance(v, dict) or any(k != "exclude" for k in v):
        raise error("self_collision", "expected a mapping with the key exclude")
    exclude = v.get("exclude") or {}
    ok = isinstance(exclude, dict) and all(
        isinstance(a, str) and isinstance(bs, list) and all(isinstance(b, str) for b in bs)
        for a, bs in exclude.items())
    if not ok:
        raise error("self_collision.exclude", "expected a mapping {link or sphere label: [links or labels]}")
    return tuple((a, b) for a, bs in exclude.items() for b in bs)


# ------------------------------------------------------------------------------------------ model folders
def models_dir() -> Path:
    """The folder of the shipped hand models (package data ``regrasp_casadi.models``)."""
    from regrasp_casadi.resources import package_data_dir

    return package_data_dir("models")


def known_models() -> list[str]:
    """Names of the shipped hand models (folders of `models_dir` with a ``hand.yaml``)."""
    root = models_dir()
    return sorted(p.name for p in root.iterdir() if (p / METADATA_FILE).is_file())


def model_urdf(model: str | Path) -> Path:
    """The URDF of a hand model: a shipped model's name (a string without a path separator), or a model
    folder (a `Path`, or a string that looks like a path) holding ``hand.yaml``.

    Raises:
        ModelError: an unknown model name, a folder without ``hand.yaml``, a ``hand.yaml`` without ``urdf``.
    """
    if isinstance(model, str) and not any(c in model for c in "/\\") and not model.startswith("."):
        folder = models_dir() / model
        if not (folder / METADATA_FILE).is_file():
            raise ModelError(f"unknown hand model {model!r} (known: {', '.join(map(repr, known_models()))})")
    else:
        folder = Path(model).expanduser().resolve()
        if not (folder / METADATA_FILE).is_file():
            raise ModelError(f"{folder}: not a hand model folder (no {METADATA_FILE})")
    meta_path = folder / METADATA_FILE
    urdf = _read_yaml(meta_path).get("urdf")
    if not isinstance(urdf, str):
        raise ModelError(f"{meta_path}: urdf: expected the URDF's file name, got {urdf!r}")
    return folder / urdf
