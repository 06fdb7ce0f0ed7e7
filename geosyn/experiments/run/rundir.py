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

A writer runs into ``<parent>/.<name>.partial-<id>`` while it holds the lock, so a partial
directory whose lock nobody holds was left by a dead writer (``kill -9``, power loss):
`claim` removes those of its own ``out`` and of every other name in its folder whose lock
is free, and ``geosyn clean`` (`clean`) those under a folder. A cleaner holds a free lock
for milliseconds; a writer that finds a lock held waits up to `LOCK_PATIENCE` before it
concludes that a live writer holds it.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import shutil
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

from geosyn.experiments.errors import OutputNotWritable, RunDirectoryExists

#: Error numbers that mean "the output cannot be written here" (disk full, read-only, ...).
WRITE_ERRNOS = frozenset(
    {errno.ENOSPC, errno.EROFS, errno.EACCES, errno.EPERM, errno.EDQUOT, errno.EFBIG}
)


#: How long a writer retries a held lock before it reports the holder [s]: longer than a
#: cleaner holds a dead writer's lock, far shorter than any run.
LOCK_PATIENCE = 0.5

_PARTIAL = re.compile(r"^\.(?P<name>.+)\.partial-[0-9a-f]+$")


def lock_path(out: Path) -> Path:
    """The lock file of the run or sweep directory ``out``."""
    return out.parent / f".{out.name}.lock"


def _holder(fd: int) -> str:
    try:
        text = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
    except OSError:
        return "?"
    return text or "?"


def acquire(out: Path, patience: float = LOCK_PATIENCE) -> int:
    """Take the lock of ``out``, retrying a held lock for ``patience`` seconds; returns its
    file descriptor.

    Raises:
        RunDirectoryExists: another live process holds it.
        OutputNotWritable: the lock file cannot be created (read-only, disk full, ...).
    """
    path = lock_path(out)
    give_up = time.monotonic() + patience
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
            if time.monotonic() < give_up:  # perhaps a cleaner, holding it for a moment
                time.sleep(0.02)
                continue
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
    """True if a live process holds the lock of ``out`` (taken and released if free)."""
    try:
        fd = acquire(out, patience=0.0)
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
        remove_dead_partials(out.parent, own=out)
        yield
    finally:
        release(out, fd)


def _partials(folder: Path, name: str) -> list[Path]:
    return sorted(p for p in folder.glob(f".{glob_escape(name)}.partial-*") if p.is_dir())


def glob_escape(name: str) -> str:
    """``name`` with the glob metacharacters ``*?[`` taken literally."""
    return re.sub(r"([*?\[])", r"[\1]", name)


def remove_dead_partials(folder: Path, own: Path | None = None) -> list[Path]:
    """Remove the partial directories in ``folder`` whose writer is dead.

    Args:
        folder: the folder to clean (not recursive).
        own: a run directory in ``folder`` whose lock the caller holds: its partial
            directories are removed without taking the lock.

    Returns:
        The directories removed, and the dead writers' lock files (a partial that cannot be
        removed is skipped).
    """
    names = {m["name"] for p in _safe_iterdir(folder) if (m := _PARTIAL.match(p.name))}
    removed: list[Path] = []
    for name in sorted(names):
        out = folder / name
        if own is not None and out == own:
            removed += _rmtree_all(_partials(folder, name))
            continue
        stale_lock = lock_path(out).exists()
        try:
            fd = acquire(out, patience=0.0)
        except (RunDirectoryExists, OutputNotWritable):
            continue  # a live writer (or a folder we may not write): leave it
        try:
            removed += _rmtree_all(_partials(folder, name))
        finally:
            release(out, fd)  # removes the dead writer's lock file too
        removed += [lock_path(out)] if stale_lock else []
    return removed


def clean(folder: Path) -> tuple[list[Path], list[Path]]:
    """Remove, under ``folder`` (recursively), the partial directories of dead writers and
    the lock files nobody holds (``geosyn clean``).

    Returns:
        ``(removed, kept)``: the partial directories and lock files removed, and the
        partial directories kept because a live process is writing them.
    """
    removed: list[Path] = []
    folders = {p.parent for p in folder.rglob(".*.partial-*") if _PARTIAL.match(p.name)}
    for sub in sorted(folders):
        removed += remove_dead_partials(sub)
    for lock in sorted(folder.rglob(".*.lock")):
        out = lock.with_name(lock.name[1 : -len(".lock")])
        if lock.is_file() and not is_locked(out):  # taking and releasing it removes it
            removed.append(lock)
    kept = sorted(p for p in folder.rglob(".*.partial-*") if _PARTIAL.match(p.name))
    return removed, kept


def _safe_iterdir(folder: Path) -> list[Path]:
    try:
        return list(folder.iterdir())
    except OSError:
        return []


def _rmtree_all(paths: list[Path]) -> list[Path]:
    for path in paths:
        shutil.rmtree(path, ignore_errors=True)
    return [p for p in paths if not p.exists()]


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


__all__ = [
    "LOCK_PATIENCE",
    "WRITE_ERRNOS",
    "acquire",
    "claim",
    "clean",
    "commit",
    "glob_escape",
    "is_locked",
    "lock_path",
    "release",
    "remove_dead_partials",
]
