"""Tests of geosyn.metrics.geodesic.transport: parallel transport along sampled curves."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.core.errors import InvalidArgument
from geosyn.metrics.geodesic import exp, parallel_transport


def test_transport_along_geodesic_panda():
    metric = get_metric("panda")
    rng = np.random.default_rng(17)
    q0 = get_robot("panda").random_q(rng, margin=0.3)
    geo = exp(metric, q0, rng.uniform(-1.0, 1.0, 7), 1.0, 200)
    U = rng.standard_normal((7, 3))
    W = parallel_transport(metric, geo.t, geo.q, U, qdot=geo.v)
    gram0 = U.T @ metric.G(geo.q[0]) @ U
    gram1 = W.T @ metric.G(geo.q[-1]) @ W
    assert np.max(np.abs(gram1 - gram0)) <= 1e-8
    # Column-wise transport equals the batched one.
    np.testing.assert_allclose(
        parallel_transport(metric, geo.t, geo.q, U[:, 1], qdot=geo.v), W[:, 1], atol=1e-14
    )
    # A geodesic's velocity is parallel along it.
    vT = parallel_transport(metric, geo.t, geo.q, geo.v[0], qdot=geo.v)
    assert np.max(np.abs(vT - geo.v[-1])) <= 1e-8
    # Transporting back returns the vectors.
    back = parallel_transport(metric, geo.t[::-1], geo.q[::-1], W, qdot=geo.v[::-1])
    assert np.max(np.abs(back - U)) <= 1e-8
    # The transport is not the identity.
    assert np.max(np.abs(W - U)) > 1e-3


def test_transport_along_any_curve_preserves_inner_product():
    metric = get_metric("planar2")
    t = np.linspace(0.0, 2.0, 401)
    q = np.column_stack([np.sin(t), 1.5 * np.cos(2 * t)])  # not a geodesic
    U = np.array([[1.0, 0.2], [-0.5, 1.0]])
    W = parallel_transport(metric, t, q, U)  # qdot from finite differences
    np.testing.assert_allclose(W.T @ metric.G(q[-1]) @ W, U.T @ metric.G(q[0]) @ U, atol=1e-8)
    back = parallel_transport(metric, t[::-1], q[::-1], W)
    np.testing.assert_allclose(back, U, atol=1e-8)


def test_bad_input_raises_clear_errors():
    metric = get_metric("planar2")
    t, q = np.linspace(0, 1, 5), np.zeros((5, 2))
    with pytest.raises(InvalidArgument, match="v must have shape"):
        parallel_transport(metric, t, q, np.zeros(3))
    with pytest.raises(InvalidArgument, match="substeps"):
        parallel_transport(metric, t, q, np.zeros(2), substeps=0)
    with pytest.raises(InvalidArgument, match="qdot must be finite"):
        parallel_transport(metric, t, q, np.zeros(2), qdot=np.zeros((4, 2)))


def test_reversed_time_axis_and_wrong_types_are_refused():
    """Issue 23: a time axis reversed without its samples made the given qdot point the
    other way (the Hermite curve then left the path): refused; booleans and complex
    values are refused instead of cast."""
    metric = get_metric("planar2")
    geo = exp(metric, np.array([0.2, 0.3]), np.array([0.8, -0.5]), 1.0, 50)
    u = np.array([1.0, 0.5])
    with pytest.raises(InvalidArgument, match="qdot is not the derivative of q along t"):
        parallel_transport(metric, geo.t[::-1], geo.q, u, qdot=geo.v)
    # the consistent reversal (t, q and qdot together) is a transport back: allowed
    w = parallel_transport(metric, geo.t, geo.q, u, qdot=geo.v)
    back = parallel_transport(metric, geo.t[::-1], geo.q[::-1], w, qdot=geo.v[::-1])
    np.testing.assert_allclose(back, u, atol=1e-8)
    for kwargs, match in (
        ({"v": np.array([True, False])}, "v must be a float array, got booleans"),
        ({"v": u + 1j}, "v must be a real"),
        ({"qdot": geo.v.astype(complex)}, "qdot must be a real"),
        ({"t": geo.t > 0.5}, "t must be a float array, got booleans"),
    ):
        args = {"t": geo.t, "q": geo.q, "v": u, "qdot": geo.v} | kwargs
        with pytest.raises(InvalidArgument, match=match):
            parallel_transport(metric, **args)
