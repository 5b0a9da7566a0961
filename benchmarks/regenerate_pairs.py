"""Regenerate the grasps of the paper-benchmark problem files (benchmarks/problems/<object>_<k>.yaml).

The pairs come from `paper_objects.generate_pairs` (`grasp_gen.generate_regrasp_pairs`, same seeds as
the originals: 2018 + object index), which now keeps the collision spheres of different fingers and of a
finger and the palm `constants.SELF_CLEARANCE` apart (issue 15). They are generated into a temporary
folder, and only the `description`, `grasp0` and `grasp_goal` blocks of the existing files are replaced:
every other key (the object's mesh path, sha256, any `mass`, ...) stays as it is. Prints the generation
time per object. Measures; asserts nothing.

    nice -n 10 python benchmarks/regenerate_pairs.py [--objects banana ...] [--workers 2]
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from paper_objects import OBJECTS, generate_pairs, problem_paths  # noqa: E402

REPLACED = ("description", "grasp0", "grasp_goal")
"""Top-level keys taken from the regenerated file; every other top-level block is kept."""


def top_level_blocks(text: str) -> list[tuple[str, str]]:
    """(key, text) of every top-level block of a YAML file, in order ("" for leading comments)."""
    blocks: list[tuple[str, list[str]]] = [("", [])]
    for line in text.splitlines(keepends=True):
        if line[:1] not in ("", " ", "-", "#", "\n") and ":" in line:
            blocks.append((line.split(":", 1)[0], [line]))
        else:
            blocks[-1][1].append(line)
    return [(k, "".join(lines)) for k, lines in blocks]


def splice(old: str, new: str) -> str:
    """`old` with its `REPLACED` blocks taken from `new` (added at the end if `old` lacks one)."""
    fresh = {k: v for k, v in top_level_blocks(new) if k in REPLACED}
    out, seen = [], set()
    for key, block in top_level_blocks(old):
        out.append(fresh.get(key, block))
        seen.add(key)
    out += [fresh[k] for k in REPLACED if k in fresh and k not in seen]
    return "".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", nargs="+", default=list(OBJECTS))
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--problems-dir", type=pathlib.Path, default=HERE / "problems")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(generate_pairs, name, args.pairs, tmp) for name in args.objects]
        for fut in futures:
            name, secs, paths = fut.result()
            for new, old in zip(paths, problem_paths(args.problems_dir, name, args.pairs), strict=True):
                fresh = pathlib.Path(new).read_text()
                old.write_text(splice(old.read_text(), fresh) if old.is_file() else fresh)
            print(f"{name}: {args.pairs} pairs in {secs:.1f} s", flush=True)
    print(f"total {time.perf_counter() - t0:.1f} s (wall, {args.workers} workers)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
