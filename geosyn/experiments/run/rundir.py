"""Claiming a run directory: one writer at a time, never a silent replacement.

A writer holds an exclusive ``flock`` on ``<parent>/.<name>.lock`` (its pid inside) from
before it looks at ``<parent>/<name>`` until it has committed it. The kernel drops the lock
when the process ends, however it ends (``kill -9`` included), so a stale lock file never
blocks anyone; a live holder makes every other writer fail at once with
`RunDirectoryExists` naming its pid. ``--force`` replaces only a directory nobody holds:
the old directory is moved aside, the new one renamed into place, then the old one
removed, so a crash in between loses neither.

The lock file is removed on release. A writer that locked a lock file another one had just
removed (and replaced) notices by the inode and locks the new file instead.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
import uuid
from collections.abc import Iterator
from pathlib import Path

from geosyn.experiments.errors import OutputNotWritable, RunDirectoryExists

#: Error numbers that mean "the output cannot be written here" (disk full, read-only, ...).
WRITE_ERRNOS = frozenset(
    {errno.ENOSPC, errno.EROFS, errno.EACCES, errno.EPERM, errno.EDQUOT, errno.EFBIG}
)


def lock_path(out: Path) -> Path:
    """The lock file of the run or sweep directory ``out``."""
    return out.parent / f".{out.name}.lock"


def _holder(fd: int) -> str:
    try:
        text = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
    except OSError:
        return "?"
    return text or "?"


def acquire(out: Path) -> int:
    """Take the lock of ``out`` without waiting; returns its file descriptor.

    Raises:
        RunDirectoryExists: another live process holds it.
        OutputNotWritable: the lock file cannot be created (read-only, disk full, ...).
    """
    path = lock_path(out)
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as err:
            raise OutputNotWritable(out, err) from err
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise RunDirectoryExists(
                out,
                f"is being written by another process (pid {holder}); wait for it or choose"
                " another --out (--force never replaces a directory being written)",
            ) from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # the previous holder removed this file on release: lock the new one
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    except OSError:
        pass  # the pid is only informative; the lock itself is held
    return fd


def release(out: Path, fd: int) -> None:
    """Remove the lock file of ``out`` and drop the lock (in this order)."""
    with contextlib.suppress(OSError):
        os.unlink(lock_path(out))
    os.close(fd)


def is_locked(out: Path) -> bool:
    """True if a live process holds the lock of ``out`` (without taking it)."""
    try:
        fd = acquire(out)
    except RunDirectoryExists:
        return True
    except OutputNotWritable:
        return False
    release(out, fd)
    return False


@contextlib.contextmanager
def claim(out: Path, force: bool) -> Iterator[None]:
    """Hold the lock of ``out`` and check that it may be written.

    Raises:
        RunDirectoryExists: another process writes ``out``; ``out`` exists and ``force``
            is False; ``out`` is a file (never replaced, even with ``force``).
        OutputNotWritable: the parent folder cannot be created or written.
    """
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise RunDirectoryExists(
                    out, f"is inside {str(parent)!r}, a file, not a folder; choose another --out"
                )
            break
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputNotWritable(out, err) from err
    fd = acquire(out)
    try:
        if out.exists() and not out.is_dir():
            raise RunDirectoryExists(
                out, "is a file, not a directory; choose another --out (it is never replaced)"
            )
        if out.exists() and not force:
            raise RunDirectoryExists(
                out, "already exists; choose another --out or pass --force to replace it"
            )
        yield
    finally:
        release(out, fd)


def commit(tmp: Path, out: Path) -> None:
    """Move the finished ``tmp`` to ``out`` (under `claim`); an old ``out`` is replaced.

    The old directory is renamed aside first and removed only after the new one is in
    place, so a crash between the two renames leaves the old results (``.<name>.replaced-*``).
    """
    old = None
    if out.exists():
        old = out.parent / f".{out.name}.replaced-{uuid.uuid4().hex[:8]}"
        os.replace(out, old)
    os.replace(tmp, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


__all__ = ["WRITE_ERRNOS", "acquire", "claim", "commit", "is_locked", "lock_path", "release"]
