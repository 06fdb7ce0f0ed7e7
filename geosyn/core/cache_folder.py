"""Where the compiled-code cache lives (`geosyn.core.codegen`), and emptying it.

Cache location, first that applies: a ``cache_dir`` argument, ``$GEOSYN_CACHE_DIR/codegen``,
``$XDG_CACHE_HOME/geosyn/codegen``, ``~/.cache/geosyn/codegen``.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

__all__ = ["TMP_PREFIX", "clear_cache", "default_cache_dir", "resolve_cache_dir"]

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
