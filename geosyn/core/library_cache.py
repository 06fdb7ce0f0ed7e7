"""The disk cache of compiled shared libraries, below `geosyn.core.codegen`.

One library per key: the key is the sha256 of the C source, the compiler, its flags and
(for a recipe) the recipe's key; the file is ``<name>_<first 24 hex of the key>.so``. A
cached library is used only if its sha256 (`geosyn.core.library_digest`) and the keys
compiled into it match; a damaged or swapped file is rebuilt, with a warning. Files
appear atomically (built in a temporary folder beside them, then ``os.replace``), so
concurrent processes never load a half-written library; and one process compiles a given
library at a time (an exclusive lock on ``<stem>.lock`` beside it,
`geosyn.core.cache_folder.cache_lock`), so the
workers of a sweep on a cold cache compile it once and the others load it.

The public entry points are `geosyn.core.codegen`'s; these are its parts.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path

import casadi as ca

from geosyn.core import GeosynError, library_digest
from geosyn.core.cache_folder import TMP_PREFIX as _TMP_PREFIX
from geosyn.core.cache_folder import cache_lock

__all__ = [
    "LIBRARY_FORMAT",
    "CodegenError",
    "build_cached",
    "cached_library",
    "find_compiler",
    "library_key",
    "load_function",
    "require_compiler",
    "run_compiler",
    "warn_rebuild",
]

LIBRARY_FORMAT = "geosyn-library-v2"
"""Salt of the library keys, bumped when what a library carries changes (v2: its keys),
so older files are never looked up (no warning about them; clear_cache removes them)."""


class CodegenError(GeosynError):
    """Generating, compiling or loading C code for a CasADi function failed.

    Attributes:
        command: the compiler command line, if the compiler was run.
        returncode: the compiler's exit status, if it ran to completion.
        stderr: the compiler's error output, if any.
    """

    def __init__(
        self,
        message: str,
        command: Sequence[str] | None = None,
        returncode: int | None = None,
        stderr: str | None = None,
    ) -> None:
        super().__init__(message)
        self.command = list(command) if command is not None else None
        self.returncode = returncode
        self.stderr = stderr


def find_compiler() -> str | None:
    """Path of the C compiler to use: ``gcc`` on ``PATH``, else ``cc``, else None."""
    return shutil.which("gcc") or shutil.which("cc")


def require_compiler(compiler: str | None) -> str:
    """``compiler`` or :func:`find_compiler`'s, else raise `CodegenError`."""
    cc = compiler if compiler is not None else find_compiler()
    if cc is None:
        raise CodegenError(
            "no C compiler found: neither 'gcc' nor 'cc' is on PATH "
            f"(PATH={os.environ.get('PATH', '')!r}); install gcc or pass compiler="
        )
    return cc


def run_compiler(compiler: str, flags: Sequence[str], source: Path, output: Path) -> None:
    """Compile the C file ``source`` into the shared library ``output`` (``-lm`` linked).

    Raises:
        CodegenError: the compiler could not run, failed, or wrote no ``output``.
    """
    command = [compiler, *flags, "-shared", "-fPIC", "-o", str(output), str(source), "-lm"]
    try:
        done = subprocess.run(command, capture_output=True, text=True, check=False)
    except OSError as err:
        raise CodegenError(
            f"could not run the C compiler {compiler!r}: {err}", command=command
        ) from err
    if done.returncode != 0 or not output.is_file():
        raise CodegenError(
            f"the C compiler {compiler!r} failed with exit status {done.returncode} on "
            f"{source.name}:\n{done.stderr.strip()[-2000:]}",
            command=command,
            returncode=done.returncode,
            stderr=done.stderr,
        )


def load_function(name: str, path: Path) -> ca.Function:
    """The function ``name`` of the library at ``path`` (``casadi.external``).

    Raises:
        CodegenError: the library or the function could not be loaded.
    """
    try:
        return ca.external(name, str(path))
    except RuntimeError as err:
        raise CodegenError(f"could not load compiled function {name!r} from {path}: {err}") from err


def library_key(source: str, cc: str, flags: Sequence[str], recipe_key: str | None) -> str:
    """64 hex digits: the key of a library (its file name holds the first 24)."""
    parts = [LIBRARY_FORMAT, source, cc, *flags]
    parts += [recipe_key] if recipe_key is not None else []
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()


def warn_rebuild(what: str, problem: str) -> None:
    """Warn once per event that the cached ``what`` is damaged and is being rebuilt
    (``stacklevel`` points at the caller of the public `geosyn.core.codegen` function)."""
    warnings.warn(
        f"compiled-code cache: {what} is damaged ({problem}); discarding it and recompiling",
        RuntimeWarning,
        stacklevel=4,
    )


def build_cached(
    name: str,
    source: str,
    load: Sequence[str],
    cache_dir: Path,
    flags: tuple[str, ...],
    compiler: str | None,
    recipe_key: str | None = None,
) -> dict[str, ca.Function]:
    """Compile ``source`` into ``<name>_<key>.so`` unless cached; load the names ``load``.

    The library carries its key and ``recipe_key`` (`library_digest.tagged_source`); a
    cached one is loaded only if its digest and both keys match.
    """
    library, checked = cached_library(name, source, cache_dir, flags, compiler, recipe_key)
    if checked:
        try:
            return {n: load_function(n, library) for n in load}
        except CodegenError as err:  # verified bytes that dlopen refuses: build anew
            warn_rebuild(library.name, str(err))
            library, _ = cached_library(name, source, cache_dir, flags, compiler,
                                         recipe_key, rebuild=True)  # fmt: skip
    return {n: load_function(n, library) for n in load}


def cached_library(
    name: str,
    source: str,
    cache_dir: Path,
    flags: tuple[str, ...],
    compiler: str | None,
    recipe_key: str | None,
    rebuild: bool = False,
) -> tuple[Path, bool]:
    """(``<name>_<key>.so``, whether it was a verified cache hit): compiled unless a
    cached library passes its digest and key checks (``rebuild``: compiled anyway). The
    compile holds `cache_lock`; a library another process finished meanwhile is a hit."""
    cc = require_compiler(compiler)
    key = library_key(source, cc, flags, recipe_key)
    stem = f"{name}_{key[:24]}"
    library = cache_dir / f"{stem}.so"
    if library.is_file() and not rebuild:
        damage = library_digest.damage(library, key, recipe_key)
        if damage is None:
            return library, True
        # A damaged or foreign file (a full disk, a killed copy, a bit flip, a copy under
        # another name): never dlopen it, build anew.
        warn_rebuild(library.name, damage)
    try:
        cache_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise CodegenError(f"cannot create the codegen cache folder {cache_dir}: {err}") from err
    with cache_lock(cache_dir / f"{stem}.lock"):
        if not rebuild and library.is_file():
            if library_digest.damage(library, key, recipe_key) is None:
                return library, True  # built by another process while this one waited
        _compile_into(cache_dir, stem, library, cc, flags, source, key, recipe_key)
    return library, False


def _compile_into(
    cache_dir: Path,
    stem: str,
    library: Path,
    cc: str,
    flags: tuple[str, ...],
    source: str,
    key: str,
    recipe_key: str | None,
) -> None:
    """Compile ``source`` (tagged with its keys) into ``library``, with its ``.c`` and
    digest beside it, each appearing by an atomic rename."""
    try:
        work = Path(tempfile.mkdtemp(prefix=_TMP_PREFIX, dir=cache_dir))
    except OSError as err:
        raise CodegenError(f"cannot create the codegen cache folder {cache_dir}: {err}") from err
    try:
        c_file = work / f"{stem}.c"
        c_file.write_text(library_digest.tagged_source(source, key, recipe_key))
        built = work / f"{stem}.so"
        run_compiler(cc, flags, c_file, built)
        digest = work / f"{stem}.so{library_digest.DIGEST_SUFFIX}"
        digest.write_text(library_digest.sha256_hex(built.read_bytes()) + "\n")
        # Same folder, so os.replace is an atomic rename: readers see all or nothing. The
        # digest goes first: a reader that pairs it with an older library rebuilds (safe).
        os.replace(c_file, cache_dir / c_file.name)
        os.replace(digest, library_digest.digest_path(library))
        os.replace(built, library)
    finally:
        shutil.rmtree(work, ignore_errors=True)
