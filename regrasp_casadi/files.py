"""Writing files without losing them: `atomic_write_text` / `atomic_write_bytes`.

The new content goes to a temporary file in the same folder, is flushed to disk (`os.fsync`) and then
renamed over the target (`os.replace`, atomic on POSIX and Windows). A write that fails at any point
(disk full, Ctrl-C, a permission error) leaves the previous file as it was and removes the temporary
file; the error is re-raised unchanged.

    >>> atomic_write_text("plan.json", text)

Only the standard library is imported here.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import secrets
import stat

__all__ = ["atomic_write_text", "atomic_write_bytes"]


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> pathlib.Path:
    """Replace `path` by `text` atomically (encoded with `encoding`, newlines written as given).

    Returns:
        The path written.

    Raises:
        OSError (or any error of the encoding or the write): the previous file is kept, no temporary
        file is left behind.
    """
    return atomic_write_bytes(path, text.encode(encoding))


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> pathlib.Path:
    """Replace `path` by `data` atomically (temporary file in the same folder + fsync + os.replace).

    A new file gets the usual permissions (0o666 minus the umask); an existing one keeps its mode. A
    symbolic link is followed: its target is replaced, the link stays.

    Returns:
        The path written (as given, not resolved).

    Raises:
        OSError (or any other error on the way): the previous file is kept, no temporary file is left.
    """
    path = pathlib.Path(path)
    target = path.resolve() if path.is_symlink() else path
    tmp = target.with_name(f".{target.name}.{secrets.token_hex(4)}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        try:
            _copy_mode(target, tmp)
            _write_all(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _sync_folder(target.parent)
    return path


def _write_all(fd: int, data: bytes) -> None:
    """Write every byte of `data` to the file descriptor `fd` (os.write may write less than asked)."""
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def _copy_mode(target: pathlib.Path, tmp: pathlib.Path) -> None:
    """Give `tmp` the permission bits of `target` when it exists (a plain write would keep them)."""
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        return
    os.chmod(tmp, mode)


def _sync_folder(folder: pathlib.Path) -> None:
    """Flush the folder entry (the rename) to disk where the platform allows it (POSIX; a no-op else)."""
    if not hasattr(os, "O_DIRECTORY"):
        return
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
