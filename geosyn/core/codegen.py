"""C code generation for CasADi functions, with a disk cache of compiled libraries.

:func:`compile_function` turns a ``casadi.Function`` into C with CasADi's code
generator, compiles it into a shared library and loads it back with
``casadi.external``. Libraries are cached on disk under a name that contains the sha256
of the generated C source (and of the compiler command), so the same function is
compiled once per machine, whichever process asks first; files appear atomically
(written under a temporary name, then ``os.replace``), so concurrent processes never
load a half-written library. :func:`compile_library` compiles several functions into one
library through the same cache (e.g. a function with hand-made derivatives).
:func:`compile_recipe` finds such a library from a caller's description of it (a
recipe) instead of its source, so a cache hit builds no symbolic graph at all.

Cache location, first that applies: the ``cache_dir`` argument,
``$GEOSYN_CACHE_DIR/codegen``, ``$XDG_CACHE_HOME/geosyn/codegen``,
``~/.cache/geosyn/codegen``. :func:`clear_cache` empties it.

Calling a compiled function from Python with numpy arrays: `geosyn.core.calls`.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import casadi as ca

from geosyn.core import GeosynError, InvalidArgument, library_digest

__all__ = [
    "CodegenError",
    "clear_cache",
    "compile_function",
    "compile_library",
    "compile_recipe",
    "default_cache_dir",
    "find_compiler",
]

DEFAULT_FLAGS: tuple[str, ...] = ("-O2",)
"""Optimisation flags given to the compiler (``-shared -fPIC`` are always added)."""
LARGE_SOURCE_FLAGS: tuple[str, ...] = ("-O1",)
"""Flags of :func:`compile_library` for long sources: megabytes of straight-line code
(e.g. the Jacobian of an RK4 step) take far longer to compile at ``-O2`` for little gain."""
LARGE_SOURCE_CHARS = 500_000
"""Source length [characters] from which :func:`compile_library` uses LARGE_SOURCE_FLAGS."""
_C_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")

# <function name>_<24 hex digits of the key>.<so|c|recipe|so.sha256>; clear_cache deletes
# only these.
_CACHED_FILE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*_[0-9a-f]{24}\.(so|c|recipe|so\.sha256)$")
_TMP_PREFIX = ".tmp-geosyn-"
# Temporary folders clear_cache removes: this module's, and those of the MPC's former
# private copy of this cache (left behind by a compile killed midway).
_TMP_PREFIXES = (_TMP_PREFIX, "geosyn-mpc-")


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


def find_compiler() -> str | None:
    """Path of the C compiler to use: ``gcc`` on ``PATH``, else ``cc``, else None."""
    return shutil.which("gcc") or shutil.which("cc")


def _resolve_cache_dir(cache_dir: str | os.PathLike[str] | None) -> Path:
    return Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()


def _generate_source(name: str, functions: Sequence[ca.Function]) -> str:
    """C source of ``functions`` in one file named after ``name``."""
    try:
        gen = ca.CodeGenerator(f"{name}.c", {"with_header": False})
        for fun in functions:
            gen.add(fun)
        return gen.dump()
    except RuntimeError as err:
        names = ", ".join(repr(f.name()) for f in functions)
        raise CodegenError(f"CasADi could not generate C code for function {names}: {err}") from err


def _compile(compiler: str, flags: Sequence[str], source: Path, output: Path) -> None:
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


def _load(name: str, path: Path) -> ca.Function:
    try:
        return ca.external(name, str(path))
    except RuntimeError as err:
        raise CodegenError(f"could not load compiled function {name!r} from {path}: {err}") from err


def compile_function(
    fun: ca.Function,
    cache_dir: str | os.PathLike[str] | None = None,
    *,
    flags: Sequence[str] = DEFAULT_FLAGS,
    compiler: str | None = None,
    fallback: bool = False,
) -> ca.Function:
    """Compile a CasADi function to C and load it back, reusing the disk cache.

    Allocates and may take seconds (the compiler runs) on a cache miss; a cache hit only
    generates the C source to hash it and loads the library (milliseconds).

    Args:
        fun: the function to compile (SX or MX based); its name must be a C identifier.
        cache_dir: folder of the compiled libraries; default :func:`default_cache_dir`.
            Created if missing.
        flags: compiler flags besides ``-shared -fPIC``, e.g. ``("-O3",)``. Part of the
            cache key.
        compiler: C compiler executable; default :func:`find_compiler`.
        fallback: if True, a missing or failing compiler is reported with a
            ``RuntimeWarning`` and ``fun`` itself is returned uncompiled, instead of
            raising.

    Returns:
        A ``casadi.Function`` with the same name, inputs and outputs as ``fun``, that
        evaluates the compiled code (or ``fun`` itself when falling back).

    Raises:
        InvalidArgument: ``fun`` is not a ``casadi.Function`` or its name is not a C
            identifier.
        CodegenError: no compiler, compilation or loading failed (unless ``fallback``).
    """
    if not isinstance(fun, ca.Function):
        raise InvalidArgument(f"fun: expected a casadi.Function, got {type(fun).__name__}")
    name = fun.name()
    if not _C_IDENTIFIER.fullmatch(name):
        raise InvalidArgument(
            f"fun: name {name!r} is not a C identifier; rename the casadi.Function"
        )
    try:
        return _compile_cached(fun, _resolve_cache_dir(cache_dir), tuple(flags), compiler)
    except CodegenError as err:
        if not fallback:
            raise
        warnings.warn(
            f"compile_function: falling back to the uncompiled function {name!r}: {err}",
            RuntimeWarning,
            stacklevel=2,
        )
        return fun


def _compile_cached(
    fun: ca.Function, cache_dir: Path, flags: tuple[str, ...], compiler: str | None
) -> ca.Function:
    name = fun.name()
    source = _generate_source(name, [fun])
    return _build_cached(name, source, [name], cache_dir, flags, compiler)[name]


def _library_stem(name: str, source: str, cc: str, flags: Sequence[str]) -> str:
    """``<name>_<24 hex>``: the cache file name (without suffix) of a compiled source."""
    key = hashlib.sha256("\0".join([source, cc, *flags]).encode()).hexdigest()[:24]
    return f"{name}_{key}"


def _build_cached(
    name: str,
    source: str,
    load: Sequence[str],
    cache_dir: Path,
    flags: tuple[str, ...],
    compiler: str | None,
) -> dict[str, ca.Function]:
    """Compile ``source`` into ``<name>_<key>.so`` unless cached; load the names ``load``."""
    cc = compiler if compiler is not None else find_compiler()
    if cc is None:
        raise CodegenError(
            "no C compiler found: neither 'gcc' nor 'cc' is on PATH "
            f"(PATH={os.environ.get('PATH', '')!r}); install gcc or pass compiler="
        )
    stem = _library_stem(name, source, cc, flags)
    library = cache_dir / f"{stem}.so"
    if library.is_file():
        damage = library_digest.damage(library)
        if damage is None:
            try:
                return {n: _load(n, library) for n in load}
            except CodegenError as err:
                damage = str(err)
        # A damaged file (a full disk, a killed copy, a bit flip): never dlopen it, build anew.
        warnings.warn(
            f"compiled-code cache: {library.name} is damaged ({damage}); recompiling it",
            RuntimeWarning,
            stacklevel=4,
        )
    try:
        cache_dir.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=_TMP_PREFIX, dir=cache_dir))
    except OSError as err:
        raise CodegenError(f"cannot create the codegen cache folder {cache_dir}: {err}") from err
    try:
        c_file = work / f"{stem}.c"
        c_file.write_text(source)
        built = work / f"{stem}.so"
        _compile(cc, flags, c_file, built)
        digest = work / f"{stem}.so{library_digest.DIGEST_SUFFIX}"
        digest.write_text(library_digest.sha256_hex(built.read_bytes()) + "\n")
        # Same folder, so os.replace is an atomic rename: readers see all or nothing. The
        # digest goes first: a reader that pairs it with an older library rebuilds (safe).
        os.replace(c_file, cache_dir / c_file.name)
        os.replace(digest, library_digest.digest_path(library))
        os.replace(built, library)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return {n: _load(n, library) for n in load}


def compile_library(
    name: str,
    functions: Sequence[ca.Function],
    cache_dir: str | os.PathLike[str] | None = None,
    *,
    load: Sequence[str] | None = None,
    flags: Sequence[str] | None = None,
    compiler: str | None = None,
) -> dict[str, ca.Function]:
    """Compile several CasADi functions into one library and load some of them back.

    Functions of one library see each other by name: ``casadi.external`` takes
    ``jac_<f>`` from the same library as the Jacobian of ``f`` and ``jac_jac_<f>`` as
    the Jacobian of that Jacobian, so a library can carry hand-made derivatives (e.g. a
    structurally zero second derivative, for Gauss-Newton Hessians). The library goes
    through the same disk cache as :func:`compile_function` (file
    ``<name>_<24 hex>.so``, removed by :func:`clear_cache`).

    Allocates and may take minutes (the compiler runs) on a cache miss; a cache hit only
    generates the C source to hash it and loads the library.

    Args:
        name: library name, a C identifier (the cache file starts with it).
        functions: the functions to compile, each named by a C identifier.
        cache_dir: folder of the compiled libraries; default :func:`default_cache_dir`.
        load: names of the functions to load back; default all of ``functions``.
        flags: compiler flags besides ``-shared -fPIC`` (part of the cache key); None for
            :data:`DEFAULT_FLAGS`, or :data:`LARGE_SOURCE_FLAGS` when the generated source
            has at least :data:`LARGE_SOURCE_CHARS` characters.
        compiler: C compiler executable; default :func:`find_compiler`.

    Returns:
        ``{function name: casadi.Function}`` for the names in ``load``, evaluating the
        compiled code.

    Raises:
        InvalidArgument: a name is not a C identifier, ``functions`` is empty or holds
            something else than ``casadi.Function``, or ``load`` names a function that is
            not in ``functions``.
        CodegenError: no compiler, compilation or loading failed.
    """
    if not isinstance(name, str) or not _C_IDENTIFIER.fullmatch(name):
        raise InvalidArgument(f"name: {name!r} is not a C identifier")
    funs = list(functions)
    if not funs or not all(isinstance(f, ca.Function) for f in funs):
        raise InvalidArgument(
            f"functions: expected a non-empty sequence of casadi.Function, got {functions!r}"
        )
    names = [f.name() for f in funs]
    bad = [n for n in names if not _C_IDENTIFIER.fullmatch(n)]
    if bad:
        raise InvalidArgument(f"functions: names {bad} are not C identifiers")
    wanted = names if load is None else list(load)
    unknown = sorted(set(wanted) - set(names))
    if unknown:
        raise InvalidArgument(f"load: {unknown} are not among the functions {names}")
    source = _generate_source(name, funs)
    if flags is None:
        flags = LARGE_SOURCE_FLAGS if len(source) >= LARGE_SOURCE_CHARS else DEFAULT_FLAGS
    return _build_cached(
        name, source, wanted, _resolve_cache_dir(cache_dir), tuple(flags), compiler
    )


def compile_recipe(
    name: str,
    recipe: str,
    make_functions: Callable[[], Sequence[ca.Function]],
    cache_dir: str | os.PathLike[str] | None = None,
    *,
    load: Sequence[str],
    flags: Sequence[str] | None = None,
    compiler: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, ca.Function]:
    """:func:`compile_library` keyed by a recipe: a cache hit builds no CasADi graph.

    Building large symbolic functions (e.g. the Jacobian of an RK4 step on the ABA) and
    generating their C source takes seconds even when the library is cached, because the
    library's key is the hash of that source. Here the caller names everything the
    functions depend on in ``recipe`` (a model description, the settings, a digest of the
    code that builds them); a small index file ``<name>_<24 hex>.recipe`` maps the
    recipe's hash to the library, and a hit only loads the library (milliseconds). On a
    miss ``make_functions`` builds the functions, :func:`compile_library`'s cache compiles
    them (or finds them compiled), and the index is written atomically afterwards, so
    concurrent processes only ever see a complete index pointing at a complete library.

    Args:
        name: library name, a C identifier.
        recipe: text determining the functions completely; a different text, a new key.
        make_functions: builds the functions (called on a miss only).
        cache_dir: folder of the compiled libraries; default :func:`default_cache_dir`.
        load: names of the functions to load back.
        flags: as for :func:`compile_library` (part of the key).
        compiler: C compiler executable; default :func:`find_compiler`.
        progress: called with a line of text before and after each slow step of a miss
            (building the graph, compiling); None reports nothing.

    Returns:
        ``{function name: casadi.Function}`` for the names in ``load``.

    Raises:
        InvalidArgument: ``name`` is not a C identifier, or ``load`` names a function
            that ``make_functions`` did not build.
        CodegenError: no compiler, compilation or loading failed.
    """
    if not isinstance(name, str) or not _C_IDENTIFIER.fullmatch(name):
        raise InvalidArgument(f"name: {name!r} is not a C identifier")
    cc = compiler if compiler is not None else find_compiler()
    if cc is None:
        raise CodegenError(
            "no C compiler found: neither 'gcc' nor 'cc' is on PATH "
            f"(PATH={os.environ.get('PATH', '')!r}); install gcc or pass compiler="
        )
    folder = _resolve_cache_dir(cache_dir)
    extra = () if flags is None else tuple(flags)
    index_key = hashlib.sha256("\0".join([recipe, cc, *extra]).encode()).hexdigest()[:24]
    index = folder / f"{name}_{index_key}.recipe"
    stem = index.read_text().strip() if index.is_file() else ""
    library = folder / f"{stem}.so"
    if (
        re.fullmatch(rf"{re.escape(name)}_[0-9a-f]{{24}}", stem)
        and library.is_file()
        and library_digest.damage(library) is None  # else rebuilt below (never dlopen it)
    ):
        try:
            return {n: _load(n, library) for n in load}
        except CodegenError as err:  # damaged: rebuild below
            warnings.warn(f"{err}; rebuilding it", RuntimeWarning, stacklevel=2)
    report = progress if progress is not None else (lambda _line: None)
    start = time.perf_counter()
    report(f"{name}: building the symbolic functions (first use; cached afterwards)")
    funs = list(make_functions())
    source = _generate_source(name, funs)
    used = tuple(flags) if flags is not None else None
    if used is None:
        used = LARGE_SOURCE_FLAGS if len(source) >= LARGE_SOURCE_CHARS else DEFAULT_FLAGS
    report(
        f"{name}: {time.perf_counter() - start:.1f} s; compiling {len(source) / 1e6:.1f} MB "
        f"of C with {' '.join(used)} (skipped if already compiled)"
    )
    names = [f.name() for f in funs]
    unknown = sorted(set(load) - set(names))
    if unknown:
        raise InvalidArgument(f"load: {unknown} are not among the functions {names}")
    result = _build_cached(name, source, list(load), folder, used, cc)
    try:  # the index appears atomically, after the library it names
        fd, tmp = tempfile.mkstemp(prefix=_TMP_PREFIX, dir=folder)
        os.chmod(tmp, 0o644)  # like the library it names (mkstemp makes it private)
        with os.fdopen(fd, "w") as fh:
            fh.write(_library_stem(name, source, cc, used) + "\n")
        os.replace(tmp, index)
    except OSError as err:
        warnings.warn(f"could not write the recipe index {index}: {err}", RuntimeWarning, 2)
    report(f"{name}: ready in {time.perf_counter() - start:.1f} s")
    return result


def clear_cache(cache_dir: str | os.PathLike[str] | None = None) -> int:
    """Delete the compiled libraries and sources of the codegen cache.

    Only files this module writes (``<name>_<24 hex>.so`` / ``.c`` and its temporary
    folders) are removed, so pointing ``cache_dir`` at a shared folder is safe. Libraries
    already loaded by a running process stay usable.

    Args:
        cache_dir: the cache folder; default :func:`default_cache_dir`.

    Returns:
        Number of files and temporary folders removed.
    """
    folder = _resolve_cache_dir(cache_dir)
    if not folder.is_dir():
        return 0
    removed = 0
    for entry in folder.iterdir():
        if entry.is_file() and _CACHED_FILE.match(entry.name):
            entry.unlink(missing_ok=True)
            removed += 1
        elif entry.is_dir() and entry.name.startswith(_TMP_PREFIXES):
            shutil.rmtree(entry, ignore_errors=True)
            removed += 1
    return removed
