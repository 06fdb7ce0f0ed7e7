"""The MPC's compiled Gauss-Newton stage functions (through the one codegen cache), its
settings and the fallback it records when there is no C compiler."""

from __future__ import annotations

import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers.mpc import GeodesicMPC
from geosyn.controllers.mpc.ocp.compiled import (
    cached_stage_dynamics,
    compiled_dynamics,
    stage_recipe,
    zero_curvature_library,
)
from geosyn.controllers.mpc.ocp.dynamics import stage_dynamics
from geosyn.controllers.mpc.ocp.settings import DEFAULT_EFFORT_WEIGHT, ocp_settings
from geosyn.core import InvalidArgument, codegen, library_cache
from geosyn.core.codegen import CodegenError, clear_cache, compile_library


def _probe() -> ca.Function:
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    y = ca.vertcat(ca.sin(x[0]) * x[1], x[0] ** 2 * u)
    return ca.Function("gn_probe", [x, u], [y], ["x", "u"], ["y"])


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A private codegen cache (the default folder follows GEOSYN_CACHE_DIR)."""
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    return tmp_path / "codegen"


def test_zero_curvature_library_gives_gauss_newton_hessians(cache: Path) -> None:
    f = _probe()
    fc = zero_curvature_library([f], "geosyn_test_gn")["gn_probe"]
    rng = np.random.default_rng(0)
    X, U = ca.MX.sym("X", 2), ca.MX.sym("U", 1)
    z = ca.vertcat(X, U)
    hess = ca.Function("h", [X, U], [ca.hessian(ca.sumsqr(fc(X, U)), z)[0]])
    jac = ca.Function("j", [X, U], [ca.jacobian(f(X, U), z)])
    for _ in range(5):
        x, u = rng.normal(size=2), rng.normal(size=1)
        np.testing.assert_allclose(fc(x, u).full(), f(x, u).full(), rtol=0, atol=1e-14)
        # Only the cost's curvature is left: the Hessian of |F|^2 is 2 J^T J.
        J = jac(x, u).full()
        np.testing.assert_allclose(hess(x, u).full(), 2 * J.T @ J, rtol=1e-12, atol=1e-12)
    # The library went through the codegen cache, which clear_cache empties.
    assert [p.name.startswith("geosyn_test_gn_") for p in cache.glob("*.so")] == [True]
    assert clear_cache() >= 2 and not any(cache.iterdir())  # the .so, its .c (and digest)


def test_compile_library_hits_the_cache_and_validates(cache: Path) -> None:
    f = _probe()
    first = compile_library("geosyn_test_lib", [f])
    (library,) = cache.glob("*.so")
    stamp = library.stat().st_mtime_ns
    again = compile_library("geosyn_test_lib", [_probe()])
    assert library.stat().st_mtime_ns == stamp and len(list(cache.glob("*.so"))) == 1
    np.testing.assert_allclose(first["gn_probe"](1.0, 2.0), again["gn_probe"](1.0, 2.0))
    with pytest.raises(InvalidArgument, match="name"):
        compile_library("not-an-identifier", [f])
    with pytest.raises(InvalidArgument, match="load"):
        compile_library("geosyn_test_lib", [f], load=["missing"])
    with pytest.raises(InvalidArgument, match="functions"):
        compile_library("geosyn_test_lib", [])
    (cache / "geosyn-mpc-x1").mkdir()  # left by the MPC's former private cache copy
    assert clear_cache() >= 3 and not any(cache.iterdir())  # .so, .c (digest), that folder


def test_compiled_stage_dynamics_match_the_symbolic_ones() -> None:
    robot = get_robot("planar2")
    rng = np.random.default_rng(1)
    for control in ("torque", "acceleration"):
        sx = stage_dynamics(robot, 0.02, control, 1, gravity=True)
        compiled = compiled_dynamics(sx, control, robot.name)  # cached in the default folder
        for _ in range(5):
            x, u = rng.normal(size=4), rng.normal(size=2)
            for a, b in zip(compiled, sx, strict=True):
                np.testing.assert_allclose(a(x, u).full(), b(x, u).full(), rtol=1e-12, atol=1e-12)


def test_without_compiler_hessian_becomes_exact_and_is_recorded(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(library_cache, "find_compiler", lambda: None)
    with pytest.warns(RuntimeWarning, match="hessian.*exact.*no C compiler"):
        mpc = GeodesicMPC(get_robot("planar2"), get_metric("planar2"), horizon=5)
    assert mpc.hessian == "exact"
    assert "no C compiler" in mpc.diagnostics.notes["hessian"]
    mpc.reset(np.zeros(2), np.zeros(2))
    assert "hessian" in mpc.diagnostics.notes  # a build-time note outlives reset


def test_exact_hessian_asked_for_is_not_a_note() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mpc = GeodesicMPC(get_robot("planar2"), get_metric("planar2"), horizon=5, hessian="exact")
    assert mpc.diagnostics.notes == {}


def test_settings_defaults_follow_the_effort() -> None:
    def settings(control: str):
        return ocp_settings(2, 5, 0.02, control, None, 1, 1.0, 1.0, None, 1.0)

    acc = settings("acceleration")
    assert acc.effort == "acceleration"
    np.testing.assert_array_equal(acc.effort_weight, DEFAULT_EFFORT_WEIGHT["acceleration"])
    tq = settings("torque")
    assert tq.effort == "torque" and tq.terminal_weight.shape == (4,)
    np.testing.assert_array_equal(tq.effort_weight, DEFAULT_EFFORT_WEIGHT["torque"])


def test_codegen_error_is_what_a_missing_compiler_raises(
    cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(library_cache, "find_compiler", lambda: None)
    with pytest.raises(CodegenError, match="no C compiler"):
        zero_curvature_library([_probe()], "geosyn_test_gn")


# -- recipe-keyed cache: a robot seen before builds no graph -------------------------------
def test_compile_recipe_hit_builds_nothing_and_clear_cache_removes_the_index(
    cache: Path,
) -> None:
    calls: list[int] = []

    def make() -> list[ca.Function]:
        calls.append(1)
        return [_probe()]

    lines: list[str] = []
    first = codegen.compile_recipe(
        "geosyn_test_recipe", "probe v1", make, load=["gn_probe"], progress=lines.append
    )
    assert calls == [1] and any("building" in s for s in lines) and "ready" in lines[-1]
    (index,) = cache.glob("*.recipe")
    (library,) = cache.glob("*.so")
    assert index.read_text().strip() == library.stem  # the index names the library
    again = codegen.compile_recipe("geosyn_test_recipe", "probe v1", make, load=["gn_probe"])
    assert calls == [1]  # the hit called nothing
    np.testing.assert_allclose(again["gn_probe"](1.0, 2.0), first["gn_probe"](1.0, 2.0))
    # Another recipe is another index and another library: each library carries the key
    # of the recipe it was built for, checked before loading (issue 23).
    codegen.compile_recipe("geosyn_test_recipe", "probe v2", make, load=["gn_probe"])
    assert calls == [1, 1] and len(list(cache.glob("*.recipe"))) == 2
    assert len(list(cache.glob("*.so"))) == 2
    # An index whose library is gone is rebuilt, not trusted.
    library.unlink()
    codegen.compile_recipe("geosyn_test_recipe", "probe v1", make, load=["gn_probe"])
    assert calls == [1, 1, 1] and library.is_file()
    with pytest.raises(InvalidArgument, match="load"):
        codegen.compile_recipe("geosyn_test_recipe", "probe v3", make, load=["missing"])
    assert clear_cache() >= 4  # .so, .c (its digest) and both indexes
    assert not any(cache.iterdir())


def test_cached_stage_dynamics_equal_the_symbolic_ones() -> None:
    """The recipe path's compiled functions (for torque control the chain-rule Jacobian
    through RK4, `rk4_parts`) equal the symbolic stage and its Jacobian, and the recipe
    tells settings apart."""
    robot = get_robot("planar2")
    rng = np.random.default_rng(2)
    for control, steps in (("torque", 1), ("torque", 2), ("acceleration", 1)):
        sx = stage_dynamics(robot, 0.02, control, steps, gravity=True)
        fast = cached_stage_dynamics(robot, 0.02, control, steps, True)
        for _ in range(3):
            x, u = rng.normal(size=4), rng.normal(size=2)
            for a, b in zip(fast, sx, strict=True):
                np.testing.assert_allclose(a(x, u).full(), b(x, u).full(), rtol=1e-13, atol=1e-13)
        # The compiled part's Jacobian is exact (its curvature is declared zero).
        f_fast = fast.F if control == "torque" else fast.TAU
        f_sx = sx.F if control == "torque" else sx.TAU
        x, u = rng.normal(size=4), rng.normal(size=2)
        jf, js = f_fast.jacobian(), f_sx.jacobian()
        out = f_sx(x, u)
        for a, b in zip(jf(x, u, out), js(x, u, out), strict=True):
            np.testing.assert_allclose(a.full(), b.full(), rtol=1e-12, atol=1e-12)
        # Reverse mode (adj1_* in the torque library) gives J^T lam exactly.
        lam = rng.normal(size=f_fast.size1_out(0))
        X, U = ca.MX.sym("X", 4), ca.MX.sym("U", 2)
        grad = ca.Function("g", [X, U], [ca.gradient(ca.dot(lam, f_fast(X, U)), ca.vertcat(X, U))])
        J = np.hstack([b.full() for b in js(x, u, out)])
        np.testing.assert_allclose(grad(x, u).full().ravel(), J.T @ lam, rtol=1e-12, atol=1e-12)
    base = stage_recipe(robot, 0.02, "torque", 1, True)
    assert base == stage_recipe(robot, 0.02, "torque", 1, True)
    for other in (
        stage_recipe(robot, 0.01, "torque", 1, True),
        stage_recipe(robot, 0.02, "torque", 2, True),
        stage_recipe(robot, 0.02, "torque", 1, False),
        stage_recipe(get_robot("planar3"), 0.02, "torque", 1, True),
    ):
        assert other != base


_RACE = """
import sys, casadi as ca
from geosyn.core import codegen
def make():
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    y = ca.vertcat(ca.sin(x[0]) * x[1], x[0] ** 2 * u)
    return [ca.Function("gn_probe", [x, u], [y], ["x", "u"], ["y"])]
f = codegen.compile_recipe("geosyn_test_race", "race v1", make, sys.argv[1], load=["gn_probe"])
print(float(f["gn_probe"](1.0, 2.0)[1]))
"""


def test_compile_recipe_concurrent_processes_share_one_library(tmp_path: Path) -> None:
    """Two processes building the same recipe at once (a sweep's workers) both succeed and
    leave one library and one index (files appear by atomic renames)."""
    import subprocess
    import sys

    procs = [
        subprocess.Popen(
            [sys.executable, "-c", _RACE, str(tmp_path)], stdout=subprocess.PIPE, text=True
        )
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=300)[0] for p in procs]
    assert [p.returncode for p in procs] == [0, 0]
    assert [float(o.strip()) for o in outs] == [2.0, 2.0]  # x = (1, 1), u = 2: x0^2 u = 2
    assert len(list(tmp_path.glob("*.so"))) == 1
    assert len(list(tmp_path.glob("*.recipe"))) == 1
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tmp-geosyn-")]
