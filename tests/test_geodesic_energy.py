"""Tests of geosyn.metrics.geodesic.energy: path energy and the straight-line baseline
(the distance is tested with the log map it relies on, in test_geodesic_log.py)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import get_metric
from geosyn.core.errors import InvalidArgument
from geosyn.metrics.geodesic import exp, path_energy, straight_line


def test_path_energy_converges_at_second_order():
    metric = get_metric("planar2")
    q0, v0 = np.array([0.1, 0.5]), np.array([1.0, -2.0])
    exact = 0.5 * v0 @ metric.G(q0) @ v0  # constant speed along a geodesic
    errors = []
    for steps in (20, 40, 80):
        geo = exp(metric, q0, v0, 1.0, steps, method="dop853")
        errors.append(abs(path_energy(metric, geo.t, geo.q) - exact))
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert all(3.0 < r < 5.0 for r in ratios), f"ratios {ratios}, errors {errors}"


def test_straight_line_and_two_sample_energy():
    q0, q1 = np.array([0.1, -0.2]), np.array([0.7, 0.4])
    line = straight_line(q0, q1, duration=2.0, steps=4)
    np.testing.assert_allclose(line.q[[0, -1]], [q0, q1], atol=1e-15)
    np.testing.assert_allclose(line.v, np.tile((q1 - q0) / 2.0, (5, 1)), atol=1e-15)
    # Two samples: the constant slope, integrated by the trapezoidal rule.
    metric = get_metric("planar2")
    qd = (q1 - q0) / 2.0
    f0, f1 = qd @ metric.G(q0) @ qd, qd @ metric.G(q1) @ qd
    e2 = path_energy(metric, line.t[[0, -1]], line.q[[0, -1]])
    assert e2 == pytest.approx(0.5 * 2.0 * 0.5 * (f0 + f1), rel=1e-14)


def test_bad_input_raises_clear_errors():
    metric = get_metric("planar2")
    q0 = np.zeros(2)
    with pytest.raises(InvalidArgument, match="q1 must have shape"):
        straight_line(q0, np.zeros(3))
    with pytest.raises(InvalidArgument, match="q must have shape"):
        path_energy(metric, np.linspace(0, 1, 5), np.zeros((4, 2)))
    with pytest.raises(InvalidArgument, match="t must be strictly monotonic"):
        path_energy(metric, np.array([0.0, 1.0, 0.5]), np.zeros((3, 2)))
    with pytest.raises(InvalidArgument, match="steps"):
        straight_line(q0, q0, steps=0)
