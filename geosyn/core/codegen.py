"""C code generation for CasADi functions, with a disk cache of compiled libraries.

:func:`compile_function` turns a ``casadi.Function`` into C with CasADi's code
generator, compiles it into a shared library and loads it back with
``casadi.external``. Libraries are cached on disk under a name that contains the sha256
of the generated C source (and of the compiler command), so the same function is
compiled once per machine, whichever process asks first; each library carries that key
(and its recipe's) compiled in, and is checked against its sha256 and its key before it is
loaded (`geosyn.core.library_digest`), so a damaged or swapped file is rebuilt, with a
warning, never used; files appear atomically
(written under a temporary name, then ``os.replace``), so concurrent processes never
load a half-written library. :func:`compile_library` compiles several functions into one
library through the same cache (e.g. a function with hand-made derivatives).
:func:`compile_recipe` finds such a library from a caller's description of it (a
recipe) instead of its source, so a cache hit builds no symbolic graph at all.

Cache location, first that applies: the ``cache_dir`` argument,
``$GEOSYN_CACHE_DIR/codegen``, ``$XDG_CACHE_HOME/geosyn/codegen``,
``~/.cache/geosyn/codegen``. :func:`clear_cache` empties it.

The cache's keys, checks and atomic writes: `geosyn.core.library_cache`. Calling a
compiled function from Python with numpy arrays: `geosyn.core.calls`.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import casadi as ca

from geosyn.core import InvalidArgument, library_digest
from geosyn.core.cache_folder import TMP_PREFIX as _TMP_PREFIX
from geosyn.core.cache_folder import clear_cache, default_cache_dir
from geosyn.core.cache_folder import resolve_cache_dir as _resolve_cache_dir
from geosyn.core.library_cache import (
    CodegenError,
    build_cached,
    cached_library,
    find_compiler,
    library_key,
    load_function,
    require_compiler,
    warn_rebuild,
)

__all__ = [
    "CodegenError",
    "clear_cache",
    "compile_function",
    "compile_library",
    "compile_recipe",
    "compile_shared",
    "compile_source",
    "default_cache_dir",
    "find_compiler",
    "generate_source",
]

DEFAULT_FLAGS: tuple[str, ...] = ("-O2",)
"""Optimisation flags given to the compiler (``-shared -fPIC`` are always added)."""
LARGE_SOURCE_FLAGS: tuple[str, ...] = ("-O1",)
"""Flags of :func:`compile_function` and :func:`compile_library` for long sources:
megabytes of straight-line code (e.g. the Jacobian of an RK4 step) take far longer to
compile at ``-O2`` for little gain. Measured on the Panda's obstacle-shaped RK4 step (2 MB
of C): 33 s at ``-O2``, 19 s at ``-O1``, and the same bits 6 % faster."""
LARGE_SOURCE_CHARS = 500_000
"""Source length [characters] from which :func:`compile_function` and
:func:`compile_library` use LARGE_SOURCE_FLAGS (unless given flags)."""
_C_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _flags_for(source: str, flags: Sequence[str] | None) -> tuple[str, ...]:
    """``flags``, or when None the default for a source of this length."""
    if flags is not None:
        return tuple(flags)
    return LARGE_SOURCE_FLAGS if len(source) >= LARGE_SOURCE_CHARS else DEFAULT_FLAGS


# Salt of the recipe keys: bumped when what a recipe index carries changes, so older
# files are never looked up (no warning about them; clear_cache removes them). The
# libraries' own salt is `library_cache.LIBRARY_FORMAT`.
_RECIPE_FORMAT = "geosyn-recipe-v2"


def generate_source(name: str, functions: Sequence[ca.Function]) -> str:
    """C source of the CasADi ``functions`` in one file named after ``name`` (no header).

    Raises:
        CodegenError: CasADi could not generate C for one of them.
    """
    try:
        gen = ca.CodeGenerator(f"{name}.c", {"with_header": False})
        for fun in functions:
            gen.add(fun)
        return gen.dump()
    except RuntimeError as err:
        names = ", ".join(repr(f.name()) for f in functions)
        raise CodegenError(f"CasADi could not generate C code for function {names}: {err}") from err


def compile_function(
    fun: ca.Function,
    cache_dir: str | os.PathLike[str] | None = None,
    *,
    flags: Sequence[str] | None = None,
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
            cache key. None for :data:`DEFAULT_FLAGS`, or :data:`LARGE_SOURCE_FLAGS` when
            the generated source has at least :data:`LARGE_SOURCE_CHARS` characters (as
            :func:`compile_library`).
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
        return _compile_cached(fun, _resolve_cache_dir(cache_dir), flags, compiler)
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
    fun: ca.Function, cache_dir: Path, flags: Sequence[str] | None, compiler: str | None
) -> ca.Function:
    name = fun.name()
    source = generate_source(name, [fun])
    used = _flags_for(source, flags)
    return build_cached(name, source, [name], cache_dir, used, compiler)[name]


def compile_shared(
    name: str,
    source: str,
    *,
    flags: Sequence[str] = DEFAULT_FLAGS,
    cache_dir: str | os.PathLike[str] | None = None,
    compiler: str | None = None,
) -> Path:
    """Compile a plain C ``source`` (no CasADi interface: e.g. a library called through
    ``ctypes``) into a shared library through the disk cache; the path of the verified
    library (its digest and compiled-in key checked, a damaged or swapped one rebuilt
    with a warning).

    Args:
        name: library name, a C identifier (the cache file starts with it).
        source: the whole C file.
        flags: compiler flags besides ``-shared -fPIC`` (part of the cache key).
        cache_dir: folder of the compiled libraries; default :func:`default_cache_dir`.
        compiler: C compiler executable; default :func:`find_compiler`.

    Raises:
        InvalidArgument: ``name`` is not a C identifier.
        CodegenError: no compiler, or compilation failed.
    """
    if not isinstance(name, str) or not _C_IDENTIFIER.fullmatch(name):
        raise InvalidArgument(f"name: {name!r} is not a C identifier")
    library, _ = cached_library(
        name, source, _resolve_cache_dir(cache_dir), tuple(flags), compiler, None
    )
    return library


def compile_source(
    name: str,
    source: str,
    load: Sequence[str],
    *,
    flags: Sequence[str],
    cache_dir: str | os.PathLike[str] | None = None,
    compiler: str | None = None,
) -> dict[str, ca.Function]:
    """Compile a C ``source`` written for CasADi's external-function interface (e.g.
    `generate_source` output plus hand-written C) through the disk cache, and load the
    functions ``load`` back (as :func:`compile_library` does for CasADi functions).

    Args:
        name: library name, a C identifier (the cache file starts with it).
        source: the whole C file.
        load: names of the functions to load back.
        flags: compiler flags besides ``-shared -fPIC`` (part of the cache key).
        cache_dir: folder of the compiled libraries; default :func:`default_cache_dir`.
        compiler: C compiler executable; default :func:`find_compiler`.

    Returns:
        ``{function name: casadi.Function}`` for the names in ``load``.

    Raises:
        InvalidArgument: ``name`` is not a C identifier.
        CodegenError: no compiler, compilation or loading failed.
    """
    if not isinstance(name, str) or not _C_IDENTIFIER.fullmatch(name):
        raise InvalidArgument(f"name: {name!r} is not a C identifier")
    return build_cached(
        name, source, list(load), _resolve_cache_dir(cache_dir), tuple(flags), compiler
    )


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
    source = generate_source(name, funs)
    return build_cached(
        name, source, wanted, _resolve_cache_dir(cache_dir), _flags_for(source, flags), compiler
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
    cc = require_compiler(compiler)
    folder = _resolve_cache_dir(cache_dir)
    extra = () if flags is None else tuple(flags)
    recipe_key = hashlib.sha256("\0".join([_RECIPE_FORMAT, recipe, cc, *extra]).encode())
    index = folder / f"{name}_{recipe_key.hexdigest()[:24]}.recipe"
    hit = _recipe_hit(index, name, load, recipe_key.hexdigest())
    if hit is not None:
        return hit
    report = progress if progress is not None else (lambda _line: None)
    start = time.perf_counter()
    report(f"{name}: building the symbolic functions (first use; cached afterwards)")
    funs = list(make_functions())
    source = generate_source(name, funs)
    used = _flags_for(source, flags)
    report(
        f"{name}: {time.perf_counter() - start:.1f} s; compiling {len(source) / 1e6:.1f} MB "
        f"of C with {' '.join(used)} (skipped if already compiled)"
    )
    names = [f.name() for f in funs]
    unknown = sorted(set(load) - set(names))
    if unknown:
        raise InvalidArgument(f"load: {unknown} are not among the functions {names}")
    result = build_cached(name, source, list(load), folder, used, cc, recipe_key.hexdigest())
    try:  # the index appears atomically, after the library it names
        fd, tmp = tempfile.mkstemp(prefix=_TMP_PREFIX, dir=folder)
        os.chmod(tmp, 0o644)  # like the library it names (mkstemp makes it private)
        with os.fdopen(fd, "w") as fh:
            fh.write(f"{name}_{library_key(source, cc, used, recipe_key.hexdigest())[:24]}\n")
        os.replace(tmp, index)
    except OSError as err:
        warnings.warn(f"could not write the recipe index {index}: {err}", RuntimeWarning, 2)
    report(f"{name}: ready in {time.perf_counter() - start:.1f} s")
    return result


def _recipe_hit(
    index: Path, name: str, load: Sequence[str], recipe_key: str
) -> dict[str, ca.Function] | None:
    """The functions of the library a recipe index names, if it is intact and was built
    for this recipe; None (after a warning, if something was wrong) to rebuild."""
    try:
        stem = library_digest.read_index(index, name)
    except (OSError, ValueError) as err:
        warn_rebuild(f"recipe index {index.name}", str(err))
        return None
    if stem is None:
        return None
    library = index.with_name(f"{stem}.so")
    if not library.is_file():  # removed by hand, or a flipped bit named another file
        warn_rebuild(f"recipe index {index.name}", f"it names a missing library {stem}.so")
        return None
    damage = library_digest.damage(library, recipe_key=recipe_key)
    if damage is None:
        try:
            return {n: load_function(n, library) for n in load}
        except CodegenError as err:
            damage = str(err)
    warn_rebuild(f"{library.name} (named by {index.name})", damage)
    return None
