"""Atomic writes: a write that fails at any stage keeps the previous file and leaves no temporary."""

from __future__ import annotations

import errno
import os
import stat
import sys

import pytest

from regrasp_casadi import files
from regrasp_casadi.files import atomic_write_bytes, atomic_write_text


def _disk_full_after_half(fd, data):
    os.write(fd, bytes(data[: len(data) // 2]))
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _raise(exc):
    def fail(*args, **kwargs):
        raise exc

    return fail


@pytest.mark.parametrize(
    "target, replacement, exc_type",
    [
        ("_write_all", _disk_full_after_half, OSError),
        ("_write_all", _raise(KeyboardInterrupt()), KeyboardInterrupt),  # Ctrl-C during the write
        ("os.fsync", _raise(OSError(errno.EIO, "I/O error")), OSError),
        ("os.replace", _raise(PermissionError(errno.EACCES, "denied")), PermissionError),
    ],
)
def test_failure_at_any_stage_keeps_the_old_file_and_removes_the_temporary(
    tmp_path, monkeypatch, target, replacement, exc_type
):
    path = tmp_path / "plan.json"
    path.write_text("old content\n", encoding="utf-8")
    module, _, name = target.rpartition(".")
    monkeypatch.setattr(getattr(files, module) if module else files, name, replacement)
    with pytest.raises(exc_type):
        atomic_write_text(path, "new content that will not arrive\n" * 1000)
    monkeypatch.undo()
    assert path.read_text(encoding="utf-8") == "old content\n"
    assert [p.name for p in tmp_path.iterdir()] == ["plan.json"]


def test_a_failed_first_write_leaves_no_file(tmp_path, monkeypatch):
    monkeypatch.setattr(files, "_write_all", _disk_full_after_half)
    with pytest.raises(OSError):
        atomic_write_bytes(tmp_path / "new.json", b"x" * 10_000)
    assert list(tmp_path.iterdir()) == []


def test_content_is_replaced_exactly(tmp_path):
    path = tmp_path / "a.txt"
    data = bytes(range(256)) * 4000  # 1 MB, every byte value, no newline translation
    assert atomic_write_bytes(path, data) == path
    assert path.read_bytes() == data
    atomic_write_text(path, "ζ = 6 mm\r\n")
    assert path.read_bytes() == "ζ = 6 mm\r\n".encode()


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX permission bits")
def test_permissions_are_those_of_a_plain_write(tmp_path):
    plain = tmp_path / "plain.txt"
    plain.write_text("x")  # the mode a new file gets (0o666 minus the umask)
    new = atomic_write_text(tmp_path / "new.txt", "x")
    assert stat.S_IMODE(new.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode)
    os.chmod(new, 0o640)  # an existing file keeps its mode
    atomic_write_text(new, "y")
    assert stat.S_IMODE(new.stat().st_mode) == 0o640


@pytest.mark.skipif(sys.platform == "win32", reason="symbolic links need privileges on Windows")
def test_a_symbolic_link_is_followed(tmp_path):
    real = tmp_path / "real.json"
    real.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    atomic_write_text(link, "new")
    assert link.is_symlink() and real.read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "real.json"]
