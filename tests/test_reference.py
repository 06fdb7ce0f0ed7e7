"""Tests of geosyn.controllers.reference: interpolation, holding, time scaling."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from conftest import get_metric
from geosyn.controllers import GeodesicReference, JointTrajectoryReference, ReferenceSample
from geosyn.core import InvalidArgument


class _Geo(NamedTuple):
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray


def rk4_geodesic(metric, q0, v0, duration, steps):
    """Independent geodesic integrator (classical RK4 on the geodesic ODE)."""
    h = duration / steps
    q, v = np.array(q0, float), np.array(v0, float)
    qs, vs = [q], [v]
    f = metric.geodesic_acceleration
    for _ in range(steps):
        k1q, k1v = v, f(q, v)
        k2q, k2v = v + 0.5 * h * k1v, f(q + 0.5 * h * k1q, v + 0.5 * h * k1v)
        k3q, k3v = v + 0.5 * h * k2v, f(q + 0.5 * h * k2q, v + 0.5 * h * k2v)
        k4q, k4v = v + h * k3v, f(q + h * k3q, v + h * k3v)
        q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
        v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        qs.append(q)
        vs.append(v)
    return _Geo(np.linspace(0.0, duration, steps + 1), np.array(qs), np.array(vs))


def _poly(coeffs, t):
    """Value, first and second derivative of sum c_p t^p for (P, n) coefficients."""
    P = coeffs.shape[0]
    pw = np.array([t**p for p in range(P)])
    d1 = np.array([p * t ** (p - 1) if p >= 1 else 0.0 for p in range(P)])
    d2 = np.array([p * (p - 1) * t ** (p - 2) if p >= 2 else 0.0 for p in range(P)])
    return pw @ coeffs, d1 @ coeffs, d2 @ coeffs


# -- JointTrajectoryReference ----------------------------------------------------------
@pytest.mark.parametrize("mode, degree", [("q", 3), ("qv", 3), ("qva", 5)])
def test_joint_trajectory_reproduces_polynomials(mode, degree):
    """Each interpolant reproduces polynomials of its degree exactly (between knots)."""
    rng = np.random.default_rng(0)
    n = 3
    coeffs = rng.normal(size=(degree + 1, n))
    t = np.sort(rng.uniform(0.2, 2.0, size=7))
    t[0], t[-1] = 0.2, 2.0
    samples = [_poly(coeffs, tk) for tk in t]
    q = np.array([s[0] for s in samples])
    v = np.array([s[1] for s in samples]) if "v" in mode else None
    a = np.array([s[2] for s in samples]) if "a" in mode else None
    ref = JointTrajectoryReference(t, q, v, a)
    assert ref.n == n and ref.t0 == pytest.approx(0.2) and ref.duration == pytest.approx(1.8)
    for tt in rng.uniform(0.2, 2.0, size=25):
        q_ref, v_ref, a_ref = ref.sample(tt)
        q_ex, v_ex, a_ex = _poly(coeffs, tt)
        np.testing.assert_allclose(q_ref, q_ex, atol=1e-10)
        np.testing.assert_allclose(v_ref, v_ex, atol=1e-9)
        np.testing.assert_allclose(a_ref, a_ex, atol=1e-8)


def test_joint_trajectory_holds_start_and_goal():
    t = np.array([1.0, 1.5, 2.0])
    q = np.array([[0.0, 1.0], [0.5, 0.5], [1.0, -1.0]])
    v = np.array([[1.0, 0.0], [1.0, -2.0], [1.0, -2.0]])
    ref = JointTrajectoryReference(t, q, v)
    before = ref.sample(0.5)
    after = ref.sample(3.0)
    assert isinstance(before, ReferenceSample)
    np.testing.assert_array_equal(before.q, q[0])
    np.testing.assert_array_equal(after.q, q[-1])
    for s in (before, after):
        np.testing.assert_array_equal(s.v, 0.0)
        np.testing.assert_array_equal(s.a, 0.0)
    np.testing.assert_array_equal(ref.goal(), q[-1])
    # Inside, the end points are interpolated exactly, velocities included.
    np.testing.assert_allclose(ref.sample(2.0).v, v[-1], atol=1e-12)
    # Samples are copies: mutating one does not change the reference.
    after.q[:] = 99.0
    np.testing.assert_array_equal(ref.goal(), q[-1])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"t": [0.0, 1.0, 0.5], "q": np.zeros((3, 2))}, "strictly increasing"),
        ({"t": [0.0], "q": np.zeros((1, 2))}, "T >= 2"),
        ({"t": [0.0, 1.0], "q": np.zeros((3, 2))}, r"shape \(T, n\)"),
        ({"t": [0.0, 1.0], "q": np.zeros((2, 2)), "v": np.zeros((2, 3))}, "v must have shape"),
        ({"t": [0.0, 1.0], "q": np.zeros((2, 2)), "a": np.zeros((2, 2))}, "without v"),
        ({"t": [0.0, 1.0], "q": [[0.0, np.nan], [0.0, 0.0]]}, "finite"),
    ],
)
def test_joint_trajectory_rejects_bad_input(kwargs, match):
    with pytest.raises(InvalidArgument, match=match):
        JointTrajectoryReference(**kwargs)


# -- GeodesicReference -----------------------------------------------------------------
@pytest.fixture(scope="module")
def panda_geodesic():
    metric = get_metric("panda")
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    v0 = 0.5 * np.array([1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
    coarse = rk4_geodesic(metric, q0, v0, 1.5, 100)
    fine = rk4_geodesic(metric, q0, v0, 1.5, 1000)
    return metric, coarse, fine


def test_geodesic_reference_matches_dense_geodesic(panda_geodesic):
    """Between the coarse knots the Hermite interpolant matches a 10x finer geodesic."""
    metric, coarse, fine = panda_geodesic
    ref = GeodesicReference(coarse, metric)
    assert ref.duration == pytest.approx(1.5) and ref.n == 7
    np.testing.assert_allclose(ref.goal(), coarse.q[-1])
    for k in range(5, 1000, 37):
        q_ref, v_ref, a_ref = ref.sample(fine.t[k])
        np.testing.assert_allclose(q_ref, fine.q[k], atol=1e-7)
        np.testing.assert_allclose(v_ref, fine.v[k], atol=1e-5)
        # The acceleration is the exact geodesic acceleration at the reference state.
        np.testing.assert_allclose(a_ref, metric.geodesic_acceleration(q_ref, v_ref), atol=1e-12)
        np.testing.assert_allclose(
            a_ref, metric.geodesic_acceleration(fine.q[k], fine.v[k]), atol=1e-3
        )


def test_geodesic_reference_velocity_is_derivative_of_position(panda_geodesic):
    metric, coarse, _ = panda_geodesic
    ref = GeodesicReference(coarse, metric)
    h = 1e-6
    for t in (0.1, 0.77, 1.3):
        fd = (ref.sample(t + h).q - ref.sample(t - h).q) / (2 * h)
        np.testing.assert_allclose(ref.sample(t).v, fd, atol=1e-7)


def test_geodesic_reference_without_metric_uses_spline_acceleration(panda_geodesic):
    metric, coarse, _ = panda_geodesic
    ref = GeodesicReference(coarse)
    h = 1e-6
    t = 0.4321
    fd = (ref.sample(t + h).v - ref.sample(t - h).v) / (2 * h)
    np.testing.assert_allclose(ref.sample(t).a, fd, atol=1e-6)
    # O(h^2)-accurate against the exact geodesic acceleration.
    q, v, a = ref.sample(t)
    np.testing.assert_allclose(a, metric.geodesic_acceleration(q, v), atol=5e-3)


@pytest.mark.parametrize("scale", [0.5, 2.0, 3.7])
def test_geodesic_reference_time_scaling(panda_geodesic, scale):
    """A geodesic run s times slower: same path, velocity / s, acceleration / s^2."""
    metric, coarse, _ = panda_geodesic
    ref1 = GeodesicReference(coarse, metric)
    refs = GeodesicReference(coarse, metric, time_scale=scale, t0=0.25)
    assert refs.duration == pytest.approx(1.5 * scale)
    for tau in (0.0, 0.3, 0.9, 1.5):
        q1, v1, a1 = ref1.sample(tau)
        qs, vs, as_ = refs.sample(0.25 + scale * tau)
        np.testing.assert_allclose(qs, q1, atol=1e-12)
        np.testing.assert_allclose(vs, v1 / scale, atol=1e-12)
        np.testing.assert_allclose(as_, a1 / scale**2, atol=1e-10)
        # A reparametrised geodesic is a geodesic: a = geodesic_acceleration(q, v).
        np.testing.assert_allclose(as_, metric.geodesic_acceleration(qs, vs), atol=1e-10)
    # Before t0 the start is held, after the end the goal, both at rest.
    s = refs.sample(0.1)
    np.testing.assert_allclose(s.q, coarse.q[0])
    np.testing.assert_array_equal(s.v, 0.0)
    s = refs.sample(0.25 + 1.5 * scale + 1e-3)
    np.testing.assert_allclose(s.q, coarse.q[-1])
    np.testing.assert_array_equal(s.a, 0.0)


class _Synergy:
    """Duck-typed synergy: metric, q0, v0 and trajectory(duration, steps)."""

    def __init__(self, metric, q0, v0):
        self.metric, self.q0, self.v0 = metric, q0, v0
        self.calls = []

    def trajectory(self, duration, steps):
        self.calls.append((duration, steps))
        return rk4_geodesic(self.metric, self.q0, self.v0, duration, steps)


def test_geodesic_reference_from_synergy(panda_geodesic):
    metric, _, fine = panda_geodesic
    syn = _Synergy(metric, fine.q[0], fine.v[0])
    ref = GeodesicReference(syn, duration=1.5, steps=150, time_scale=2.0)
    assert syn.calls == [(1.5, 150)]
    assert ref.metric is metric and ref.duration == pytest.approx(3.0)
    q, v, _ = ref.sample(1.8)  # geodesic time 0.9 = fine.t[600]
    np.testing.assert_allclose(q, fine.q[600], atol=1e-7)
    np.testing.assert_allclose(v, fine.v[600] / 2.0, atol=1e-5)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"time_scale": 0.0}, "time_scale"),
        ({"time_scale": np.inf}, "time_scale"),
        ({"t0": np.nan}, "t0"),
    ],
)
def test_geodesic_reference_rejects_bad_input(panda_geodesic, kwargs, match):
    metric, coarse, _ = panda_geodesic
    with pytest.raises(InvalidArgument, match=match):
        GeodesicReference(coarse, metric, **kwargs)


def test_geodesic_reference_rejects_bad_source(panda_geodesic):
    metric, coarse, _ = panda_geodesic
    with pytest.raises(InvalidArgument, match="source must be"):
        GeodesicReference(np.zeros(3), metric)
    with pytest.raises(InvalidArgument, match="metric has dimension 7"):
        GeodesicReference(_Geo(coarse.t, coarse.q[:, :3], coarse.v[:, :3]), metric)
    with pytest.raises(InvalidArgument, match="source.v"):
        GeodesicReference(_Geo(coarse.t, coarse.q, coarse.v[:-1]), metric)


def test_geodesic_reference_from_geodesic_synergy(panda_geodesic):
    """The library's GeodesicSynergy gives the same reference as the independent RK4."""
    from geosyn.synergies import GeodesicSynergy

    metric, _, fine = panda_geodesic
    ref = GeodesicReference(GeodesicSynergy(metric, fine.q[0], fine.v[0]), duration=1.5, steps=150)
    assert ref.metric is metric
    for k in (0, 300, 600, 1000):
        q, v, a = ref.sample(fine.t[k])
        np.testing.assert_allclose(q, fine.q[k], atol=1e-7)
        np.testing.assert_allclose(v, fine.v[k], atol=1e-5)


def test_rest_to_rest_timing_keeps_the_path_and_starts_and_ends_at_rest(panda_geodesic):
    metric, coarse, fine = panda_geodesic
    T = 2.0
    ref = GeodesicReference(coarse, metric, time_scale=T / 1.5, t0=0.1, rest_to_rest=True)
    assert ref.duration == pytest.approx(T)
    for t in (0.1, 0.1 + T):
        s = ref.sample(t)
        np.testing.assert_allclose(s.v, 0.0, atol=1e-12)
        np.testing.assert_allclose(s.a, 0.0, atol=1e-10)
    np.testing.assert_allclose(ref.sample(0.1).q, coarse.q[0], atol=1e-12)
    np.testing.assert_allclose(ref.sample(0.1 + T).q, coarse.q[-1], atol=1e-12)
    # Halfway in time is halfway along the geodesic (the quintic law is symmetric).
    np.testing.assert_allclose(ref.sample(0.1 + T / 2).q, fine.q[500], atol=1e-7)
    # Velocity and acceleration are the time derivatives of the position.
    h = 1e-5
    for t in (0.3, 0.9, 1.7):
        fd_v = (ref.sample(t + h).q - ref.sample(t - h).q) / (2 * h)
        fd_a = (ref.sample(t + h).v - ref.sample(t - h).v) / (2 * h)
        np.testing.assert_allclose(ref.sample(t).v, fd_v, atol=1e-7)
        np.testing.assert_allclose(ref.sample(t).a, fd_a, atol=2e-4)


@pytest.mark.parametrize("rest_to_rest", [False, True])
def test_interpolated_acceleration_is_close_to_exact(panda_geodesic, rest_to_rest):
    """exact_acceleration=False: quintic Hermite through exact knot accelerations."""
    metric, coarse, _ = panda_geodesic
    kw = {"time_scale": 1.3, "rest_to_rest": rest_to_rest}
    exact = GeodesicReference(coarse, metric, **kw)
    interp = GeodesicReference(coarse, metric, exact_acceleration=False, **kw)
    calls = []
    original = metric.geodesic_acceleration
    metric.geodesic_acceleration = lambda q, v: calls.append(1) or original(q, v)
    try:
        samples = [interp.sample(t) for t in np.linspace(0.0, 1.95, 40)]
    finally:
        del metric.geodesic_acceleration
    assert not calls  # no metric call per sample
    for t, s in zip(np.linspace(0.0, 1.95, 40), samples, strict=True):
        e = exact.sample(t)
        np.testing.assert_allclose(s.q, e.q, atol=1e-8)
        np.testing.assert_allclose(s.v, e.v, atol=1e-6)
        np.testing.assert_allclose(s.a, e.a, atol=1e-4)


def test_sequence_reference_plays_segments_in_turn():
    """Two cubic pieces of one polynomial (independent: the polynomial itself) played one
    after the other give the polynomial on both, and hold the end after the last."""
    from geosyn.controllers.sequence_reference import SequenceReference

    rng = np.random.default_rng(3)
    coeffs = rng.normal(size=(4, 2))
    pieces = []
    for t in (np.linspace(0.0, 1.0, 6), np.linspace(1.0, 2.5, 6)):
        s = [_poly(coeffs, tk) for tk in t]
        pieces.append(
            JointTrajectoryReference(t, np.array([x[0] for x in s]), np.array([x[1] for x in s]))
        )
    seq = SequenceReference(pieces)
    assert seq.n == 2 and seq.t0 == 0.0 and seq.duration == pytest.approx(2.5)
    for tt in rng.uniform(0.0, 2.5, size=20):
        np.testing.assert_allclose(seq.sample(tt).q, _poly(coeffs, tt)[0], atol=1e-10)
    np.testing.assert_allclose(seq.sample(9.0).q, _poly(coeffs, 2.5)[0], atol=1e-12)
    np.testing.assert_array_equal(seq.sample(9.0).v, 0.0)
    np.testing.assert_allclose(seq.goal(), _poly(coeffs, 2.5)[0], atol=1e-12)
    with pytest.raises(InvalidArgument, match="at least one"):
        SequenceReference([])
    with pytest.raises(InvalidArgument, match=r"segments\[1\].t0"):
        SequenceReference([pieces[0], pieces[0]])
