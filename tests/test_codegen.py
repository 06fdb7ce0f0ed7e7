"""Tests of geosyn.core.codegen: compiled functions, the disk cache, failures."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from geosyn.core import GeosynError, InvalidArgument, codegen, library_cache
from geosyn.core.calls import numpy_function
from geosyn.core.codegen import CodegenError, clear_cache, compile_function
from geosyn.robots import symbolic


def _tiny() -> ca.Function:
    """A small function with a vector, a matrix and a scalar output."""
    x = ca.SX.sym("x", 3)
    y = ca.SX.sym("y")
    return ca.Function(
        "tiny",
        [x, y],
        [ca.sin(x) * y, ca.horzcat(x, 2 * x), ca.dot(x, x)],
        ["x", "y"],
        ["s", "m", "n"],
        {"cse": True},
    )


@pytest.fixture(scope="module")
def sample_dynamics() -> symbolic.DynamicsFunctions:
    return symbolic.dynamics_functions(
        pin.buildSampleModelManipulator(), np.array([0.0, 0.0, -9.81])
    )


@pytest.fixture
def compile_counter(monkeypatch: pytest.MonkeyPatch) -> list[Path]:
    """Records every compiler run (the C file compiled) while still compiling."""
    runs: list[Path] = []
    real = library_cache.run_compiler

    def counting(compiler, flags, source, output):
        runs.append(source)
        return real(compiler, flags, source, output)

    monkeypatch.setattr(library_cache, "run_compiler", counting)
    return runs


def _cached(cache: Path, suffix: str = ".so") -> list[Path]:
    return sorted(p for p in cache.iterdir() if p.suffix == suffix)


def test_compiled_equals_uncompiled(tmp_path: Path, sample_dynamics) -> None:
    rng = np.random.default_rng(0)
    for fun in (sample_dynamics.M, sample_dynamics.aba):
        compiled = compile_function(fun, tmp_path)
        assert compiled.name() == fun.name()
        assert compiled.name_in() == fun.name_in()
        assert compiled.name_out() == fun.name_out()
        for _ in range(50):
            args = [rng.normal(size=fun.size1_in(i)) for i in range(fun.n_in())]
            expected = fun(*args).full()
            scale = max(1.0, float(np.max(np.abs(expected))))
            np.testing.assert_allclose(compiled(*args).full(), expected, rtol=0, atol=1e-14 * scale)


def test_second_compile_hits_the_cache(tmp_path: Path, compile_counter: list[Path]) -> None:
    fun = _tiny()
    first = compile_function(fun, tmp_path)
    (library,) = _cached(tmp_path)
    assert len(_cached(tmp_path, ".c")) == 1
    stamp = library.stat().st_mtime_ns
    second = compile_function(_tiny(), tmp_path)  # a new but identical Function
    assert len(compile_counter) == 1
    assert library.stat().st_mtime_ns == stamp
    x = np.array([0.1, -0.2, 0.3])
    np.testing.assert_array_equal(first(x, 2.0)[1].full(), second(x, 2.0)[1].full())
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tmp")]


def test_cache_is_shared_across_processes(tmp_path: Path) -> None:
    compile_function(_tiny(), tmp_path)
    (library,) = _cached(tmp_path)
    stamp = library.stat().st_mtime_ns
    script = textwrap.dedent(
        f"""
        import casadi as ca
        from geosyn.core import codegen, library_cache

        def no_compiler(*args):
            raise SystemExit("the compiler ran despite a cached library")

        library_cache.run_compiler = no_compiler
        x = ca.SX.sym("x", 3)
        y = ca.SX.sym("y")
        fun = ca.Function("tiny", [x, y], [ca.sin(x) * y, ca.horzcat(x, 2 * x), ca.dot(x, x)],
                          ["x", "y"], ["s", "m", "n"], {{"cse": True}})
        out = codegen.compile_function(fun, {str(tmp_path)!r})
        print(float(out([1.0, 2.0, 3.0], 1.0)[2]))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert float(done.stdout) == 14.0
    assert _cached(tmp_path) == [library]
    assert library.stat().st_mtime_ns == stamp


def test_flags_are_part_of_the_key(tmp_path: Path, compile_counter: list[Path]) -> None:
    compile_function(_tiny(), tmp_path)
    compile_function(_tiny(), tmp_path, flags=("-O1",))
    assert len(compile_counter) == 2
    assert len(_cached(tmp_path)) == 2


def test_long_sources_compile_with_the_large_source_flags(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """compile_function without flags: -O2, or -O1 from LARGE_SOURCE_CHARS characters of
    C on (here lowered below the tiny function's source); the numbers are the uncompiled
    function's either way."""
    used: list[tuple[str, ...]] = []
    real = library_cache.run_compiler

    def recording(compiler, flags, source, output):
        used.append(tuple(flags))
        return real(compiler, flags, source, output)

    monkeypatch.setattr(library_cache, "run_compiler", recording)
    fun = _tiny()
    x, y = np.array([0.3, -1.2, 2.0]), 0.7
    short = compile_function(fun, tmp_path / "short")
    monkeypatch.setattr(codegen, "LARGE_SOURCE_CHARS", 10)
    long = compile_function(fun, tmp_path / "long")
    assert used == [codegen.DEFAULT_FLAGS, codegen.LARGE_SOURCE_FLAGS] == [("-O2",), ("-O1",)]
    for compiled in (short, long):
        for a, b in zip(compiled(x, y), fun(x, y), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_damaged_library_is_rebuilt(tmp_path: Path, compile_counter: list[Path]) -> None:
    good = tmp_path / "good"
    compile_function(_tiny(), good)
    (library,) = _cached(good)
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    (damaged / library.name).write_bytes(b"not a shared library")
    with pytest.warns(RuntimeWarning, match="recompiling"):
        fun = compile_function(_tiny(), damaged)
    assert len(compile_counter) == 2
    assert float(fun([1.0, 2.0, 3.0], 1.0)[2]) == 14.0


_TINY_SCRIPT = """
import sys, warnings
import casadi as ca
from geosyn.core import codegen

x = ca.SX.sym("x", 3)
y = ca.SX.sym("y")
fun = ca.Function("tiny", [x, y], [ca.sin(x) * y, ca.horzcat(x, 2 * x), ca.dot(x, x)],
                  ["x", "y"], ["s", "m", "n"], {"cse": True})
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    out = codegen.compile_function(fun, sys.argv[1])
print(float(out([1.0, 2.0, 3.0], 1.0)[2]), sum("damaged" in str(w.message) for w in caught))
"""


def _tiny_in_subprocess(cache: Path, *, wait: bool = True) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", _TINY_SCRIPT, str(cache)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    if wait:
        proc.wait(timeout=120)
    return proc


def _replace_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` as a new file at ``path`` (a new inode: a library this process has
    loaded stays mapped intact)."""
    tmp = path.with_name(path.name + ".new")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def test_library_digest_is_stored_and_verified(tmp_path: Path) -> None:
    compile_function(_tiny(), tmp_path)
    (library,) = _cached(tmp_path)
    digest = library.with_name(library.name + ".sha256")
    assert digest.read_text().strip() == hashlib.sha256(library.read_bytes()).hexdigest()
    assert codegen.library_digest.damage(library) is None
    data = bytearray(library.read_bytes())
    data[len(data) // 2] ^= 0x40  # one flipped bit: the ELF structure is still intact
    _replace_bytes(library, bytes(data))
    assert codegen.library_digest.elf_damage(bytes(data)) is None
    assert (
        codegen.library_digest.damage(library) == "sha256 differs from the digest stored beside it"
    )


@pytest.mark.parametrize("damage", ["truncated", "bitflip", "empty"])
def test_corrupted_cache_entry_is_rebuilt_in_a_fresh_process(tmp_path: Path, damage: str) -> None:
    """A damaged .so is never dlopen'ed (a truncated one gave a bus error): rebuilt, no crash."""
    first = _tiny_in_subprocess(tmp_path)
    assert first.returncode == 0, first.stderr.read() if first.stderr else ""
    (library,) = _cached(tmp_path)
    good = library.read_bytes()
    data = bytearray(good)
    if damage == "truncated":
        data = data[: len(data) // 2]
    elif damage == "bitflip":
        data[len(data) // 3] ^= 0x01
    else:
        data = bytearray()
    _replace_bytes(library, bytes(data))
    proc = _tiny_in_subprocess(tmp_path)
    out, err = proc.communicate()
    assert proc.returncode == 0, err  # a SIGBUS/SIGSEGV would be -7/-11
    value, warned = out.split()
    assert float(value) == 14.0 and int(warned) == 1
    assert library.read_bytes() == good  # rebuilt: gcc is deterministic for one source
    assert codegen.library_digest.damage(library) is None


def test_library_cached_before_digests_is_adopted(
    tmp_path: Path, compile_counter: list[Path]
) -> None:
    compile_function(_tiny(), tmp_path)
    (library,) = _cached(tmp_path)
    digest = library.with_name(library.name + ".sha256")
    digest.unlink()
    assert codegen.library_digest.damage(library) is None  # intact ELF: adopted, digest written
    assert digest.is_file() and len(compile_counter) == 1
    digest.unlink()
    _replace_bytes(library, library.read_bytes()[:-100])  # truncated, no digest to compare
    assert "truncated" in str(codegen.library_digest.damage(library))


def test_concurrent_builders_agree(tmp_path: Path) -> None:
    procs = [_tiny_in_subprocess(tmp_path, wait=False) for _ in range(3)]
    for proc in procs:
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
        assert out.split() == ["14.0", "0"]
    (library,) = _cached(tmp_path)
    assert codegen.library_digest.damage(library) is None
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tmp-geosyn-")]


def test_missing_compiler_raises(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(library_cache.shutil, "which", lambda name: None)
    with pytest.raises(CodegenError, match="no C compiler"):
        compile_function(_tiny(), tmp_path)
    assert issubclass(CodegenError, GeosynError)


def test_missing_compiler_falls_back_with_a_warning(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    fun = _tiny()
    with pytest.warns(RuntimeWarning, match="falling back.*no C compiler"):
        out = compile_function(fun, tmp_path, fallback=True)
    assert out is fun


def test_broken_compiler_on_path_raises(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    gcc = bin_dir / "gcc"
    gcc.write_text("#!/bin/sh\necho 'gcc: internal compiler error' >&2\nexit 4\n")
    gcc.chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
    cache = tmp_path / "cache"
    with pytest.raises(CodegenError, match="internal compiler error") as info:
        compile_function(_tiny(), cache)
    assert info.value.returncode == 4
    assert info.value.command[0] == str(gcc)
    # Nothing half-built is left behind.
    assert list(cache.iterdir()) == []
    with pytest.warns(RuntimeWarning, match="falling back"):
        compile_function(_tiny(), cache, fallback=True)


def test_compiler_that_cannot_run_raises(tmp_path: Path) -> None:
    not_executable = tmp_path / "cc"
    not_executable.write_text("garbage")
    with pytest.raises(CodegenError, match="could not run"):
        compile_function(_tiny(), tmp_path / "cache", compiler=str(not_executable))


def test_clear_cache_removes_only_its_files(tmp_path: Path) -> None:
    compile_function(_tiny(), tmp_path)
    keep = tmp_path / "notes.txt"
    keep.write_text("not ours")
    other_so = tmp_path / "libother.so"
    other_so.write_bytes(b"")
    assert clear_cache(tmp_path) == 3  # the .so, its .so.sha256 digest and the .c
    assert sorted(p.name for p in tmp_path.iterdir()) == ["libother.so", "notes.txt"]
    assert clear_cache(tmp_path / "missing") == 0


def test_default_cache_dir_follows_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, compile_counter: list[Path]
) -> None:
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    assert codegen.default_cache_dir() == tmp_path / "codegen"
    compile_function(_tiny())
    assert len(_cached(tmp_path / "codegen")) == 1
    assert clear_cache() == 3  # .so, .so.sha256, .c
    monkeypatch.delenv("GEOSYN_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert codegen.default_cache_dir() == tmp_path / "xdg" / "geosyn" / "codegen"


def test_bad_arguments_raise(tmp_path: Path) -> None:
    with pytest.raises(InvalidArgument, match="casadi.Function"):
        compile_function("tiny", tmp_path)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="casadi.Function"):
        numpy_function(lambda x: x)  # type: ignore[arg-type]


@pytest.mark.parametrize("compiled", [False, True])
def test_numpy_function_matches_call(tmp_path: Path, compiled: bool, sample_dynamics) -> None:
    tiny = compile_function(_tiny(), tmp_path) if compiled else _tiny()
    call = numpy_function(tiny)
    x = np.array([0.4, -1.0, 2.5])
    s, m, n = call(x, 3.0)
    expected = tiny(x, 3.0)
    assert s.shape == (3,)
    assert m.shape == (3, 2)
    assert n.shape == (1,)
    np.testing.assert_array_equal(s, expected[0].full().ravel())
    np.testing.assert_array_equal(m, expected[1].full())
    np.testing.assert_array_equal(n, expected[2].full().ravel())

    mass = numpy_function(sample_dynamics.M)
    q = np.random.default_rng(1).normal(size=sample_dynamics.M.size1_in(0))
    np.testing.assert_array_equal(mass(q)[0], sample_dynamics.M(q).full())
    with pytest.raises(InvalidArgument, match="expected 2 arguments"):
        call(x)


def test_numpy_function_rejects_sparse_outputs() -> None:
    x = ca.SX.sym("x", 2)
    sparse = ca.Function("sparse", [x], [ca.diag(x)])
    with pytest.raises(InvalidArgument, match="sparse"):
        numpy_function(sparse)


def test_all_names_resolve() -> None:
    for name in codegen.__all__:
        assert hasattr(codegen, name), name


# -- the cache verifies what it loads: corrupt digests and indexes, swapped libraries ------
_RECIPE_SCRIPT = """
import json, sys, warnings
import casadi as ca
from geosyn.core import codegen

def make(dt):
    x = ca.SX.sym("x", 2)
    return [ca.Function("step", [x], [x + dt * ca.sin(x)], ["x"], ["y"])]

dt = float(sys.argv[2])
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    lib = codegen.compile_recipe("geosyn_test_swap", f"step dt={dt}", lambda: make(dt),
                                 sys.argv[1], load=["step"])
y = lib["step"]([0.3, -1.2]).full().ravel().tolist()
print(json.dumps({"y": y, "warnings": [str(w.message) for w in caught]}))
"""


def _step_reference(dt: float) -> np.ndarray:
    """The uncompiled CasADi function of the recipe ``step dt=<dt>``, evaluated."""
    x = ca.SX.sym("x", 2)
    fun = ca.Function("step", [x], [x + dt * ca.sin(x)])
    return fun([0.3, -1.2]).full().ravel()


def _recipe_run(cache: Path, dt: float) -> tuple[np.ndarray, list[str]]:
    """compile_recipe in a fresh process (nothing dlopen-ed before): (y, warnings)."""
    done = subprocess.run(
        [sys.executable, "-c", _RECIPE_SCRIPT, str(cache), repr(dt)],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr  # no traceback, whatever the cache holds
    out = __import__("json").loads(done.stdout)
    return np.array(out["y"]), out["warnings"]


def _recipe_files(cache: Path, dt: float) -> tuple[Path, Path]:
    """(index, library) of the recipe ``step dt=<dt>``."""
    for index in cache.glob("geosyn_test_swap_*.recipe"):
        library = cache / f"{index.read_text().strip()}.so"
        keys = codegen.library_digest.embedded_keys(library.read_bytes())[1]
        recipe = f"step dt={dt}"
        cc = codegen.find_compiler()
        want = hashlib.sha256(
            "\0".join([codegen._RECIPE_FORMAT, recipe, str(cc)]).encode()
        ).hexdigest()
        if keys == [want]:
            return index, library
    raise AssertionError(f"no library for dt={dt}")


def test_swapped_recipe_library_is_detected_and_rebuilt(tmp_path: Path) -> None:
    """An index naming another recipe's valid library (the MPC ran another time step's
    dynamics) is refused: the library carries the key of the recipe it was built for."""
    for dt in (0.01, 0.02):
        y, warned = _recipe_run(tmp_path, dt)
        np.testing.assert_allclose(y, _step_reference(dt), rtol=0, atol=1e-15)
        assert warned == []
    index_a, library_a = _recipe_files(tmp_path, 0.01)
    _, library_b = _recipe_files(tmp_path, 0.02)
    assert library_a != library_b
    index_a.write_text(library_b.stem + "\n")  # the index of dt=0.01 names dt=0.02's library
    y, warned = _recipe_run(tmp_path, 0.01)
    np.testing.assert_allclose(y, _step_reference(0.01), rtol=0, atol=1e-15)
    assert len(warned) == 1 and "another recipe" in warned[0]
    assert index_a.read_text().strip() == library_a.stem  # the index is repaired
    y, warned = _recipe_run(tmp_path, 0.01)
    assert warned == []


def test_library_copied_under_another_name_is_rebuilt(tmp_path: Path) -> None:
    """A valid library with its valid digest, copied over another library's name."""
    for dt in (0.01, 0.02):
        _recipe_run(tmp_path, dt)
    _, library_a = _recipe_files(tmp_path, 0.01)
    _, library_b = _recipe_files(tmp_path, 0.02)
    good = library_a.read_bytes()
    _replace_bytes(library_a, library_b.read_bytes())
    _replace_bytes(
        codegen.library_digest.digest_path(library_a),
        codegen.library_digest.digest_path(library_b).read_bytes(),
    )
    assert "another library" in str(codegen.library_digest.damage(library_a))
    y, warned = _recipe_run(tmp_path, 0.01)
    np.testing.assert_allclose(y, _step_reference(0.01), rtol=0, atol=1e-15)
    assert len(warned) >= 1 and all("discarding it and recompiling" in w for w in warned)
    assert library_a.read_bytes() == good


def _step_in_process(cache: Path, dt: float) -> tuple[np.ndarray, list[str]]:
    """compile_recipe of ``step dt=<dt>`` in this process: (y, warnings)."""

    def make() -> list[ca.Function]:
        x = ca.SX.sym("x", 2)
        return [ca.Function("step", [x], [x + dt * ca.sin(x)], ["x"], ["y"])]

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        lib = codegen.compile_recipe(
            "geosyn_test_swap", f"step dt={dt}", make, cache, load=["step"]
        )
    return lib["step"]([0.3, -1.2]).full().ravel(), [str(w.message) for w in caught]


@pytest.mark.parametrize("target", [".sha256", ".recipe"])
@pytest.mark.parametrize("bit", [0x01, 0x80])  # 0x80: invalid UTF-8 (a UnicodeDecodeError once)
def test_flipped_bit_in_digest_or_index_is_discarded_and_rebuilt(
    tmp_path: Path, target: str, bit: int
) -> None:
    _step_in_process(tmp_path, 0.01)
    index, library = _recipe_files(tmp_path, 0.01)
    victim = index if target == ".recipe" else codegen.library_digest.digest_path(library)
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= bit
    victim.write_bytes(bytes(data))
    y, warned = _step_in_process(tmp_path, 0.01)
    np.testing.assert_allclose(y, _step_reference(0.01), rtol=0, atol=1e-15)
    assert warned and all("damaged" in w and "recompiling" in w for w in warned), warned
    assert codegen.library_digest.damage(library) is None  # repaired on disk
    assert _step_in_process(tmp_path, 0.01)[1] == []


def test_corrupt_digest_and_index_files_are_read_defensively(tmp_path: Path) -> None:
    library = tmp_path / "f_0123456789abcdef01234567.so"
    library.write_bytes(b"\x7fELF")
    digest = codegen.library_digest.digest_path(library)
    index = tmp_path / "f_0123456789abcdef01234567.recipe"
    for garbage in (b"\xff\xfe\x00", b"", b"0" * 10_000, b"zz" * 32, b"f_abc\n"):
        digest.write_bytes(garbage)
        with pytest.raises(ValueError, match="corrupt"):
            codegen.library_digest.read_digest(library)
        index.write_bytes(garbage)
        with pytest.raises(ValueError, match="corrupt"):
            codegen.library_digest.read_index(index, "f")
    index.write_text("f_0123456789abcdef01234567\n")
    assert codegen.library_digest.read_index(index, "f") == "f_0123456789abcdef01234567"
    assert codegen.library_digest.read_index(tmp_path / "missing.recipe", "f") is None


def test_compiled_library_carries_its_key(tmp_path: Path) -> None:
    compile_function(_tiny(), tmp_path)
    (library,) = _cached(tmp_path)
    keys, recipes = codegen.library_digest.embedded_keys(library.read_bytes())
    assert len(keys) == 1 and keys[0].startswith(library.stem.rsplit("_", 1)[1])
    assert recipes == []
