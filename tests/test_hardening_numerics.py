"""Numerical blow-ups stop where they start, long calls are bounded, limits can be raised."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers import JointTrajectoryReference
from geosyn.controllers.qp import QPController
from geosyn.core import InvalidArgument
from geosyn.experiments.errors import ConfigError
from geosyn.metrics import exp
from geosyn.metrics.errors import NonFiniteResult
from geosyn.world import InvalidGeometry, Payload

Q = np.array([0.2, 0.3])


@pytest.mark.parametrize("speed", [1e4, 1e6])
def test_exp_with_a_huge_velocity_raises_instead_of_returning_nan(speed):
    with pytest.raises(NonFiniteResult, match=r"exp: the geodesic left the float64 range at t="):
        exp(get_metric("planar2"), Q, np.array([speed, speed]))
    geo = exp(get_metric("planar2"), Q, np.array([1e2, 1e2]))  # large but representable
    assert np.isfinite(geo.q).all() and np.isfinite(geo.v).all()


def test_overflowing_velocities_raise_and_finite_large_results_pass():
    metric = get_metric("planar2")
    for fn in (metric.geodesic_acceleration, metric.coriolis):
        # refused at the boundary (issue 23): its squared norm is not a float64
        with pytest.raises(InvalidArgument, match="v is too large to compute with"):
            fn(Q, np.array([1e200, -1e200]))
    # |v| ~ 1e150: the result ~ 1e300 is finite (its squared norm overflows): returned
    a = metric.geodesic_acceleration(Q, np.array([1e150, 1e150]))
    assert np.isfinite(a).all() and np.abs(a).max() > 1e299
    # and it equals the scaled value at unit speed (C(q, v) v is quadratic in v)
    np.testing.assert_allclose(
        a, 1e300 * metric.geodesic_acceleration(Q, np.array([1.0, 1.0])), rtol=1e-12
    )


def test_payload_mass_is_bounded():
    with pytest.raises(InvalidGeometry, match=r"Payload.mass must be in \[0, 100000\]"):
        Payload("link2", 1e30)
    assert Payload("link2", 1e5).mass == 1e5


def test_qp_tick_is_bounded_under_velocity_noise():
    """Under v noise (std 2 rad/s) proxsuite's defaults took a million inner iterations
    (8 s) for one tick; the bound max_iter * max_inner_iter holds and a solve that hits it
    falls back, flagged."""
    robot = get_robot("panda")
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    ref = JointTrajectoryReference(np.array([0.0, 1.0]), np.stack([q0, q0 + 0.2]))
    qp = QPController(robot, 900.0, 60.0, 1e-3, reference=ref)
    assert (qp.max_iter, qp.max_inner_iter) == (100, 30)
    assert (qp.qp.settings.max_iter, qp.qp.settings.max_iter_in) == (100, 30)
    rng = np.random.default_rng(0)
    qp.reset(q0, np.zeros(7))
    statuses = set()
    for k in range(40):
        v = rng.normal(0.0, 2.0, 7)
        tau = qp.compute(k * 1e-3, q0 + 0.01 * k, v)
        info = qp.qp.results.info
        assert info.iter_ext <= 100 and info.iter <= 100 * 30
        assert np.isfinite(tau).all()
        d = qp.diagnostics
        statuses.add(d.solver_status)
        assert d.fallback_used == (d.solver_status != "ok")
    assert "ok" in statuses


def test_simulation_log_size_is_bounded():
    from geosyn.controllers import ComputedTorque
    from geosyn.sim import Simulation

    robot = get_robot("planar2")
    sim = Simulation(robot, ComputedTorque(robot, 100.0, 10.0))
    with pytest.raises(InvalidArgument, match="MAX_LOG_BYTES"):
        sim.run(Q, None, 1e9)


def test_tick_limit_can_be_raised(monkeypatch):
    from geosyn.experiments.config.loader import load_config

    bomb = ["simulation.duration=2000", "params.duration=1.0", "outputs.plots=false"]
    with pytest.raises(
        ConfigError, match=r"simulation.duration: 2000 s .* GEOSYN_MAX_TICKS=2000000"
    ):
        load_config("planar2_geodesic_vs_euclidean", bomb)
    monkeypatch.setenv("GEOSYN_MAX_TICKS", "2000000")
    cfg, _ = load_config("planar2_geodesic_vs_euclidean", bomb)
    assert cfg.simulation.duration == 2000
    monkeypatch.setenv("GEOSYN_MAX_TICKS", "many")
    with pytest.raises(ConfigError, match="GEOSYN_MAX_TICKS: must be a positive integer"):
        load_config("planar2_geodesic_vs_euclidean", bomb)


@pytest.mark.parametrize(
    "bad", [np.array([True, False]), [True, False], (0.2, np.bool_(True)), np.bool_(True)]
)
def test_check_vector_refuses_booleans(bad):
    from geosyn.core.validation import check_vector

    with pytest.raises(InvalidArgument, match=r"q must be a float array of shape \(2,\), got bool"):
        check_vector(bad, 2, "q")
    # integers are still numbers: read as floats
    np.testing.assert_array_equal(check_vector(np.array([1, 0]), 2, "q"), [1.0, 0.0])
