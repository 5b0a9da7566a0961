"""The plan file's codec: field validation of the JSON dicts, `StepPath` and certificate (de)serialisation,
and the strict JSON text (no NaN, no duplicate keys, UTF-8).

`plan.PlanStep.to_dict` / `from_dict` and `plan.Plan.to_dict` / `from_dict` are built from these; every
error is a `PlanFormatError` naming the field (e.g. "steps[3].path.t"), without the file name (the caller
adds it). Only numpy, the standard library, `regrasp_casadi.errors` and `regrasp_casadi.motion` are
imported.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
from typing import Any

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.errors import PlanFormatError
from regrasp_casadi.motion import INTERPOLATION, PATH_PHASES, StepPath

__all__ = [
    "CERTIFICATE_KINDS",
    "require_mapping",
    "check_choice",
    "get_field",
    "get_choice",
    "get_float",
    "get_array",
    "get_certificate",
    "path_to_dict",
    "path_from_dict",
    "jsonable",
    "read_json",
]

PATH_FIELDS = tuple(f.name for f in dataclasses.fields(StepPath))

CERTIFICATE_KINDS = ("force_closure", "gravity")
"""The kinds of a step's stored stability certificate (`certificates.Certificate.kind`)."""


def get_certificate(d: dict, where: str) -> dict | None:
    """The optional step certificate (absent or null: None): a mapping with a known kind and a bool ok."""
    if d.get("certificate") is None:
        return None
    w = f"{where}.certificate"
    c = require_mapping(d["certificate"], w, ("kind", "ok", "margin", "forces", "detail"))
    check_choice(c.get("kind"), CERTIFICATE_KINDS, f"{w}.kind")
    get_field(c, "ok", w, bool)
    return dict(c)


def path_to_dict(path: StepPath, where: str) -> dict[str, Any]:
    """JSON-ready dict of a `StepPath`; `PlanFormatError` for a phase or rule `from_dict` would refuse."""
    for i, phase in enumerate(path.phases):
        check_choice(phase, PATH_PHASES, f"{where}.phases[{i}]")
    check_choice(path.interpolation, (INTERPOLATION,), f"{where}.interpolation")
    return {
        "t": path.t.tolist(),
        "q": path.q.tolist(),
        "T_palm_object": path.T_palm_object.tolist(),
        "phases": list(path.phases),
        "ok": path.ok,
        "detail": path.detail,
        "metrics": dict(path.metrics),
        "interpolation": path.interpolation,
    }


def path_from_dict(d: Any, where: str) -> StepPath:
    """Inverse of `path_to_dict`; `PlanFormatError` naming the field."""
    d = require_mapping(d, where, PATH_FIELDS)
    phases = get_field(d, "phases", where, list)
    for i, phase in enumerate(phases):
        check_choice(phase, PATH_PHASES, f"{where}.phases[{i}]")
    metrics = get_field(d, "metrics", where, dict)
    for k, v in metrics.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise PlanFormatError(f"{where}.metrics.{k}: expected a finite number, found {v!r:.60}")
    t = get_array(d, "t", where, 1)
    if t.size and (t[0] != 0.0 or np.any(np.diff(t) < 0)):
        raise PlanFormatError(f"{where}.t: expected time stamps from 0, non-decreasing")
    try:
        return StepPath(t=t, q=get_array(d, "q", where, 2),
                        T_palm_object=get_array(d, "T_palm_object", where, 3, (None, 4, 4)),
                        phases=tuple(phases), ok=get_field(d, "ok", where, bool),
                        detail=get_field(d, "detail", where, str), metrics=metrics,
                        interpolation=get_choice(d, "interpolation", where, (INTERPOLATION,)))
    except ValueError as e:
        raise PlanFormatError(f"{where}: {e}") from None


# ---------------------------------------------------------------------------- dict field validation
def require_mapping(d: Any, where: str, fields: tuple[str, ...]) -> dict:
    """`d` itself, after checking that it is a dict whose keys are all among `fields`."""
    if not isinstance(d, dict):
        raise PlanFormatError(f"{where}: expected an object (mapping), found {type(d).__name__}")
    unknown = [k for k in d if k not in fields]
    if unknown:
        names = ", ".join(repr(k) for k in unknown)
        raise PlanFormatError(
            f"{where}: unknown field{'s' if len(unknown) > 1 else ''} {names} (known: {', '.join(fields)})"
        )
    return d


def check_choice(value: Any, choices: tuple[str, ...], name: str) -> None:
    if not isinstance(value, str) or value not in choices:
        raise PlanFormatError(f"{name}: expected one of {', '.join(choices)}, found {value!r:.60}")


def get_field(d: dict, key: str, where: str, types: type | tuple[type, ...]) -> Any:
    if key not in d:
        raise PlanFormatError(f"{where}.{key}: missing field")
    v = d[key]
    allowed = types if isinstance(types, tuple) else (types,)
    if not isinstance(v, allowed) or (isinstance(v, bool) and bool not in allowed):
        names = types.__name__ if isinstance(types, type) else " or ".join(t.__name__ for t in types)
        raise PlanFormatError(f"{where}.{key}: expected {names}, found {type(v).__name__} {v!r:.60}")
    return v


def get_choice(d: dict, key: str, where: str, choices: tuple[str, ...]) -> Any:
    v = get_field(d, key, where, str)
    check_choice(v, choices, f"{where}.{key}")
    return v


def get_float(d: dict, key: str, where: str) -> float:
    v = get_field(d, key, where, (int, float))
    if isinstance(v, bool) or not math.isfinite(v):
        raise PlanFormatError(f"{where}.{key}: expected a finite number, found {v!r}")
    return float(v)


def get_array(
    d: dict, key: str, where: str, ndim: int, shape: tuple[int | None, ...] | None = None
) -> NDArray[np.float64]:
    if key not in d:
        raise PlanFormatError(f"{where}.{key}: missing field")
    v = d[key]
    try:
        if not isinstance(v, list) or _has_bool(v):
            raise TypeError
        a = np.array(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise PlanFormatError(
            f"{where}.{key}: expected a {ndim}-D array of numbers, found {v!r:.60}"
        ) from None
    if a.ndim != ndim and not (a.size == 0 and ndim == 2 and shape is not None):
        raise PlanFormatError(f"{where}.{key}: expected a {ndim}-D array, found shape {a.shape}")
    if a.size == 0 and ndim == 2 and shape is not None:
        a = a.reshape(0, shape[1] if shape[1] is not None else 0)
    if shape is not None and any(s is not None and s != n for s, n in zip(shape, a.shape, strict=True)):
        raise PlanFormatError(f"{where}.{key}: expected shape {shape}, found {a.shape}")
    if not np.all(np.isfinite(a)):
        raise PlanFormatError(f"{where}.{key}: non-finite values")
    return a


def _has_bool(v: Any) -> bool:
    if isinstance(v, bool):
        return True
    if isinstance(v, list):
        return any(_has_bool(x) for x in v)
    return False


def jsonable(x: Any, where: str) -> Any:
    """Convert numpy scalars/arrays and tuples to JSON-native values; reject non-finite floats."""
    if isinstance(x, dict):
        return {str(k): jsonable(v, f"{where}.{k}") for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v, f"{where}[{i}]") for i, v in enumerate(x)]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist(), where)
    if isinstance(x, np.generic):
        return jsonable(x.item(), where)
    if isinstance(x, float) and not math.isfinite(x):
        raise PlanFormatError(f"{where}: non-finite value {x!r} cannot be written to JSON")
    if isinstance(x, pathlib.PurePath):
        return str(x)
    if x is None or isinstance(x, (bool, int, float, str)):
        return x
    raise PlanFormatError(f"{where}: value of type {type(x).__name__} cannot be written to JSON")


# ------------------------------------------------------------------------------------------ JSON text
def read_json(path: pathlib.Path) -> Any:
    """The JSON document in `path` (UTF-8, no NaN/Infinity, no duplicate keys).

    Raises:
        PlanFormatError: without the file name (the caller adds it).
    """
    try:
        data = path.read_bytes()
    except OSError as e:
        raise PlanFormatError(f"cannot read plan file: {e.strerror or e}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise PlanFormatError(f"not a UTF-8 text file (byte {e.start}: {e.reason})") from None
    try:
        return json.loads(text, parse_constant=_reject_constant, object_pairs_hook=_reject_duplicates)
    except ValueError as e:  # json.JSONDecodeError, or NaN / Infinity from `_reject_constant`
        raise PlanFormatError(f"not valid JSON: {e}") from None


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} is not allowed in a plan file")


def _reject_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """`object_pairs_hook` for `json.loads`: a dict, or `PlanFormatError` for a key given twice."""
    d: dict[str, Any] = {}
    for k, v in pairs:
        if k in d:
            raise PlanFormatError(f"duplicate key {k!r} in a JSON object")
        d[k] = v
    return d
