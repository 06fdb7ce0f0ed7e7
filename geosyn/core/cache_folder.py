"""Where the compiled-code cache lives (`geosyn.core.codegen`), emptying it, the lock
every disk cache of geosyn takes to make an entry once (`cache_lock`, `fill_once`), and
how a JSON entry is written so that no process reads it half-written (`store_json`).

Cache location, first that applies: a ``cache_dir`` argument, ``$GEOSYN_CACHE_DIR/codegen``,
``$XDG_CACHE_HOME/geosyn/codegen``, ``~/.cache/geosyn/codegen``.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

__all__ = [
    "LOCK_WAIT",
    "TMP_PREFIX",
    "cache_lock",
    "clear_cache",
    "default_cache_dir",
    "fill_once",
    "read_json",
    "resolve_cache_dir",
    "store_json",
]

T = TypeVar("T")

# <function name>_<24 hex digits of the key>.<so|c|recipe|so.sha256|lock>; clear_cache
# deletes only these.
_CACHED_FILE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*_[0-9a-f]{24}\.(so|c|recipe|so\.sha256|lock)$")
TMP_PREFIX = ".tmp-geosyn-"
# Temporary folders clear_cache removes: this module's, and those of the MPC's former
# private copy of this cache (left behind by a compile killed midway).
TMP_PREFIXES = (TMP_PREFIX, "geosyn-mpc-")


def default_cache_dir() -> Path:
    """The cache folder used when none is given (not created here).

    Returns:
        ``$GEOSYN_CACHE_DIR/codegen`` if the variable is set, else
        ``$XDG_CACHE_HOME/geosyn/codegen``, else ``~/.cache/geosyn/codegen``.
    """
    root = os.environ.get("GEOSYN_CACHE_DIR")
    if root:
        return Path(root).expanduser() / "codegen"
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "geosyn" / "codegen"


def resolve_cache_dir(cache_dir: str | os.PathLike[str] | None) -> Path:
    """``cache_dir`` as a path, or :func:`default_cache_dir` when None."""
    return Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()


def clear_cache(cache_dir: str | os.PathLike[str] | None = None) -> int:
    """Delete the compiled libraries and sources of the codegen cache.

    Only files this module writes (``<name>_<24 hex>.so`` / ``.c`` / ``.recipe`` /
    ``.so.sha256`` / ``.lock`` and its temporary folders) are removed, so pointing ``cache_dir`` at a shared folder is safe. Libraries
    already loaded by a running process stay usable.

    Args:
        cache_dir: the cache folder; default :func:`default_cache_dir`.

    Returns:
        Number of files and temporary folders removed.
    """
    folder = resolve_cache_dir(cache_dir)
    if not folder.is_dir():
        return 0
    removed = 0
    for entry in folder.iterdir():
        if entry.is_file() and _CACHED_FILE.match(entry.name):
            entry.unlink(missing_ok=True)
            removed += 1
        elif entry.is_dir() and entry.name.startswith(TMP_PREFIXES):
            shutil.rmtree(entry, ignore_errors=True)
            removed += 1
    return removed


LOCK_WAIT = 600.0
"""Longest wait [s] for another process making the same cache entry (the largest libraries
compile in about a minute); after it this process does the work too, with a warning."""
_LOCK_POLL = 0.05  # [s] between two tries of the lock
_unlocked_warned = False  # whether working without locks was warned in this process


def _warn_unlocked(path: Path, err: BaseException) -> None:
    """Say once per process that the cache works without locks (concurrent processes
    may then do the same work; still safe)."""
    global _unlocked_warned
    if not _unlocked_warned:
        _unlocked_warned = True
        warnings.warn(
            f"cache: cannot lock {path} ({err}); concurrent processes may each compile or "
            "fit the same thing (safe, only slower)",
            RuntimeWarning,
            stacklevel=6,
        )


def _acquire(fd: int, path: Path, limit: float) -> bool:
    """Take the exclusive ``flock`` on ``fd`` within ``limit`` [s]: True if held; False
    (warned) after the wait, or on a file system without locks."""
    import fcntl

    deadline = time.monotonic() + limit
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except BlockingIOError:  # held by another process (or open file) now
            if time.monotonic() >= deadline:
                warnings.warn(
                    f"cache: another process has held {path.name} for more than "
                    f"{limit:g} s (compiling or fitting); doing the same work here",
                    RuntimeWarning,
                    stacklevel=6,
                )
                return False
            time.sleep(_LOCK_POLL)
        except OSError as err:  # a file system without locks (ENOLCK): run unlocked
            _warn_unlocked(path, err)
            return False


@contextlib.contextmanager
def cache_lock(path: Path, wait: float | None = None) -> Iterator[None]:
    """Hold an exclusive advisory lock (``flock``) on the file ``path`` for the ``with``
    block: one process makes a cache entry at a time (a compiled library,
    `geosyn.core.library_cache`; a robot's spheres; the collocation's node functions; a
    data wheel). Released when the block ends or the process dies. The file is created
    for it and removed after it (a process killed meanwhile leaves it: the caches'
    clear functions remove it).

    Waits at most ``wait`` [s] (default `LOCK_WAIT`) for another holder, then warns and
    runs the block without the lock (two processes then both do the work; the atomic
    renames keep that safe). Where the lock file cannot be opened (a read-only folder,
    no ``fcntl``) or locked (a file system without locks), the block runs without it,
    warned once per process.
    """
    try:
        import fcntl  # noqa: F401 - POSIX only

        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except (ImportError, OSError) as err:
        _warn_unlocked(path, err)
        yield
        return
    held = False
    try:
        held = _acquire(fd, path, LOCK_WAIT if wait is None else wait)
        yield
    finally:
        if held:  # remove the file if it is still this lock's (not a newer holder's)
            with contextlib.suppress(OSError):
                if os.stat(path).st_ino == os.fstat(fd).st_ino:
                    os.unlink(path)
        os.close(fd)  # releases the lock


def fill_once(lock: Path, read: Callable[[], T | None], make: Callable[[], T]) -> T:
    """A cache entry made by one process at a time: under `cache_lock` on ``lock`` (its
    folder created), ``read()`` again (another process may have made the entry while
    this one waited), else ``make()`` (which stores it). Call after a ``read`` that
    missed."""
    with contextlib.suppress(OSError):  # unwritable: unlocked, and the store says so
        lock.parent.mkdir(parents=True, exist_ok=True)
    with cache_lock(lock):
        found = read()
        return make() if found is None else found


def read_json(path: Path, parse: Callable[[Any], T], what: str, redo: str,
              stacklevel: int = 2, warn: bool = True) -> T | None:  # fmt: skip
    """``parse`` of the JSON record at ``path`` (`store_json`'s), or None: no file, or a
    damaged one (unreadable, not JSON, or refused by ``parse`` with ValueError, KeyError
    or TypeError), warned when ``warn`` as "``what``: <file> is damaged (why); ``redo``"
    at ``stacklevel`` above the caller: the caller makes the entry again."""
    if not path.is_file():
        return None
    try:
        return parse(json.loads(path.read_text()))
    except (OSError, ValueError, KeyError, TypeError) as err:
        if warn:
            warnings.warn(f"{what}: {path.name} is damaged ({err!r}); {redo}",
                          RuntimeWarning, stacklevel + 1)  # fmt: skip
        return None


def store_json(path: Path, record: Any, what: str, stacklevel: int = 2) -> None:
    """Write ``record`` (JSON-serialisable) to ``path`` atomically: to a temporary file in
    its folder (created), then renamed over it, so that a concurrent process reads the
    old entry or the new one, never a partial file. An unwritable cache is warned (as
    ``what``, e.g. "the sphere cache", at ``stacklevel`` above the caller), not raised:
    it only costs the entry's making next time."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}_", suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            json.dump(record, f)
        os.replace(tmp, path)
    except OSError as err:
        warnings.warn(f"could not write {what} {path}: {err}", RuntimeWarning, stacklevel + 1)
