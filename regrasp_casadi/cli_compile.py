"""The `regrasp compile` subcommand: compile the planner's NLPs for a hand into the disk cache
(`regrasp_casadi.precompile`), so that every later plan solves them compiled (2-3x faster per solve).

    regrasp compile [--hand MODEL|HAND.urdf] [--jobs N]

Exit codes (`regrasp_casadi.cli`): 0 every NLP compiled or already cached, 1 some could not be compiled
(they stay interpreted), 2 bad input (no C compiler, an unknown hand).
"""

from __future__ import annotations

import argparse

from regrasp_casadi.cli_tools import positive_int

__all__ = ["add_compile_parser", "cmd_compile"]


def cmd_compile(args: argparse.Namespace) -> int:
    """Compile (or find cached) every planner NLP of the hand, one line per NLP; exit 1 if one failed."""
    from regrasp_casadi.precompile import precompile

    records = precompile(args.hand, jobs=args.jobs, report=lambda line: print(line, flush=True))
    failed = [r.name for r in records if not r.path]
    if failed:
        print(f"{len(failed)} NLP(s) could not be compiled and stay interpreted: {', '.join(failed)}")
        return 1
    print(f"done: {len(records)} NLPs ({sum(r.compiled for r in records)} compiled now); plans use them "
          "unless REGRASP_COMPILE=0")
    return 0


def add_compile_parser(add, default_hand: str) -> None:
    """The `compile` subcommand (``add(name, help)`` makes a subparser)."""
    sp = add("compile", "compile the planner's NLPs for a hand to C, once: every later plan solves them "
                        "2-3x faster")
    sp.add_argument("--hand", default=default_hand, metavar="MODEL",
                    help=f"a shipped model name, a model folder or a URDF file (default: {default_hand})")
    sp.add_argument("--jobs", type=positive_int, default=1, metavar="N",
                    help="NLPs compiled at a time, one process each (default: 1)")
    sp.set_defaults(func=cmd_compile)
