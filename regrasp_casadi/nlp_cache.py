"""Caches of built NLPs: `NLPCache` keeps the package's NLP objects across plans (one per kind, hand,
object and options), and `build_solver`'s solvers are kept by the hash of their expressions
(`solver_key`), so an NLP whose object data are parameters (OPT2's) is built once per process.

    >>> cache = NLPCache()
    >>> nlp = cache.get("finger_gait", hand, obj, ("index", options), lambda: FingerGaitNLP(...))
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Callable, Hashable, Sequence
from typing import Any, TypeVar

import casadi as ca

__all__ = ["NLPCache", "solver_key", "built_solver", "keep_solver", "clear_built_solvers", "BUILT_MAX"]

NLP = TypeVar("NLP")


class _Same:
    """A key part that compares by identity and holds its object, so that while the key is cached the
    object stays alive and its id cannot be reused by another."""

    __slots__ = ("obj",)

    def __init__(self, obj: Any):
        self.obj = obj

    def __hash__(self) -> int:
        return id(self.obj)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Same) and other.obj is self.obj


class NLPCache:
    """Built NLPs, reused across plans: one per (kind, hand, object, key), the least recently used
    dropped beyond `max_size`.

    The hand and object are part of the key by identity (a new model is a new entry, even when equal
    to a cached one) and are held by the cache until their entries are dropped or the cache is cleared.

        >>> cache = NLPCache()
        >>> nlp = cache.get("finger_gait", hand, obj, ("index", options), lambda: FingerGaitNLP(...))
        >>> cache.clear()
    """

    def __init__(self, max_size: int = 64):
        self.max_size = int(max_size)
        """Largest number of NLPs kept."""
        self.builds = 0
        """Number of NLPs this cache has built."""
        self._nlps: OrderedDict[tuple, Any] = OrderedDict()

    def get(self, kind: str, hand: Any, obj: Any, key: Hashable, build: Callable[[], NLP]) -> NLP:
        """The cached NLP of `kind` for (`hand`, `obj`, `key`); on a miss `build()` makes it."""
        full_key = (kind, _Same(hand), _Same(obj), key)
        if full_key in self._nlps:
            self._nlps.move_to_end(full_key)
            return self._nlps[full_key]
        nlp = build()
        self.builds += 1
        self._nlps[full_key] = nlp
        while len(self._nlps) > self.max_size:
            self._nlps.popitem(last=False)
        return nlp

    def clear(self) -> None:
        """Forget every NLP (and release the hands and objects they were built for)."""
        self._nlps.clear()

    def __len__(self) -> int:
        return len(self._nlps)


BUILT_MAX = 16
"""Solvers `build_solver` keeps in this process, by the hash of their NLP's expressions (least recently
used dropped beyond it)."""
_BUILT: OrderedDict[str, ca.Function] = OrderedDict()


def solver_key(name: str, backend: str, nlp: dict, opts: dict, curved_rows: Sequence[int] | None,
               compiled_mode: str) -> str:
    """SHA-256 of everything a built solver depends on: its NLP's expressions (x, p -> f, g, serialized),
    the backend's options, the curved rows, the compiled mode (`compiled.mode`), and its name. An NLP whose
    object data are parameters (OPT2's; OPT1's for every object of two or more convex pieces) has the same
    expressions for every object, so it is built once per process (its Hessian with common subexpressions
    eliminated takes ~2 s), not once per object."""
    x = nlp["x"]
    f = ca.Function("key", [x, nlp.get("p", type(x)(0, 1))], [nlp["f"], nlp.get("g", type(x)(0, 1))])
    rows = None if curved_rows is None else sorted(set(int(i) for i in curved_rows))
    text = repr((name, backend, sorted(opts.items()), rows, compiled_mode, ca.__version__))
    return hashlib.sha256(f.serialize().encode() + text.encode()).hexdigest()


def clear_built_solvers() -> None:
    """Forget the solvers `build_solver` keeps (the next build of each NLP builds it again)."""
    _BUILT.clear()


def built_solver(key: str) -> ca.Function | None:
    """The solver kept under `key` (`solver_key`), or None."""
    solver = _BUILT.get(key)
    if solver is not None:
        _BUILT.move_to_end(key)
    return solver


def keep_solver(key: str, solver: ca.Function) -> ca.Function:
    """Keep `solver` under `key` (the least recently used dropped beyond `BUILT_MAX`); returns it."""
    _BUILT[key] = solver
    while len(_BUILT) > BUILT_MAX:
        _BUILT.popitem(last=False)
    return solver
