"""Smooth signed distances (`geosyn.world.smooth`) against the exact ones
(`geosyn.world.signed_distance`), on 10k seeded points per shape; the cylinder's exact
distance against a closed form; smoothness by the continuity of the Hessian."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from geosyn.world import Box, Capsule, Cylinder, HalfSpace, Sphere, signed_distance
from geosyn.world.pose import rotation_from_rpy
from geosyn.world.smooth import (
    error_bound,
    smooth_rounded_box_distance,
    smooth_signed_distance,
)

R = rotation_from_rpy([0.3, -0.4, 1.1])
SHAPES = {
    "box": (Box((0.1, 0.2, 0.3), (0.2, 0.05, 0.1), R), 3),
    "cylinder": (Cylinder((0.0, 0.0, 0.1), 0.05, 0.2, R), 2),
    "capsule": (Capsule((0.0, 0.0, 0.0), (0.3, 0.1, 0.0), 0.05), 3),
    "sphere": (Sphere((0.0, 0.1, 0.0), 0.1), 3),
    "half-space": (HalfSpace((0.0, 0.6, 0.8), 0.1), 3),
}


@pytest.mark.parametrize("name", list(SHAPES))
def test_smooth_distance_is_conservative_within_the_bound(name: str) -> None:
    shape, components = SHAPES[name]
    points = np.random.default_rng(11).uniform(-0.6, 0.6, (10_000, 3))
    err = smooth_signed_distance(shape, points) - signed_distance(shape, points)
    bound = error_bound(components=components)
    assert err.max() <= 1e-12  # never above the exact distance
    assert err.min() >= -bound
    assert bound < 2.5e-3
    # a sharper setting is closer, as its bound says
    sharp = smooth_signed_distance(shape, points, sharpness=2e4, delta=1e-5)
    err_sharp = sharp - signed_distance(shape, points)
    assert err_sharp.min() >= -error_bound(2e4, 1e-5, components) and err_sharp.max() <= 1e-12
    assert np.abs(err_sharp).max() < 0.2 * np.abs(err).max()


def test_cylinder_distance_closed_form() -> None:
    cyl = Cylinder((0.0, 0.0, 0.0), 0.1, 0.2)  # axis z
    pts = np.array([[0.3, 0.0, 0.0], [0.0, 0.0, 0.5], [0.4, 0.0, 0.6], [0.05, 0.0, 0.0]])
    expected = [0.2, 0.3, np.hypot(0.3, 0.4), -0.05]
    np.testing.assert_allclose(signed_distance(cyl, pts), expected, atol=1e-15)


def test_smooth_box_distance_has_a_continuous_hessian_across_an_edge() -> None:
    """Exact box distance: curvature jumps where the closest point leaves a face; smooth:
    the Hessian changes by O(step) between points 1e-7 m apart across that line."""
    f = smooth_rounded_box_distance()
    x = ca.SX.sym("x", 3)
    prm = Box((0.0, 0.0, 0.0), (0.1, 0.1, 0.1)).rounded_box()
    hess = ca.Function("h", [x], [ca.hessian(f(x, prm)[0], x)[0]])
    xs = np.linspace(0.1 - 1e-4, 0.1 + 1e-4, 2001)  # crossing x = h_x at y = 0.15, z = 0
    H = np.array([np.asarray(hess([xi, 0.15, 0.0])) for xi in xs])
    assert np.abs(np.diff(H, axis=0)).max() < 1e-2
    assert np.all(np.isfinite(H))
