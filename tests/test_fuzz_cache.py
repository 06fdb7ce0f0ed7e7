"""Fuzz: the compiled-code cache under seeded damage (issue 23).

Every file of a recipe-keyed library (the ``.so``, its ``.so.sha256``, the ``.recipe``
index, the ``.c`` source) is damaged in a seeded way: one flipped bit, truncation, empty,
random bytes, invalid UTF-8, a megabyte of text, another library's file, a link to
``/dev/zero``, a FIFO. Each case must end with the right numbers (compared with the
uncompiled CasADi function), at most warnings (never an exception or a traceback), and
a repaired cache (the next call warns no more). A swapped library is never loaded: each
case copies the cache to a new folder, so no file was ever ``dlopen``-ed at its path.
"""

from __future__ import annotations

import os
import random
import shutil
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from fuzzing import time_bound

from geosyn.core import codegen

X = np.array([0.3, -1.2, 2.0])
CASES = 16
DAMAGES = ("bitflip", "truncate", "empty", "random", "utf8", "huge", "swap", "devzero", "fifo")
TARGETS = (".so", ".so.sha256", ".recipe", ".c")


def _functions(dt: float) -> list[ca.Function]:
    x = ca.SX.sym("x", 3)
    return [ca.Function("fz_step", [x], [x + dt * ca.sin(x) * ca.cos(x[0])], ["x"], ["y"])]


def _call(cache: Path, dt: float) -> tuple[np.ndarray, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        lib = codegen.compile_recipe(
            "geosyn_fuzz_cache", f"fuzz dt={dt}", lambda: _functions(dt), cache, load=["fz_step"]
        )
    return lib["fz_step"](X).full().ravel(), [str(w.message) for w in caught]


def _reference(dt: float) -> np.ndarray:
    return _functions(dt)[0](X).full().ravel()


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A cache holding the libraries of two recipes (dt = 0.01 and dt = 0.02)."""
    folder = tmp_path_factory.mktemp("pristine")
    for dt in (0.01, 0.02):
        _call(folder, dt)
    return folder


def _files(cache: Path, dt: float) -> dict[str, Path]:
    """The cache files of recipe ``dt`` by suffix."""
    for index in cache.glob("*.recipe"):
        stem = index.read_text().strip()
        library = cache / f"{stem}.so"
        recipes = codegen.library_digest.embedded_keys(library.read_bytes())[1]
        cc = codegen.find_compiler()
        key = __import__("hashlib").sha256(
            "\0".join([codegen._RECIPE_FORMAT, f"fuzz dt={dt}", str(cc)]).encode()
        )
        if recipes == [key.hexdigest()]:
            return {
                ".so": library,
                ".so.sha256": codegen.library_digest.digest_path(library),
                ".recipe": index,
                ".c": cache / f"{stem}.c",
            }
    raise AssertionError(f"no library for dt={dt}")


def _damage(path: Path, other: Path, how: str, rng: random.Random) -> None:
    data = path.read_bytes()
    path.unlink()
    if how == "bitflip":
        flipped = bytearray(data)
        flipped[rng.randrange(len(flipped))] ^= 1 << rng.randrange(8)
        path.write_bytes(bytes(flipped))
    elif how == "truncate":
        path.write_bytes(data[: rng.randrange(len(data))])
    elif how == "empty":
        path.write_bytes(b"")
    elif how == "random":
        path.write_bytes(rng.randbytes(rng.randrange(1, 200)))
    elif how == "utf8":
        path.write_bytes(b"\xff\xfe" + data[2:])
    elif how == "huge":
        path.write_bytes(b"0123456789abcdef" * 65536)
    elif how == "swap":  # the same file of the other recipe
        path.write_bytes(other.read_bytes())
    elif how == "devzero":
        path.symlink_to("/dev/zero")
    else:
        os.mkfifo(path)


@pytest.mark.parametrize("case", range(CASES))
def test_damaged_cache_gives_the_right_numbers_and_repairs_itself(
    pristine: Path, tmp_path: Path, case: int
) -> None:
    rng = random.Random(2300 + case)
    how, target = DAMAGES[case % len(DAMAGES)], rng.choice(TARGETS)
    cache = tmp_path / "cache"
    shutil.copytree(pristine, cache, symlinks=True)
    _damage(_files(cache, 0.01)[target], _files(cache, 0.02)[target], how, rng)
    with time_bound(60.0):
        y, warned = _call(cache, 0.01)
    np.testing.assert_allclose(y, _reference(0.01), rtol=0, atol=1e-15, err_msg=f"{how} {target}")
    assert all("recompiling" in w for w in warned), (how, target, warned)
    with time_bound(60.0):
        y, warned = _call(cache, 0.01)
    np.testing.assert_allclose(y, _reference(0.01), rtol=0, atol=1e-15)
    assert warned == [], (how, target, warned)  # repaired
    y, _ = _call(cache, 0.02)  # the other recipe is untouched
    np.testing.assert_allclose(y, _reference(0.02), rtol=0, atol=1e-15)
