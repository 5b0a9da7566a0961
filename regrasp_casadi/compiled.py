"""Compiled NLP solvers: an NLP's functions (objective, constraints, their derivatives and the Hessian of
the Lagrangian) generated as C by CasADi, compiled by the system C compiler into a shared library and
loaded by the backend instead of being evaluated by CasADi's virtual machine.

`solver.build_solver` is the one caller. Three modes (`mode`): "compile" (`SolverOptions.compiled` True
or ``$REGRASP_COMPILE=1``): a library is compiled when the cache has none; "cached" (the default, or
``$REGRASP_COMPILE=cached``): a library already in the cache is used, none is compiled (`regrasp compile`
fills the cache once per hand: `precompile`); "off" (`compiled` False or ``$REGRASP_COMPILE=0``): always
interpreted. Compiled and interpreted solvers give the same plans (the paper benchmark's 50 plans: the same
steps, errors and IPOPT iterations, 2026-12-06). Anything that goes wrong (no C compiler on the PATH, a
failed or timed-out compilation, a library that does not load) logs one warning per kind of failure and
per process, and the interpreted solver is returned: compiling never makes a build fail.

    >>> solver = compiled.solver("in_grasp_svd", nlp, "ipopt", opts)   # compiled, or interpreted

The libraries are cached on disk, ``<cache dir>/jit/nlp_<key>.so`` (the cache dir of `convex.cache_dir`,
``$REGRASP_CACHE_DIR``), the key a SHA-256 of the serialized NLP (x, p → f, g), the CasADi version, the
compiler (its path and version line), its flags and the backend's structural options. A library is built
in a private temporary folder beside its target and renamed onto it (atomic), so two processes compiling
the same NLP both succeed and either one's file is kept.

Measured (benchmarks/README.md, "OPT1's clearance on local plane sets ... and compiled NLPs"): the paper
benchmark's 50 plans, identical compiled and interpreted, OPT1 6.2 → 4.0 ms and OPT2 28.8 → 13.3 ms per
call (SVD, medians), plan median 3.44 → 1.94 s. Compiling takes minutes, once per hand and machine (the
NLPs' object data are parameters; OPT1 has a one-piece and a several-piece variant): `regrasp compile
--jobs 2` made the 10 libraries in 3 min 55 s. Hence `DEFAULT` "cached": no compiling unasked.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import pathlib
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass

import casadi as ca

__all__ = ["ENV_VAR", "DEFAULT", "MODES", "COMPILERS", "CFLAGS", "BuildRecord", "mode", "enabled",
           "find_compiler", "library_key", "library_path", "solver", "compile_count", "build_records"]

_log = logging.getLogger(__name__)

ENV_VAR = "REGRASP_COMPILE"
"""Environment variable of the process-wide mode: "1" compile, "cached", "0" off (unset: `DEFAULT`)."""
MODES = ("compile", "cached", "off")
"""The modes (module docstring)."""
DEFAULT = "cached"
"""The mode when neither the option nor `ENV_VAR` says: compiled libraries are used once `regrasp compile`
has made them (compiling the planner's NLPs takes minutes, once per hand and machine; each solve is then
2-3x faster), and none is compiled unasked."""
COMPILERS = ("cc", "gcc")
"""C compilers looked for on the PATH, in order."""
CFLAGS = ("-O1", "-fPIC", "-shared")
"""Compiler flags (-O1: -O0 code is no faster than CasADi's virtual machine; -O1 halves the Hessian's
evaluation time)."""
GCC_FLAGS = ("-fira-region=one", "-fno-tree-ter")
"""Added for gcc: the same code quality as plain -O1 on OPT2's Hessian, a quarter less compile time
(register allocation of the one huge function dominates gcc's time)."""
TIMEOUT = 1800.0
"""Longest compilation of one NLP before giving up (and solving interpreted), s."""
FUNCTIONS = ("nlp_f", "nlp_g", "nlp_grad", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")
"""The backend's functions put in the library besides the NLP itself (`generate_dependencies`' list)."""

_IN_LIBRARY = ("hess_lag", "jac_g", "grad_f")
"""`nlpsol` options of user-given derivative functions: compiled into the library, not passed again."""
_COUNTERS = {"compiles": 0}
_WARNED: set[str] = set()


@dataclass(frozen=True)
class BuildRecord:
    """One compiled solver made in this process (for benchmarks: compile and load times)."""

    name: str
    """The solver's name."""
    path: str
    """The shared library."""
    compiled: bool
    """True: compiled now; False: loaded from the disk cache."""
    seconds: float
    """Wall time of code generation + compilation + loading (compiled) or of loading (cached), s."""


_RECORDS: list[BuildRecord] = []


def compile_count() -> int:
    """Number of NLP libraries compiled in this process (disk-cache hits do not count)."""
    return _COUNTERS["compiles"]


def build_records() -> list[BuildRecord]:
    """The compiled solvers made in this process, oldest first (a copy)."""
    return list(_RECORDS)


def mode(option: bool | None) -> str:
    """The mode of a build (one of `MODES`): "compile" / "off" for `option` True / False, else
    ``$REGRASP_COMPILE`` ("1", "cached", "0"), else `DEFAULT`."""
    if option is not None:
        return "compile" if option else "off"
    value = os.environ.get(ENV_VAR, "").strip().lower()
    if value in ("1", "true", "yes", "on", "compile"):
        return "compile"
    if value in ("0", "false", "no", "off"):
        return "off"
    if value == "cached":
        return "cached"
    if value:
        _warn_once(f"env:{value}", "%s=%r is not 1, cached or 0; using the default (%s)", ENV_VAR, value,
                   DEFAULT)
    return DEFAULT


def enabled(option: bool | None) -> bool:
    """Whether a build compiles a library the cache lacks (`mode` "compile")."""
    return mode(option) == "compile"


def find_compiler() -> str | None:
    """The path of the first of `COMPILERS` on the PATH, or None."""
    for name in COMPILERS:
        path = shutil.which(name)
        if path:
            return path
    return None


@functools.lru_cache(maxsize=8)
def _compiler_id(path: str) -> tuple[str, tuple[str, ...]]:
    """The compiler's path and the first line of its ``--version`` (part of the cache key), and its
    flags (`CFLAGS`, plus `GCC_FLAGS` for gcc)."""
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30, check=False)
        text = (out.stdout or out.stderr).strip()
    except (OSError, subprocess.SubprocessError):
        text = ""
    first = text.splitlines()[0] if text else "?"
    gcc = "Free Software Foundation" in text and "clang" not in text
    return f"{path} {first}", CFLAGS + (GCC_FLAGS if gcc else ())


def library_key(nlp: dict, backend: str, opts: dict, compiler: str) -> str:
    """The cache key (hex) of `nlp` ({"x", "p", "f", "g"}) built with `backend` and `opts` by the compiler
    at path `compiler`: IPOPT's own ("ipopt."-prefixed) options do not change the generated code, except
    the Hessian approximation, and are left out; a user-given derivative Function (`hess_lag`) enters by its
    serialization."""
    x = nlp["x"]
    empty = type(x)(0, 1)
    fg = ca.Function("nlp", [x, nlp.get("p", empty)], [nlp["f"], nlp.get("g", empty)])
    structural = sorted((k, v.serialize() if isinstance(v, ca.Function) else repr(v)) for k, v in opts.items()
                        if not k.startswith("ipopt.") or k == "ipopt.hessian_approximation")
    h = hashlib.sha256()
    identity, flags = _compiler_id(compiler)
    for part in (fg.serialize(), ca.__version__, identity, " ".join(flags), backend,
                 repr(structural), " ".join(FUNCTIONS)):
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()[:32]


def library_path(key: str) -> pathlib.Path:
    """Where the library of `key` is cached: ``<cache dir>/jit/nlp_<key>.so``."""
    from regrasp_casadi.convex import cache_dir  # the project's one cache-dir convention

    return cache_dir() / "jit" / f"nlp_{key}.so"


def solver(name: str, nlp: dict, backend: str, opts: dict, compile_missing: bool = True) -> ca.Function:
    """The `backend` solver of `nlp` named `name` with options `opts`, evaluated from a compiled library
    (cached on disk); the interpreted solver when no compiler is found or compilation fails (one
    warning per kind of failure and process), or, with `compile_missing` False, when the cache has no
    library of it (no warning: mode "cached")."""
    if not compile_missing and not _any_library():  # nothing compiled on this machine: skip the key
        return ca.nlpsol(name, backend, nlp, opts)  # (serializing OPT2 and its Hessian takes ~0.6 s)
    compiler = find_compiler()
    if compiler is None:
        if compile_missing:
            _warn_once("no-compiler", "no C compiler (%s) on the PATH: NLPs are solved interpreted",
                       "/".join(COMPILERS))
        return ca.nlpsol(name, backend, nlp, opts)
    interpreted = None
    try:
        t0 = time.perf_counter()
        path = library_path(library_key(nlp, backend, opts, compiler))
        fresh = not path.is_file()
        if fresh and not compile_missing:
            return ca.nlpsol(name, backend, nlp, opts)
        if fresh:
            interpreted = ca.nlpsol(name, backend, nlp, opts)
            _compile(interpreted, path, compiler)
        # the library holds the NLP's own functions, a user-given Hessian (`hess_lag`) among them
        result = ca.nlpsol(name, backend, str(path), {k: v for k, v in opts.items() if k not in _IN_LIBRARY})
    except (OSError, RuntimeError, subprocess.SubprocessError) as exc:
        _warn_once("failed", "compiling NLP %s failed, solving it interpreted (warned once): %s", name,
                   str(exc).strip()[-2000:])
        return interpreted if interpreted is not None else ca.nlpsol(name, backend, nlp, opts)
    seconds = time.perf_counter() - t0
    _RECORDS.append(BuildRecord(name, str(path), fresh, seconds))
    _log.info("%s NLP %s in %.2f s (%s)", "compiled" if fresh else "loaded", name, seconds, path)
    return result


def _any_library() -> bool:
    """Whether the cache holds any compiled library (``<cache dir>/jit/nlp_*.so``)."""
    folder = library_path("").parent
    return folder.is_dir() and any(folder.glob("nlp_*.so"))


def _compile(interpreted: ca.Function, target: pathlib.Path, compiler: str) -> None:
    """Generate the C of `interpreted` (its NLP and `FUNCTIONS`), compile it into `target` (atomic: a
    temporary folder beside it, then a rename).

    Raises:
        OSError, RuntimeError (CasADi) or subprocess.SubprocessError (compiler failed or timed out).
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    stem = target.stem  # nlp_<hex>: a valid C identifier, the generator's name
    with tempfile.TemporaryDirectory(prefix=".build-", dir=target.parent) as tmp:
        gen = ca.CodeGenerator(f"{stem}.c")
        gen.add(interpreted.oracle())
        for fname in FUNCTIONS:
            gen.add(interpreted.get_function(fname))
        source = gen.generate(tmp + os.sep)
        built = pathlib.Path(tmp) / target.name
        flags = _compiler_id(compiler)[1]
        proc = subprocess.run([compiler, *flags, source, "-o", str(built), "-lm"], capture_output=True,
                              text=True, timeout=TIMEOUT, check=False)
        if proc.returncode != 0 or not built.is_file():
            raise subprocess.SubprocessError(f"{compiler} exited with {proc.returncode}: {proc.stderr}")
        os.replace(built, target)
    _COUNTERS["compiles"] += 1


def _warn_once(kind: str, message: str, *args: object) -> None:
    """Log `message` as a warning the first time `kind` is met in this process."""
    if kind not in _WARNED:
        _WARNED.add(kind)
        _log.warning(message, *args)
