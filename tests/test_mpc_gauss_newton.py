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
from geosyn.controllers.mpc.dynamics import stage_dynamics
from geosyn.controllers.mpc.gauss_newton import compiled_dynamics, zero_curvature_library
from geosyn.controllers.mpc.settings import DEFAULT_EFFORT_WEIGHT, ocp_settings
from geosyn.core import InvalidArgument, codegen
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
    assert clear_cache() == 2  # the .so and its .c


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
    assert clear_cache() == 3 and not any(cache.iterdir())  # .so, .c and that folder


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
    monkeypatch.setattr(codegen, "find_compiler", lambda: None)
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
    monkeypatch.setattr(codegen, "find_compiler", lambda: None)
    with pytest.raises(CodegenError, match="no C compiler"):
        zero_curvature_library([_probe()], "geosyn_test_gn")
