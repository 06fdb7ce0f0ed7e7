"""Signed distances of world shapes: numeric against brute-force closest points, symbolic
against numeric, gradients against finite differences."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import minimize, minimize_scalar

from geosyn.world import (
    HALFSPACE_EXTENT,
    Box,
    Capsule,
    HalfSpace,
    InvalidGeometry,
    Sphere,
    signed_distance,
)
from geosyn.world.distance import rounded_box_distance


def _rot(axis, angle: float) -> np.ndarray:
    return pin.exp3(np.asarray(axis, dtype=float) / np.linalg.norm(axis) * angle)


SHAPES = [
    Sphere((0.3, -0.2, 0.5), 0.15),
    Box((0.1, 0.2, -0.3), (0.2, 0.05, 0.3), _rot([1, 2, 3], 0.7)),
    Box((0.0, 0.0, 0.0), (0.1, 0.0, 0.2)),  # flat: zero thickness along y
    Capsule((-0.2, 0.1, 0.0), (0.3, 0.4, 0.2), 0.08),
    Capsule((0.2, 0.2, 0.2), (0.2, 0.2, 0.2), 0.1),  # zero length: a ball
    HalfSpace(np.array([0.2, -0.3, 1.0]) / np.linalg.norm([0.2, -0.3, 1.0]), 0.05),
]
IDS = ["sphere", "box", "flat_box", "capsule", "ball_capsule", "halfspace"]


def _points(shape, rng: np.random.Generator, n: int = 60) -> np.ndarray:
    """Points around the shape: a wide cloud about its rounded-box centre and a tight one
    (mostly inside the shape)."""
    c = shape.rounded_box()[:3] if not isinstance(shape, HalfSpace) else np.zeros(3)
    wide = c + rng.normal(scale=0.3, size=(n - n // 3, 3))
    return np.vstack([wide, c + rng.normal(scale=0.03, size=(n // 3, 3))])


def _brute_force(shape, x: np.ndarray) -> float:
    """Signed distance by numerical minimisation over the shape (outside) or by the distance
    to the nearest face (inside a box); independent of geosyn's closed forms."""
    if isinstance(shape, Sphere):
        return float(np.linalg.norm(x - shape.center) - shape.radius)
    if isinstance(shape, HalfSpace):
        n = np.asarray(shape.normal)
        foot = x - (n @ x - shape.offset) * n  # projection onto the plane
        return float(np.sign(n @ x - shape.offset) * np.linalg.norm(x - foot))
    if isinstance(shape, Capsule):
        a, b = np.asarray(shape.p0), np.asarray(shape.p1)
        res = minimize_scalar(
            lambda t: np.sum((a + t * (b - a) - x) ** 2),
            bounds=(0.0, 1.0),
            method="bounded",
            options={"xatol": 1e-12},
        )
        return float(np.sqrt(res.fun) - shape.radius)
    R, c, h = np.asarray(shape.rotation), np.asarray(shape.center), np.asarray(shape.half_extents)
    local = R.T @ (x - c)
    if np.all(np.abs(local) <= h):  # inside: the nearest face
        return -float(np.min(h - np.abs(local)))
    res = minimize(
        lambda u: np.sum((c + R @ u - x) ** 2),
        np.zeros(3),
        jac=lambda u: 2.0 * R.T @ (c + R @ u - x),
        bounds=list(zip(-h, h, strict=True)),
        method="L-BFGS-B",
        options={"ftol": 1e-15, "gtol": 1e-12},
    )
    return float(np.sqrt(res.fun))


@pytest.mark.parametrize("shape", SHAPES, ids=IDS)
def test_signed_distance_matches_brute_force(shape) -> None:
    rng = np.random.default_rng(10)
    pts = _points(shape, rng)
    sd = signed_distance(shape, pts)
    ref = np.array([_brute_force(shape, x) for x in pts])
    assert sd.shape == (len(pts),)
    np.testing.assert_allclose(sd, ref, atol=1e-7)
    if not isinstance(shape, HalfSpace):
        assert (sd < 0).any() or isinstance(shape, Box) and min(shape.half_extents) == 0.0
        assert (sd > 0).any()


@pytest.mark.parametrize("shape", SHAPES, ids=IDS)
def test_symbolic_equals_numeric(shape) -> None:
    """The CasADi rounded-box distance equals the numeric one to 1e-12 m outside; inside
    it is larger by exactly the 1e-12 m of its regularised square root."""
    f = rounded_box_distance()
    prm = shape.rounded_box()
    rng = np.random.default_rng(11)
    pts = _points(shape, rng)
    sym = np.array([float(f(x, prm)[0]) for x in pts])
    num = signed_distance(shape, pts)
    out = num > 0.0
    np.testing.assert_allclose(sym[out], num[out], rtol=0, atol=1e-12)
    if isinstance(shape, Box | HalfSpace):  # inside a box the closest-point term is 0
        np.testing.assert_allclose(sym[~out], num[~out] + 1e-12, rtol=0, atol=1e-13)
    else:
        np.testing.assert_allclose(sym[~out], num[~out], rtol=0, atol=1e-12)


@pytest.mark.parametrize("shape", SHAPES, ids=IDS)
def test_symbolic_gradient_is_the_distance_gradient(shape) -> None:
    """Outside the shape, d sd / dx matches central differences of the numeric distance and
    is a unit vector (the distance is a Euclidean distance)."""
    f = rounded_box_distance()
    prm = shape.rounded_box()
    rng = np.random.default_rng(12)
    pts = [x for x in _points(shape, rng, 200) if signed_distance(shape, x)[0] > 1e-3][:20]
    assert len(pts) == 20
    step = 1e-6
    for x in pts:
        grad = np.asarray(f(x, prm)[1]).ravel()
        fd = np.array(
            [
                (signed_distance(shape, x + step * e)[0] - signed_distance(shape, x - step * e)[0])
                / (2 * step)
                for e in np.eye(3)
            ]
        )
        np.testing.assert_allclose(grad, fd, atol=1e-6)
        assert np.linalg.norm(grad) == pytest.approx(1.0, abs=1e-9)


def test_halfspace_is_exact_within_the_extent() -> None:
    """The half-space's cube gives n . x - offset up to 100 m from the origin's foot point."""
    shape = HalfSpace((0.0, 0.6, 0.8), -0.3)
    rng = np.random.default_rng(13)
    pts = rng.uniform(-0.5 * HALFSPACE_EXTENT, 0.5 * HALFSPACE_EXTENT, size=(50, 3))
    f = rounded_box_distance()
    sym = np.array([float(f(x, shape.rounded_box())[0]) for x in pts])
    exact = pts @ np.array([0.0, 0.6, 0.8]) + 0.3
    np.testing.assert_allclose(sym, exact, rtol=0, atol=1e-11)
    np.testing.assert_allclose(signed_distance(shape, pts), exact, rtol=0, atol=1e-12)


def test_single_point_and_non_shapes() -> None:
    assert signed_distance(Sphere((0, 0, 0), 1.0), np.array([3.0, 0.0, 0.0])).tolist() == [2.0]
    with pytest.raises(InvalidGeometry, match=r"shape is a dict"):
        signed_distance({"center": (0, 0, 0)}, np.zeros((1, 3)))  # type: ignore[arg-type]
