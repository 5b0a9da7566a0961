"""Building blocks of the `regrasp` command line: one-line errors, argument types, output-path and host
checks made before any long work, the help formatter, and progress bars on stderr.

Nothing here plans or loads models; `regrasp_casadi.cli` assembles the commands from these pieces.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "EXIT_BAD_INPUT", "UserError", "print_error", "Parser", "HelpFormatter",
    "positive_int", "non_negative_int", "positive_float", "non_negative_float", "finite_float",
    "finite_positive_float",
    "gravity_values", "plan_stability", "plan_gravity_palm", "check_output", "check_host",
    "progress_enabled", "progress_bar", "plan_progress", "found_progress",
]

EXIT_BAD_INPUT = 2
"""Exit code of bad input (also `regrasp_casadi.cli.EXIT_BAD_INPUT`)."""


class UserError(Exception):
    """An input problem detected by the CLI itself (exit code 2)."""


def print_error(msg: str) -> None:
    """Print ``regrasp: error: <msg>`` on stderr (the CLI's one error line)."""
    print(f"regrasp: error: {msg}", file=sys.stderr)


# ------------------------------------------------------------------------------------- argument types
def _number(kind: type, minimum: float, strict: bool, what: str) -> Callable[[str], Any]:
    """An argparse `type` accepting a `kind` (int or float) above `minimum` (or equal, unless `strict`)."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not (value > minimum if strict else value >= minimum):  # NaN fails both comparisons
            raise argparse.ArgumentTypeError(f"expected {what}, got {text}")
        return value

    parse.__name__ = what
    return parse


positive_int = _number(int, 0, True, "a positive integer")
non_negative_int = _number(int, 0, False, "a non-negative integer")
positive_float = _number(float, 0.0, True, "a positive number")
non_negative_float = _number(float, 0.0, False, "a non-negative number")


def finite_float(text: str) -> float:
    """argparse type: a finite number."""
    try:
        x = float(text)
    except ValueError:
        x = float("nan")
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return x


def finite_positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    x = finite_float(text)
    if x <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return x


class Parser(argparse.ArgumentParser):
    """Usage errors as ONE line, like every other error of the CLI (exit code 2)."""

    def error(self, message: str):
        print_error(f"{message} (see `{self.prog} --help`)")
        self.exit(EXIT_BAD_INPUT)


class HelpFormatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """Keeps the epilog's layout and appends "(default: …)" to options whose default means something
    (not None, not False, not already stated in the help text)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if any(action.default is x for x in (None, False, argparse.SUPPRESS)) or "default" in text:
            return text
        return super()._get_help_string(action)


# --------------------------------------------------------------------------- checks before long work
def gravity_values(option: str, values: list[str] | None, words: tuple[str, ...]) -> tuple | str | None:
    """A ``--gravity`` value: None (not given), one of `words` (e.g. "support"), or three finite numbers
    (m/s², palm frame) as a tuple.

    Raises:
        UserError: naming `option`, for anything else.
    """
    if values is None:
        return None
    if len(values) == 1 and values[0] in words:
        return values[0]
    try:
        g = tuple(finite_float(v) for v in values)
    except argparse.ArgumentTypeError as exc:
        raise UserError(f"{option}: {exc}") from None
    if len(g) != 3:
        raise UserError(f"{option}: expected X Y Z (m/s^2, palm frame) or one of {', '.join(words)}; "
                        f"got {' '.join(values)}")
    return g


def plan_stability(stability: str | None, gravity: list[str] | None,
                   problem_gravity: tuple | str | None = None) -> tuple[str, tuple | str | None]:
    """`regrasp plan`'s certificate and gravity from ``--stability``, ``--gravity`` and the problem file's
    `gravity` (`problem_gravity`; ``--gravity`` wins): "force_closure" by default, "gravity" when a
    gravity is given (X Y Z, or "support") and ``--stability`` does not say otherwise (an explicit
    ``--stability`` other than gravity ignores the file's).

    Raises:
        UserError: ``--gravity`` with another ``--stability``, or a malformed ``--gravity``.
    """
    g = gravity_values("--gravity", gravity, ("support",))
    if g is None and stability in (None, "gravity"):
        g = problem_gravity
    stability = stability or ("gravity" if g is not None else "force_closure")
    if g is not None and stability != "gravity":
        raise UserError(f"--gravity sets the gravity certificate's direction: it needs --stability gravity, "
                        f"not {stability}")
    return stability, g


def plan_gravity_palm(gravity: tuple | str, grasp0) -> tuple[float, float, float]:
    """Gravity in the palm frame, m/s²: the given X Y Z, or for "support" the direction that presses the
    object of `grasp0` onto the fingers opposite the thumb (`hand_orientation.supporting_gravity`,
    printed on stderr)."""
    if gravity != "support":
        return tuple(float(v) for v in gravity)
    from regrasp_casadi.hand_orientation import supporting_gravity

    g = tuple(float(v) for v in supporting_gravity(grasp0))
    print("gravity (palm frame, m/s^2): " + " ".join(f"{v:.3f}" for v in g), file=sys.stderr)
    return g


def check_output(option: str, value: str | os.PathLike | None, folder: bool = False) -> Path | None:
    """The path given to `option` (None stays None), checked before any long work.

    It must not be an existing folder (or, with `folder`, an existing file), and the first existing
    folder on its way must be a folder that can be written to (missing folders are made when the file
    is saved). Writing a temporary file there is the test: it also holds for root and read-only mounts.

    Raises:
        UserError: naming the option and the path.
    """
    if value is None:
        return None
    path = Path(value).expanduser()
    if not folder and path.is_dir():
        raise UserError(f"{option} {value}: is a folder; give a file name")
    if folder and path.exists() and not path.is_dir():
        raise UserError(f"{option} {value}: is a file; give a folder")
    existing = (path if folder else path.parent).absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f"{option} {value}: {existing} is not a folder")
    try:
        with tempfile.NamedTemporaryFile(dir=existing, prefix=".regrasp-write-test-"):
            pass
    except OSError as e:
        raise UserError(f"{option} {value}: cannot write in {existing} ({e.strerror or e})") from None
    return path


def check_host(host: str) -> str:
    """`--host`, checked before any long work: an address of this machine. Raises `UserError`."""
    from regrasp_casadi.live_server import check_host as check

    try:
        check(host)
    except ValueError as e:
        raise UserError(f"--{e}") from None
    return host


# ------------------------------------------------------------------------------------- progress bars
def progress_enabled(args: argparse.Namespace) -> bool:
    """Progress bars on stderr: only on a terminal, and not with --quiet (or --no-progress)."""
    quiet = getattr(args, "quiet", False) or getattr(args, "no_progress", False)
    return not quiet and sys.stderr.isatty()


@contextlib.contextmanager
def progress_bar(desc: str, enabled: bool, total: int | None = None, unit: str = "it") -> Iterator[Any]:
    """A tqdm bar on stderr (None when not `enabled`), redrawn every 0.5 s so that its elapsed time runs
    while the work gives no news; closed at the end (left on screen when it has a `total`)."""
    if not enabled:
        yield None
        return
    from tqdm import tqdm

    bar_format = None if total is not None else "{desc}: {elapsed}{postfix}"
    bar = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, dynamic_ncols=True,
               leave=total is not None, bar_format=bar_format)
    stop = threading.Event()

    def redraw() -> None:
        while not stop.wait(0.5):
            bar.refresh()

    thread = threading.Thread(target=redraw, name="regrasp-progress", daemon=True)
    thread.start()
    try:
        yield bar
    finally:
        stop.set()
        thread.join()
        bar.close()


def plan_progress(bar) -> Callable[[int, int, float], None] | None:
    """The planner's ``progress(iteration, max_iters, average_error_m)`` driving `bar` (None without)."""
    if bar is None:
        return None

    def callback(iteration: int, max_it: int, avg_error_m: float) -> None:
        bar.total = max_it
        bar.n = min(iteration, max_it)
        bar.set_postfix_str(f"avg error {avg_error_m * 1e3:.2f} mm", refresh=False)
        bar.refresh()

    return callback


def found_progress(bar) -> Callable[[int, int], None] | None:
    """Grasp generation's ``progress(found, attempts)`` driving `bar` (None without a bar)."""
    if bar is None:
        return None

    def callback(found: int, attempts: int) -> None:
        bar.n = found
        bar.set_postfix_str(f"attempt {attempts}", refresh=False)
        bar.refresh()

    return callback
