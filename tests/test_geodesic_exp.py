"""Tests of geosyn.metrics.geodesic.exp_map: the exponential map, and the per-metric
function cache it builds into."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.core.errors import InvalidArgument
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic import (
    Geodesic,
    distance,
    exp,
    log,
    parallel_transport,
    path_energy,
    straight_line,
)
from geosyn.metrics.geodesic.exp_map import numpy_rk4, rk4_step


class ConstantMetric(Metric):
    """A constant SPD metric: its geodesics are straight lines."""

    def __init__(self, G: np.ndarray) -> None:
        self._G = np.asarray(G, dtype=np.float64)
        self.n = self._G.shape[0]

    def G(self, q):
        return self._G.copy()

    def symbolic_G(self, q):
        return ca.SX(ca.DM(self._G))


class NumericOnly(Metric):
    """A metric without symbolic form, delegating to another metric's numeric methods."""

    def __init__(self, inner: Metric) -> None:
        self._inner = inner
        self.n = inner.n

    def G(self, q):
        return self._inner.G(q)

    def geodesic_acceleration(self, q, v):
        return self._inner.geodesic_acceleration(q, v)


def test_energy_conserved_panda():
    metric = get_metric("panda")
    rng = np.random.default_rng(1)
    q0 = get_robot("panda").random_q(rng, margin=0.3)
    v0 = rng.uniform(-1.5, 1.5, 7)
    geo = exp(metric, q0, v0, duration=1.0, steps=1000)
    assert isinstance(geo, Geodesic)
    assert geo.t.shape == (1001,) and geo.q.shape == (1001, 7) and geo.v.shape == (1001, 7)
    # Reference: pin.crba mass matrix at every sample.
    energy = np.array([0.5 * v @ metric.G(q) @ v for q, v in zip(geo.q, geo.v, strict=True)])
    drift = np.max(np.abs(energy - energy[0])) / energy[0]
    assert drift <= 1e-8, f"relative energy drift {drift:.2e}"
    # The motion is not trivial.
    assert np.linalg.norm(geo.q[-1] - q0 - v0) > 1e-2


def test_cyclic_momentum_conserved_planar2():
    metric = get_metric("planar2")
    geo = exp(metric, np.array([0.3, -0.7]), np.array([1.2, -2.5]), duration=2.0, steps=1000)
    # M does not depend on q1, so p1 = (M qdot)_1 is a conserved momentum.
    p1 = np.array([(metric.G(q) @ v)[0] for q, v in zip(geo.q, geo.v, strict=True)])
    assert np.max(np.abs(p1 - p1[0])) <= 1e-10
    assert np.ptp(geo.v[:, 0]) > 0.1  # joint velocity itself is not constant


def test_constant_metric_gives_straight_lines():
    A = np.array([[2.0, 0.3, 0.1], [0.3, 1.0, -0.2], [0.1, -0.2, 0.5]])
    metric = ConstantMetric(A)
    q0 = np.array([0.1, -0.4, 0.8])
    v0 = np.array([1.0, 2.0, -0.5])
    geo = exp(metric, q0, v0, duration=1.5, steps=30)
    np.testing.assert_allclose(geo.q, q0 + geo.t[:, None] * v0, atol=1e-14)
    np.testing.assert_allclose(geo.v, np.repeat(v0[None], 31, axis=0), atol=1e-14)
    q1 = np.array([1.0, 0.0, -1.0])
    np.testing.assert_allclose(log(metric, q0, q1), q1 - q0, atol=1e-12)
    d = q1 - q0
    assert distance(metric, q0, q1) == pytest.approx(np.sqrt(d @ A @ d), rel=1e-12)
    line = straight_line(q0, q1, steps=7)
    assert path_energy(metric, line.t, line.q) == pytest.approx(0.5 * d @ A @ d, rel=1e-12)


def test_planar2_straight_line_with_folded_elbow_fixed():
    metric = get_metric("planar2")
    geo = exp(metric, np.array([0.4, 0.0]), np.array([1.3, 0.0]), duration=1.0, steps=200)
    assert np.max(np.abs(geo.q[:, 1])) <= 1e-14
    np.testing.assert_allclose(geo.q[:, 0], 0.4 + 1.3 * geo.t, atol=1e-12)


def test_rk4_agrees_with_dop853_and_has_order_four():
    metric = get_metric("panda")
    rng = np.random.default_rng(3)
    q0 = get_robot("panda").random_q(rng, margin=0.3)
    v0 = rng.uniform(-2.0, 2.0, 7)
    ref = exp(metric, q0, v0, duration=1.0, steps=800, method="dop853")
    fine = exp(metric, q0, v0, duration=1.0, steps=800, method="rk4")
    assert np.max(np.abs(fine.q - ref.q)) <= 1e-8
    assert np.max(np.abs(fine.v - ref.v)) <= 1e-8
    errors = [np.linalg.norm(exp(metric, q0, v0, steps=s).q[-1] - ref.q[-1]) for s in (10, 20, 40)]
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert all(12.0 < r < 20.0 for r in ratios), f"error ratios {ratios}, errors {errors}"


def test_numeric_fallback_matches_compiled():
    inner = get_metric("planar2")
    metric = NumericOnly(inner)
    q0, v0 = np.array([0.5, 1.0]), np.array([-1.0, 2.0])
    a = exp(metric, q0, v0, steps=50)
    b = exp(inner, q0, v0, steps=50)
    np.testing.assert_allclose(a.q, b.q, atol=1e-12)
    np.testing.assert_allclose(a.v, b.v, atol=1e-12)
    q1 = np.array([1.1, 0.4])
    np.testing.assert_allclose(
        log(metric, q0, q1, steps=50), log(inner, q0, q1, steps=50), atol=1e-8
    )
    u, w = np.array([1.0, -0.5]), np.array([0.3, 0.7])
    A = parallel_transport(metric, a.t, a.q, np.column_stack([u, w]), qdot=a.v)
    B = parallel_transport(inner, a.t, a.q, np.column_stack([u, w]), qdot=a.v)
    np.testing.assert_allclose(A, B, atol=1e-8)
    assert rk4_step(metric) is None and len(metric.functions) == 0  # nothing was built


def test_bad_input_raises_clear_errors():
    metric = get_metric("planar2")
    q0 = np.zeros(2)
    with pytest.raises(InvalidArgument, match="v0 must have shape"):
        exp(metric, q0, np.zeros(3))
    with pytest.raises(InvalidArgument, match="steps"):
        exp(metric, q0, q0, steps=0)
    with pytest.raises(InvalidArgument, match="duration"):
        exp(metric, q0, q0, duration=-1.0)
    with pytest.raises(InvalidArgument, match="method"):
        exp(metric, q0, q0, method="euler")
    with pytest.raises(InvalidArgument, match="q0 must be finite"):
        exp(metric, np.array([np.nan, 0.0]), q0)
    with pytest.raises(InvalidArgument, match="metric"):
        exp("planar2", q0, q0)  # type: ignore[arg-type]


def test_functions_are_kept_per_metric_and_cleared_by_one_call():
    """The RK4 step lives in ``metric.functions`` (not in a module-level cache);
    ``metric.functions.clear()`` forgets it and the next call rebuilds the same thing."""
    metric = KineticEnergyMetric(get_robot("planar2"))  # its own cache, not the shared one
    other = KineticEnergyMetric(get_robot("planar2"))
    q0, v0 = np.array([0.1, 0.2]), np.array([0.5, -0.5])
    a = exp(metric, q0, v0, steps=17)
    step = rk4_step(metric)
    assert step is not None and step is rk4_step(metric)  # built once, kept
    assert "geodesic_rk4_step" in metric.functions and ("geodesic_rk4", 17) in metric.functions
    assert len(other.functions) == 0  # another metric object has its own cache
    builds = metric.functions.builds
    metric.functions.clear()
    assert len(metric.functions) == 0
    b = exp(metric, q0, v0, steps=17)
    np.testing.assert_array_equal(a.q, b.q)
    assert rk4_step(metric) is not step and metric.functions.builds == builds + 2


class _ParameterisedMetric(Metric):
    """G(q) = diag(1 + p q_i^2): a metric whose shape is a run-time parameter p."""

    def __init__(self) -> None:
        self.n = 2
        self.p = 0.0
        self._p_sym = ca.SX.sym("p")

    def G(self, q):  # noqa: N802
        q = self._check(q, "q")
        return np.diag(1.0 + self.p * q**2)

    def symbolic_G(self, q):  # noqa: N802
        return ca.diag(1.0 + self._p_sym * q**2)

    def symbolic_parameters(self):
        return self._p_sym

    def parameter_values(self):
        return np.array([self.p])


def test_parameters_change_geodesics_without_rebuild() -> None:
    """exp/log/transport read metric parameters at call time; changing one rebuilds nothing."""
    metric = _ParameterisedMetric()
    q0, v0 = np.array([0.5, -0.3]), np.array([1.0, 0.4])
    flat = exp(metric, q0, v0, steps=200)
    np.testing.assert_allclose(flat.q[-1], q0 + v0, atol=1e-12)  # p = 0: straight line
    step_before = rk4_step(metric)
    metric.p = 2.0
    curved = exp(metric, q0, v0, steps=200)
    assert rk4_step(metric) is step_before, "no rebuild on a parameter change"
    # Reference: the same metric integrated by the numpy RK4 path on G's closed form.
    ref = numpy_rk4(metric, q0, v0, 1.0 / 200, 200)
    np.testing.assert_allclose(curved.q[-1], ref[-1, :2], atol=1e-10)
    assert np.abs(curved.q[-1] - flat.q[-1]).max() > 0.05
    # Energy 1/2 v^T G v is conserved under the parameterised metric too.
    e = 0.5 * np.einsum("ti,ti->t", curved.v**2, 1.0 + 2.0 * curved.q**2)
    assert np.ptp(e) / e[0] < 1e-8
    v_back = log(metric, q0, curved.q[-1], steps=200)
    np.testing.assert_allclose(v_back, v0, atol=1e-8)
    u = parallel_transport(metric, curved.t, curved.q, v0, qdot=curved.v)
    np.testing.assert_allclose(u, curved.v[-1], atol=1e-8)


@pytest.mark.parametrize("speed", [1e5, 1e8])
def test_dop853_with_a_huge_velocity_is_bounded(monkeypatch, speed):
    """Issue 23: |v0| = 1e5 took 206 s and 1e8 never returned; now at most
    MAX_DOP853_EVALUATIONS evaluations (lowered here to keep the test short), then
    GeodesicNotFound."""
    from geosyn.metrics.errors import GeodesicNotFound
    from geosyn.metrics.geodesic import exp_map

    metric = get_metric("planar2")
    calls = []
    real = metric.geodesic_acceleration
    monkeypatch.setattr(metric, "geodesic_acceleration", lambda q, v: calls.append(1) or real(q, v))
    monkeypatch.setattr(exp_map, "MAX_DOP853_EVALUATIONS", 5_000)
    with pytest.raises(GeodesicNotFound, match="MAX_DOP853_EVALUATIONS = 5000"):
        exp(metric, np.array([0.2, 0.3]), np.array([speed, -speed]), method="dop853")
    assert len(calls) == 5_000
    # a moderate velocity within the budget matches the compiled RK4 (1000 steps)
    v0 = np.array([1.0, -0.5])
    a = exp(metric, np.array([0.2, 0.3]), v0, method="dop853")
    b = exp(metric, np.array([0.2, 0.3]), v0, steps=1000)
    np.testing.assert_allclose(a.q[-1], b.q[-1], atol=1e-10)


class _Exploding(ConstantMetric):
    """A metric whose geodesic acceleration turns NaN once |v| > 1.5 (after t = 0.4 s from
    |v0| = 1, as qdd = v) and whose symbolic form divides by zero while it is built (a
    singular G folded into constants)."""

    def geodesic_acceleration(self, q, v):
        v = np.asarray(v)
        return np.where(np.abs(v) > 1.5, np.nan, v)

    def symbolic_geodesic_acceleration(self, q, v):
        return ca.SX(1.0 / 0.0)


def test_blow_ups_inside_exp_are_nonfinite_results_not_other_errors():
    """Issue 23: a singular metric gave a ZeroDivisionError, and a NaN state inside DOP853
    an InvalidArgument blaming the caller's q."""
    from geosyn.metrics.errors import NonFiniteResult

    metric = _Exploding(np.eye(2))
    with pytest.raises(NonFiniteResult, match="divides by zero"):
        exp(metric, np.zeros(2), np.ones(2))
    with pytest.raises(NonFiniteResult, match="left the float64 range"):
        exp(metric, np.zeros(2), np.ones(2), method="dop853")
