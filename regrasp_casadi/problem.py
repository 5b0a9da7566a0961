"""The regrasp problem file: `RegraspProblem.load(path.yaml)` gives the hand, object, initial and goal grasp.

A problem file (YAML, schema in `problems/README.md`) names the hand, the object (a primitive with its
dimensions, or a mesh path relative to the file), the initial grasp (joints + object pose) and the
desired grasp (contacts + object pose). Every error is a `ProblemFileError` naming the file and the key
path, e.g. ``problems/x.yaml: grasp_goal.contacts.thumb: expected 3 numbers, got 2``.

    >>> problem = RegraspProblem.load("problems/box_rotate.yaml")
    >>> plan = plan_regrasp(problem.grasp0, problem.grasp_goal)

`plan_models(plan)` rebuilds the hand and the object of a (loaded) plan from its specs.
"""

from __future__ import annotations

import inspect
import json
import os
import pathlib
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from regrasp_casadi.errors import GraspError, MeshError, ModelError, ProblemFileError
from regrasp_casadi.files import atomic_write_text
from regrasp_casadi.grasp import Grasp
from regrasp_casadi.transforms import make_T, rpy_to_R

if TYPE_CHECKING:  # pragma: no cover
    from regrasp_casadi.hand import Hand
    from regrasp_casadi.objects import ObjectModel
    from regrasp_casadi.plan import Plan

__all__ = ["RegraspProblem", "PROBLEM_SCHEMA_VERSION", "plan_models", "clear_model_cache"]

PROBLEM_SCHEMA_VERSION = 1
"""Version of the problem-file schema; files must say `schema_version: 1`."""

_TOP_KEYS = ("schema_version", "name", "description", "hand", "object", "grasp0", "grasp_goal", "gravity")
_PRIMITIVE_DIMENSIONS = {  # the keys a problem file must give for each primitive (no silent defaults), m
    "box": ("extents",),
    "cylinder": ("radius", "height"),
    "sphere": ("radius",),
    "capsule": ("radius", "height"),
    "bottle": ("body_radius", "body_height", "shoulder_height", "neck_radius", "neck_height"),
    "banana": ("length", "thickness", "bend_radius"),
    "bowl": ("radius", "wall"),
    "cup": ("radius", "height", "wall", "bottom"),
    "mug": ("radius", "height", "wall", "bottom", "handle_radius", "handle_thickness"),
    "flat_tool": ("length", "thickness", "handle_width", "head_length", "head_width", "corner_radius"),
    "holed_box": ("extents", "hole_radius"),
}
_PRIMITIVES = tuple(_PRIMITIVE_DIMENSIONS)  # = objects.PRIMITIVES (tested)
_MESH_KEYS = ("mesh", "scale", "sha256", "threshold", "max_planes_per_piece", "hull_tolerance")
_OBJECT_DATA_KEYS = ("mass",)
"""Keys of the object section that describe the object, not its geometry (kept out of its spec)."""


class _Ctx:
    """Error context: the file name, prefixed to every message with the key path."""

    def __init__(self, path: str):
        self.path = path

    def error(self, key: str, msg: str) -> ProblemFileError:
        return ProblemFileError(f"{self.path}: {key}: {msg}" if key else f"{self.path}: {msg}")


class _DuplicateKey(yaml.YAMLError):
    """A key given twice in one YAML mapping."""

    def __init__(self, key: Any, line: int):
        super().__init__(f"duplicate key {key!r} (line {line})")
        self.key, self.line = key, line


class _UniqueKeyLoader(yaml.SafeLoader):
    """`yaml.SafeLoader` that rejects a key given twice in one mapping (PyYAML keeps the last silently).
    Keys merged in with ``<<`` may be overridden, as YAML allows."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: set = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    if key in seen:
                        raise _DuplicateKey(key, key_node.start_mark.line + 1)
                    seen.add(key)
                except TypeError:   # an unhashable key: SafeLoader reports it
                    pass
        return super().construct_mapping(node, deep=deep)


def _read_yaml(ctx: _Ctx, p: pathlib.Path) -> Any:
    """The YAML document in `p` (UTF-8, no duplicate keys)."""
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ctx.error("", f"cannot read problem file: {e.strerror or e}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ctx.error("", f"not a UTF-8 text file (byte {e.start}: {e.reason})") from None
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # a SafeLoader: plain data only
    except _DuplicateKey as e:
        raise ctx.error("", str(e)) from None
    except yaml.YAMLError as e:
        raise ctx.error("", f"invalid YAML: {e}") from None


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)


def _numbers(ctx: _Ctx, key: str, v: Any, n: int | None = None) -> np.ndarray:
    """A flat list of finite numbers (length `n` if given)."""
    if not isinstance(v, (list, tuple)):
        what = f"{n} numbers" if n is not None else "numbers"
        raise ctx.error(key, f"expected a list of {what}, got {type(v).__name__}")
    bad = [i for i, x in enumerate(v) if not _is_number(x)]
    if bad:
        raise ctx.error(f"{key}[{bad[0]}]", f"expected a finite number, got {v[bad[0]]!r}")
    if n is not None and len(v) != n:
        raise ctx.error(key, f"expected {n} numbers, got {len(v)}")
    return np.array(v, dtype=float)


def _mapping(ctx: _Ctx, key: str, v: Any, allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> dict:
    if not isinstance(v, dict):
        raise ctx.error(key, f"expected a mapping, got {type(v).__name__}")
    unknown = [k for k in v if k not in allowed]
    if unknown:
        raise ctx.error(key, f"unknown key(s) {', '.join(map(str, unknown))} (allowed: {', '.join(allowed)})")
    for k in required:
        if k not in v:
            raise ctx.error(key, f"missing key {k!r}")
    return v


def _pose(ctx: _Ctx, key: str, v: Any) -> np.ndarray:
    """T_palm_object as a (4, 4) list of rows or {xyz: [3], rpy: [3]} (URDF fixed-axis rpy, rad)."""
    if isinstance(v, dict):
        _mapping(ctx, key, v, ("xyz", "rpy"), ("xyz", "rpy"))
        xyz = _numbers(ctx, f"{key}.xyz", v["xyz"], 3)
        rpy = _numbers(ctx, f"{key}.rpy", v["rpy"], 3)
        return make_T(rpy_to_R(*rpy), xyz)
    if not isinstance(v, list) or len(v) != 4:
        raise ctx.error(key, "expected a 4x4 matrix (4 rows of 4 numbers) or {xyz: [3], rpy: [3]}")
    return np.array([_numbers(ctx, f"{key}[{i}]", row, 4) for i, row in enumerate(v)])


def _joints(ctx: _Ctx, key: str, v: Any, hand: Hand) -> np.ndarray:
    """Joint angles as a list in `hand.joint_names` order or a complete {joint_name: value} mapping."""
    if isinstance(v, dict):
        names = list(hand.joint_names)
        unknown = [k for k in v if k not in names]
        if unknown:
            raise ctx.error(key, f"unknown joint(s) {', '.join(map(str, unknown))} for {hand.name}")
        missing = [k for k in names if k not in v]
        if missing:
            raise ctx.error(key, f"missing joint(s) {', '.join(missing)}")
        for k in names:
            if not _is_number(v[k]):
                raise ctx.error(f"{key}.{k}", f"expected a finite number, got {v[k]!r}")
        return np.array([float(v[k]) for k in names])
    q = _numbers(ctx, key, v)
    if len(q) != hand.n_joints:
        raise ctx.error(key, f"expected {hand.n_joints} joint angles for {hand.name}, got {len(q)}")
    return q


def _load_hand(ctx: _Ctx, v: Any, base_dir: pathlib.Path) -> Hand:
    from regrasp_casadi.hand import Hand

    try:
        if isinstance(v, str):
            return Hand.from_spec({"model": v})
        m = _mapping(ctx, "hand", v, ("model", "urdf", "fingers"))
        if ("model" in m) == ("urdf" in m):
            raise ctx.error("hand", "give exactly one of 'model' (a model name or folder) or 'urdf'")
        if "model" in m:
            return _load_model(ctx, m, base_dir)
        if not isinstance(m["urdf"], str):
            raise ctx.error("hand.urdf", f"expected a path, got {m['urdf']!r}")
        path = pathlib.Path(m["urdf"]).expanduser()
        path = path if path.is_absolute() else base_dir / path
        if not path.is_file():
            raise ctx.error("hand.urdf", f"file not found: {path}")
        fingers = m.get("fingers")
        if fingers is not None and not (
            isinstance(fingers, dict) and all(isinstance(x, str) for x in [*fingers, *fingers.values()])
        ):
            raise ctx.error("hand.fingers", "expected a mapping {finger name: tip link name}")
        return Hand.from_urdf(path, fingers=fingers)
    except (ModelError, MeshError, KeyError, ValueError, TypeError) as e:
        raise ctx.error("hand", str(e)) from None


def _load_model(ctx: _Ctx, m: dict, base_dir: pathlib.Path) -> Hand:
    """``hand: {model: NAME}`` (a shipped model) or ``{model: FOLDER}`` (a model folder, relative to the
    problem file when not absolute), optionally ``fingers: [index, middle, thumb]``: the fingers that
    hold (a subset of the model's, in that order); the others stay collision bodies only."""
    from regrasp_casadi.hand import Hand

    if not isinstance(m["model"], str):
        raise ctx.error("hand.model", f"expected a model name or folder, got {m!r}")
    name = m["model"]
    if "/" in name or "\\" in name or name.startswith("."):
        folder = pathlib.Path(name).expanduser()
        hand = Hand.from_model(folder if folder.is_absolute() else base_dir / folder)
    else:
        hand = Hand.from_model(name)
    fingers = m.get("fingers")
    if fingers is None:
        return hand
    if not (isinstance(fingers, list) and fingers and all(f in hand.fingers for f in fingers)
            and len(set(fingers)) == len(fingers)):
        raise ctx.error("hand.fingers", f"expected a list of distinct fingers of {hand.name} "
                                        f"({', '.join(hand.fingers)}), got {fingers!r}")
    return Hand.from_urdf(hand.urdf_path, {f: hand.tip_links[f] for f in fingers})


def _object_mass(ctx: _Ctx, v: Any) -> float | None:
    """The object section's optional `mass`, kg (a positive number), or None."""
    if not isinstance(v, dict) or "mass" not in v:
        return None
    if not (_is_number(v["mass"]) and v["mass"] > 0):
        raise ctx.error("object.mass", f"expected a positive number (kg), got {v['mass']!r}")
    return float(v["mass"])


def _gravity(ctx: _Ctx, raw: dict) -> tuple[float, float, float] | str | None:
    """The file's optional `gravity`: three numbers (m/s², palm frame), "support", or None."""
    if "gravity" not in raw:
        return None
    if raw["gravity"] == "support":
        return "support"
    if isinstance(raw["gravity"], str):
        raise ctx.error("gravity", f"expected [x, y, z] (m/s^2, palm frame) or 'support', "
                                   f"got {raw['gravity']!r}")
    return tuple(float(g) for g in _numbers(ctx, "gravity", raw["gravity"], 3))


def _load_object(ctx: _Ctx, v: Any, base_dir: pathlib.Path) -> ObjectModel:
    from regrasp_casadi.objects import ObjectModel

    if not isinstance(v, dict):
        raise ctx.error("object", f"expected a mapping (primitive: ... or mesh: ...), got {type(v).__name__}")
    v = {k: x for k, x in v.items() if k not in _OBJECT_DATA_KEYS}
    if ("primitive" in v) == ("mesh" in v):
        raise ctx.error("object", "give exactly one of 'primitive' or 'mesh'")
    if "mesh" in v:
        _check_mesh_object(ctx, v)
    else:
        _check_primitive_object(ctx, v, ObjectModel)
    try:
        return ObjectModel.from_spec(dict(v), base_dir=base_dir)
    except (MeshError, ValueError, TypeError) as e:
        raise ctx.error("object", str(e)) from None


def _check_mesh_object(ctx: _Ctx, v: dict) -> None:
    """The keys of a `mesh:` object (before loading it)."""
    _mapping(ctx, "object", v, _MESH_KEYS)
    if not isinstance(v["mesh"], str):
        raise ctx.error("object.mesh", f"expected a path, got {v['mesh']!r}")
    if "scale" in v and not (_is_number(v["scale"]) and v["scale"] > 0):
        raise ctx.error("object.scale", f"expected a positive number, got {v['scale']!r}")
    if "sha256" in v and not isinstance(v["sha256"], str):
        raise ctx.error("object.sha256", f"expected a hex string, got {v['sha256']!r}")
    if "threshold" in v and not (_is_number(v["threshold"]) and v["threshold"] > 0):
        raise ctx.error("object.threshold", f"expected a positive number, got {v['threshold']!r}")
    planes = v.get("max_planes_per_piece", 4)
    if not (isinstance(planes, int) and not isinstance(planes, bool) and planes >= 4):
        raise ctx.error("object.max_planes_per_piece", f"expected an integer ≥ 4, got {planes!r}")
    if "hull_tolerance" in v and not (_is_number(v["hull_tolerance"]) and v["hull_tolerance"] >= 0):
        raise ctx.error("object.hull_tolerance", f"expected a number ≥ 0 (m), got {v['hull_tolerance']!r}")


def _check_primitive_object(ctx: _Ctx, v: dict, object_model: type) -> None:
    """The keys of a `primitive:` object: a known primitive, its dimensions (the keyword arguments of
    its `ObjectModel` constructor), all positive."""
    kind = v["primitive"]
    if kind not in _PRIMITIVES:
        raise ctx.error("object.primitive", f"unknown primitive {kind!r} (one of {', '.join(_PRIMITIVES)})")
    params = [p for p in inspect.signature(getattr(object_model, kind)).parameters if p != "cls"]
    _mapping(ctx, "object", v, ("primitive", *params))
    missing = [k for k in _PRIMITIVE_DIMENSIONS[kind] if k not in v]
    if missing:
        raise ctx.error("object", f"primitive {kind} needs its dimensions: missing key(s) "
                                  f"{', '.join(missing)} (m)")
    for k, x in v.items():
        if k == "extents":
            ext = _numbers(ctx, "object.extents", x, 3)
            if np.any(ext <= 0):
                raise ctx.error("object.extents", f"expected positive sizes, got {x}")
        elif k != "primitive" and not (_is_number(x) and x > 0):
            raise ctx.error(f"object.{k}", f"expected a positive number, got {x!r}")


def _grasp(ctx: _Ctx, key: str, build) -> Grasp:
    try:
        return build()
    except GraspError as e:
        raise ctx.error(key, str(e)) from None


@dataclass(frozen=True, eq=False)
class RegraspProblem:
    """A regrasp problem read from (or written to) a YAML problem file."""

    name: str
    """Problem name (the file's `name`, default the file stem)."""
    description: str
    """Free text ("" when absent)."""
    path: pathlib.Path | None
    """The file it was loaded from (None if built in memory)."""
    hand: Hand
    """The hand."""
    obj: ObjectModel
    """The object."""
    grasp0: Grasp
    """Initial grasp (joints + object pose, validated: fingertips on the surface)."""
    grasp_goal: Grasp
    """Desired grasp (contacts on the surface + desired object pose; joints optional)."""
    raw: dict
    """The parsed YAML document as read."""
    object_mass: float | None = None
    """The object's mass from the file's `object.mass`, kg (None: not stated; the planner's gravity
    certificate then uses the mesh volume × density, `certificates.object_mass`)."""
    gravity: tuple[float, float, float] | str | None = None
    """The file's `gravity`: (3,) m/s² in the palm frame, "support" (`gravity_palm` resolves it with
    `hand_orientation.supporting_gravity`), or None (not stated). `regrasp plan` then certifies every
    step for it (`stability="gravity"`)."""

    @property
    def gravity_palm(self) -> tuple[float, float, float] | None:
        """The problem's gravity in the palm frame, m/s² ("support" resolved for grasp0), or None."""
        if self.gravity != "support":
            return self.gravity
        from regrasp_casadi.hand_orientation import supporting_gravity

        return tuple(float(g) for g in supporting_gravity(self.grasp0))

    @classmethod
    def load(cls, path: str | os.PathLike) -> RegraspProblem:
        """Read and validate a problem file.

        Args:
            path: the YAML file; relative mesh/URDF paths in it are resolved against its folder.

        Raises:
            ProblemFileError: naming the file and the key path, for a missing file, invalid YAML, a
                missing, unknown or malformed key, or a grasp that fails validation (the `GraspError`
                text, with the finger and distance, follows the key).
        """
        shown = str(path)
        ctx = _Ctx(shown)
        p = pathlib.Path(path)
        raw = _read_yaml(ctx, p)
        if not isinstance(raw, dict):
            raise ctx.error("", "expected a mapping at the top level")
        _mapping(ctx, "", raw, _TOP_KEYS, ("schema_version", "hand", "object", "grasp0", "grasp_goal"))
        version = raw["schema_version"]
        if version != PROBLEM_SCHEMA_VERSION or isinstance(version, bool):
            raise ctx.error("schema_version", f"expected {PROBLEM_SCHEMA_VERSION}, found {version!r}")
        name = raw.get("name", p.stem)
        description = raw.get("description", "")
        for k, x in (("name", name), ("description", description)):
            if not isinstance(x, str):
                raise ctx.error(k, f"expected a string, got {type(x).__name__}")
        base_dir = p.resolve().parent
        hand = _load_hand(ctx, raw["hand"], base_dir)
        obj = _load_object(ctx, raw["object"], base_dir)
        mass = _object_mass(ctx, raw["object"])
        gravity = _gravity(ctx, raw)

        g0 = _mapping(ctx, "grasp0", raw["grasp0"], ("joints", "T_palm_object"), ("joints", "T_palm_object"))
        q0 = _joints(ctx, "grasp0.joints", g0["joints"], hand)
        T0 = _pose(ctx, "grasp0.T_palm_object", g0["T_palm_object"])
        grasp0 = _grasp(ctx, "grasp0", lambda: Grasp.from_joints(hand, obj, q0, T0))

        gg = _mapping(ctx, "grasp_goal", raw["grasp_goal"], ("contacts", "T_palm_object", "joints"),
                      ("contacts", "T_palm_object"))
        c = _mapping(ctx, "grasp_goal.contacts", gg["contacts"], tuple(hand.fingers), tuple(hand.fingers))
        contacts = np.array([_numbers(ctx, f"grasp_goal.contacts.{f}", c[f], 3) for f in hand.fingers])
        Tg = _pose(ctx, "grasp_goal.T_palm_object", gg["T_palm_object"])
        qg = _joints(ctx, "grasp_goal.joints", gg["joints"], hand) if "joints" in gg else None
        grasp_goal = _grasp(ctx, "grasp_goal",
                            lambda: Grasp.from_contacts(hand, obj, contacts, Tg, q=qg))
        return cls(name, description, p, hand, obj, grasp0, grasp_goal, raw, mass, gravity)

    def to_yaml_dict(self, base_dir: str | os.PathLike | None = None) -> dict:
        """The problem as a YAML-ready dict (the schema `load` reads; floats round-trip exactly).

        Args:
            base_dir: folder the file will be written to; mesh/URDF paths inside it are written
                relative to it (default: absolute paths).
        """
        hand_spec = dict(self.hand.spec())
        if "model" in hand_spec:
            hand_out: Any = hand_spec["model"]
        else:
            hand_out = {"urdf": _rel(hand_spec["urdf"], base_dir)}
            if hand_spec.get("fingers"):
                hand_out["fingers"] = dict(hand_spec["fingers"])
        obj_out = _plain(dict(self.obj.spec))
        if "mesh" in obj_out:
            obj_out["mesh"] = _rel(obj_out["mesh"], base_dir)
        elif "primitive" not in obj_out:
            raise ProblemFileError(
                f"object {self.obj.name!r} has no file or primitive spec; save its mesh to a file first"
            )
        if self.object_mass is not None:
            obj_out["mass"] = float(self.object_mass)
        g0, gg = self.grasp0, self.grasp_goal
        if g0.q is None:
            raise ProblemFileError("grasp0 has no joint angles; a problem file needs them")
        goal: dict[str, Any] = {
            "contacts": {f: _plain(row)
                         for f, row in zip(self.hand.fingers, gg.contacts_object, strict=True)},
            "T_palm_object": _plain(gg.T_palm_object),
        }
        if gg.q is not None:
            goal["joints"] = _plain(gg.q)
        return {
            "schema_version": PROBLEM_SCHEMA_VERSION,
            "name": self.name,
            "description": self.description,
            "hand": hand_out,
            "object": obj_out,
            "grasp0": {"joints": _plain(g0.q), "T_palm_object": _plain(g0.T_palm_object)},
            "grasp_goal": goal,
            **({} if self.gravity is None else {"gravity": _plain(self.gravity) if self.gravity != "support"
                                                else "support"}),
        }

    def save(self, path: str | os.PathLike) -> pathlib.Path:
        """Write the problem as YAML (relative paths to meshes/URDFs next to it). Returns the path."""
        path = pathlib.Path(path)
        d = self.to_yaml_dict(base_dir=path.resolve().parent)
        header = f"# regrasp problem {self.name!r} (schema in problems/README.md)\n"
        text = header + yaml.safe_dump(d, sort_keys=False, default_flow_style=None, width=110)
        return atomic_write_text(path, text)


def _rel(p: str, base_dir: str | os.PathLike | None) -> str:
    if base_dir is None:
        return str(p)
    try:
        return os.path.relpath(pathlib.Path(p).resolve(), pathlib.Path(base_dir).resolve())
    except ValueError:  # another drive (Windows)
        return str(p)


def _plain(x: Any) -> Any:
    """numpy arrays/scalars to plain lists/floats (YAML writes Python floats with repr: lossless)."""
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    return x


# ------------------------------------------------------------------------------ models of a plan
_MODEL_CACHE_SIZE = 8
"""How many hands and objects `plan_models` keeps (least recently used ones are dropped first)."""

_model_cache: OrderedDict[tuple[str, str], Any] = OrderedDict()


def plan_models(
    plan: Plan, hand: Hand | None = None, obj: ObjectModel | None = None
) -> tuple[Hand, ObjectModel]:
    """The hand and the object of a plan, rebuilt from `plan.hand_spec` and `plan.object_spec`.

    Models are cached per spec: the spec's content plus, for a spec naming a file ("urdf", "mesh"),
    the file's absolute path, size and modification time. Verifying, viewing and replaying one plan (or
    several plans of one problem) build each model once. `clear_model_cache()` empties the cache.

    Args:
        plan: a plan, e.g. from `Plan.load`.
        hand, obj: models to use as they are instead of rebuilding them (for functions whose `hand` /
            `obj` arguments default to the plan's: ``hand, obj = plan_models(plan, hand, obj)``).

    Returns:
        (hand, obj): `Hand.from_spec(plan.hand_spec)`, `ObjectModel.from_spec(plan.object_spec)`
        (or the models given).

    Raises:
        ModelError: the hand spec names an unknown model or an unreadable URDF.
        MeshError: the object spec names an unknown primitive or an unreadable mesh.
    """
    if hand is None:
        from regrasp_casadi.hand import Hand

        hand = _cached_model("hand", plan.hand_spec, "urdf", Hand.from_spec)
    if obj is None:
        from regrasp_casadi.objects import ObjectModel

        obj = _cached_model("object", plan.object_spec, "mesh", ObjectModel.from_spec)
    return hand, obj


def clear_model_cache() -> None:
    """Forget every hand and object built by `plan_models`."""
    _model_cache.clear()


def _cached_model(kind: str, spec: dict, file_key: str, build: Callable[[dict], Any]) -> Any:
    key = (kind, _spec_key(spec, file_key))
    if key in _model_cache:
        _model_cache.move_to_end(key)
        return _model_cache[key]
    model = build(dict(spec))
    _model_cache[key] = model
    while len(_model_cache) > _MODEL_CACHE_SIZE:
        _model_cache.popitem(last=False)
    return model


def _spec_key(spec: dict, file_key: str) -> str:
    """Canonical text of `spec` (sorted keys), with the stamp of the file it names under `file_key`."""
    stamp = None
    if isinstance(spec.get(file_key), str):
        file = os.path.abspath(os.path.expanduser(spec[file_key]))
        try:
            st = os.stat(file)
            stamp = [file, st.st_size, st.st_mtime_ns]
        except OSError:
            stamp = [file]
    return json.dumps([_plain(spec), stamp], sort_keys=True, default=str)
