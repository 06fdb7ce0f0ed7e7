"""Bounds that mean something (issue 23): the MPC's horizon and stage length, the QP's
control period, the interior-point solvers' tolerance and iteration limit are refused
outside their stated ranges with one geosyn error naming the argument, in the API and in
the config schema (which states them in ``geosyn schema``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers.mpc import DDPOptions, GeodesicMPC, NLPOptions
from geosyn.controllers.mpc.nlp.options import MAX_ITER, MIN_TOL
from geosyn.controllers.mpc.ocp.settings import (
    MAX_HORIZON,
    MAX_STAGE_DT,
    MIN_STAGE_DT,
    ocp_settings,
)
from geosyn.controllers.qp import MIN_DT, QPController
from geosyn.core import GeosynError, InvalidArgument
from geosyn.experiments import load_config
from geosyn.experiments.cli import main
from geosyn.experiments.errors import ConfigError

BAD_MPC = [
    {"horizon": 10**12},  # was std::bad_alloc after minutes of graph building
    {"horizon": MAX_HORIZON + 1},
    {"horizon": 0},
    {"dt": 1e300},
    {"dt": MAX_STAGE_DT * 1.01},
    {"dt": 1e-300},
    {"dt": MIN_STAGE_DT / 2},
    {"dt": math.nan},
    {"dt": -0.01},
]


@pytest.mark.parametrize("kwargs", BAD_MPC, ids=lambda k: f"{k}")
def test_mpc_refuses_absurd_horizons_and_stages(kwargs: dict[str, float]) -> None:
    (name,) = kwargs
    with pytest.raises(InvalidArgument, match=rf"^{name} must be"):
        GeodesicMPC(get_robot("planar2"), get_metric("planar2"), **kwargs)


@pytest.mark.parametrize("dt", [1e-300, MIN_DT / 2, 0.0, 1e300, math.inf])
def test_qp_refuses_absurd_periods(dt: float) -> None:
    with pytest.raises(InvalidArgument, match=r"^dt must be"):
        QPController(get_robot("planar2"), 400.0, 40.0, dt)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"tol": 1e-300},
        {"tol": MIN_TOL / 10},
        {"tol": 1e300},
        {"tol": 2.0},
        {"max_iter": 10**12},
        {"max_iter": MAX_ITER + 1},
        {"max_iter": 0},
    ],
    ids=lambda k: f"{k}",
)
def test_nlp_options_refuse_meaningless_tolerances_and_limits(kwargs: dict[str, float]) -> None:
    (name,) = kwargs
    with pytest.raises(InvalidArgument, match=rf"^{name} must be"):
        NLPOptions("fatrop", **kwargs)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"tol": 1e-300},
        {"tol": 2.0},
        {"max_iter": 10**12},
        {"max_iter": MAX_ITER + 1},
        {"warm_iterations": 10**12},
        {"warm_iterations": 0},
    ],
    ids=lambda k: f"{k}",
)
def test_ddp_options_refuse_meaningless_tolerances_and_limits(kwargs: dict[str, float]) -> None:
    (name,) = kwargs
    with pytest.raises(InvalidArgument, match=rf"^{name} must be"):
        DDPOptions(**kwargs)
    assert DDPOptions(tol=MIN_TOL, max_iter=MAX_ITER).max_iter == MAX_ITER  # the edges


def test_the_edges_are_accepted() -> None:
    assert NLPOptions("ipopt", tol=MIN_TOL, max_iter=MAX_ITER).max_iter == MAX_ITER
    assert NLPOptions("fatrop", tol=1.0).tol == 1.0
    qp = QPController(get_robot("planar2"), 400.0, 40.0, MIN_DT)
    assert qp.dt == MIN_DT
    mpc = GeodesicMPC(
        get_robot("planar2"), get_metric("planar2"), horizon=3, dt=MAX_STAGE_DT, hessian="exact"
    )  # fmt: skip  (no compiled code: quick in a cold cache)
    assert mpc.dt == MAX_STAGE_DT and np.isfinite(mpc.dt)


def _garbage(rng: np.random.Generator) -> object:
    """One seeded draw of a numeric input, sensible or not."""
    kind = int(rng.integers(9))
    magnitude = 10.0 ** rng.uniform(-320, 308)
    return [
        magnitude,
        -magnitude,
        int(rng.integers(-(2**62), 2**62)),
        10 ** int(rng.integers(0, 30)),
        [math.nan, math.inf, -math.inf, 0.0, -0.0][int(rng.integers(5))],
        bool(rng.integers(2)),
        complex(magnitude, 1.0),
        np.float32(rng.uniform(0, 2)),
        str(rng.uniform(0, 1)),
    ][kind]


def _inside(x: object, low: float, high: float, integer: bool) -> bool:
    if isinstance(x, bool | complex | str):
        return False
    if integer and not isinstance(x, int):
        return False
    return isinstance(x, int | float | np.floating) and low <= float(x) <= high


def test_fuzz_bounds_one_error_type() -> None:
    """600 seeded draws per argument: accepted exactly inside the stated range, else
    InvalidArgument naming the argument; no other exception, no hang (nothing is built)."""
    rng = np.random.default_rng(23)
    checks = {
        "horizon": (1, MAX_HORIZON, True),
        "dt": (MIN_STAGE_DT, MAX_STAGE_DT, False),
        "tol": (MIN_TOL, 1.0, False),
        "max_iter": (1, MAX_ITER, True),
    }
    base = {"horizon": 10, "dt": 0.02}
    for name, (low, high, integer) in checks.items():
        accepted = refused = 0
        for _ in range(600):
            x = _garbage(rng)
            try:
                if name in base:
                    args = {**base, name: x}
                    ocp_settings(2, args["horizon"], args["dt"], "torque", None, 1,
                                 1.0, 1.0, None, 1.0)  # fmt: skip
                else:
                    NLPOptions("ipopt", **{name: x})
            except InvalidArgument as err:
                assert str(err).startswith(f"{name} must be"), err
                assert not _inside(x, low, high, integer), (name, x, err)
                refused += 1
            else:
                assert _inside(x, low, high, integer), (name, x)
                accepted += 1
        assert accepted >= 3 and refused >= 300, (name, accepted, refused)  # both sides drawn


MPC_SET = "controllers=[{type: mpc, %s}]"


@pytest.mark.parametrize(
    "field, value",
    [
        ("horizon", "1000000000000"),
        ("dt", "1.0e+300"),
        ("dt", "1.0e-300"),
        ("solver", "{type: fatrop, tol: 1.0e-300}"),
        ("solver", "{type: ipopt, max_iter: 1000000000}"),
        ("solver", "{type: ddp, max_iter: 1000000000}"),
        ("solver", "{type: ddp, tol: 1.0e-300}"),
    ],
)
def test_schema_refuses_them_naming_the_field(field: str, value: str) -> None:
    with pytest.raises(ConfigError) as err:
        load_config("ur5_tracking", [MPC_SET % f"{field}: {value}"])
    assert isinstance(err.value, GeosynError) and f"controllers.0.{field}" in str(err.value)


def test_geosyn_schema_states_the_bounds(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schema", "mpc"]) == 0
    out = capsys.readouterr().out
    assert f"horizon: int >= 1, <= {MAX_HORIZON}" in out
    assert f"dt: float >= {MIN_STAGE_DT:g}, <= {MAX_STAGE_DT:g}" in out
    assert f"tol: float >= {MIN_TOL:g}, <= 1.0" in out
    assert f"max_iter: int >= 1, <= {MAX_ITER}" in out
