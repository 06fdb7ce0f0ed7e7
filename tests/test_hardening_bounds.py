"""Bounds that mean something (issue 23): the MPC's horizon and stage length, the QP's
control period, the interior-point solvers' tolerance and iteration limit are refused
outside their stated ranges with one geosyn error naming the argument, in the API and in
the config schema (which states them in ``geosyn schema``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers.mpc import GeodesicMPC, NLPOptions
from geosyn.controllers.mpc.nlp.options import MAX_ITER, MIN_TOL
from geosyn.controllers.mpc.ocp.settings import MAX_HORIZON, MAX_STAGE_DT, MIN_STAGE_DT
from geosyn.controllers.qp import MIN_DT, QPController
from geosyn.core import InvalidArgument

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


def test_the_edges_are_accepted() -> None:
    assert NLPOptions("ipopt", tol=MIN_TOL, max_iter=MAX_ITER).max_iter == MAX_ITER
    assert NLPOptions("fatrop", tol=1.0).tol == 1.0
    qp = QPController(get_robot("planar2"), 400.0, 40.0, MIN_DT)
    assert qp.dt == MIN_DT
    mpc = GeodesicMPC(
        get_robot("planar2"), get_metric("planar2"), horizon=3, dt=MAX_STAGE_DT, hessian="exact"
    )  # fmt: skip  (no compiled code: quick in a cold cache)
    assert mpc.dt == MAX_STAGE_DT and np.isfinite(mpc.dt)
