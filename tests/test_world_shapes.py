"""World shapes: validation with one set of tolerances, rounded-box parameters, moves."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from geosyn.core import InvalidArgument
from geosyn.world import (
    HALFSPACE_EXTENT,
    Box,
    Capsule,
    HalfSpace,
    InvalidGeometry,
    Sphere,
    signed_distance,
)
from geosyn.world.shapes import ROUNDED_BOX_SIZE, check_shape
from geosyn.world.validation import ROTATION_TOL, UNIT_TOL


def _rot(axis, angle: float) -> np.ndarray:
    return pin.exp3(np.asarray(axis, dtype=float) / np.linalg.norm(axis) * angle)


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda: Sphere((0, 0), 0.1), "Sphere.center"),
        (lambda: Sphere((0, 0, np.nan), 0.1), "Sphere.center"),
        (lambda: Sphere((0, 0, 0), 0.0), "Sphere.radius"),
        (lambda: Sphere((0, 0, 0), "big"), "Sphere.radius"),
        (lambda: Capsule((0, 0, 0), (1, 0), 0.1), "Capsule.p1"),
        (lambda: Capsule((0, 0, 0), (1, 0, 0), -0.1), "Capsule.radius"),
        (lambda: Box((0, 0, 0), (0.1, -0.1, 0.1)), "Box.half_extents"),
        (lambda: Box((0, 0, 0), (0.1, 0.1, 0.1), np.diag([1.0, 1.0, -1.0])), "Box.rotation"),
        (lambda: Box((0, 0, 0), (0.1, 0.1, 0.1), np.eye(2)), "Box.rotation"),
        (lambda: HalfSpace((0, 0, 2.0), 0.0), "HalfSpace.normal"),
        (lambda: HalfSpace((0, 0, 1.0), float("inf")), "HalfSpace.offset"),
    ],
)
def test_bad_fields_name_the_field(make, name: str) -> None:
    with pytest.raises(InvalidGeometry, match=name.replace(".", r"\.")) as info:
        make()
    assert info.value.name == name
    assert isinstance(info.value, InvalidArgument)


def test_one_rotation_and_unit_tolerance() -> None:
    """A rotation off by less than ROTATION_TOL is accepted, by 10x more refused; the same
    for a normal's length and UNIT_TOL."""
    R = _rot([1, 2, 3], 0.7)
    Box((0, 0, 0), (0.1, 0.1, 0.1), R + 0.1 * ROTATION_TOL * np.eye(3))
    with pytest.raises(InvalidGeometry, match="rotation"):
        Box((0, 0, 0), (0.1, 0.1, 0.1), R + 10 * ROTATION_TOL * np.eye(3))
    HalfSpace((0.0, 0.0, 1.0 + 0.5 * UNIT_TOL), 0.0)
    with pytest.raises(InvalidGeometry, match="unit"):
        HalfSpace((0.0, 0.0, 1.0 + 10 * UNIT_TOL), 0.0)


def test_shapes_are_frozen_values() -> None:
    a = Box(np.array([0.1, 0.2, 0.3]), [0.1, 0.1, 0.1], _rot([0, 0, 1], 0.3))
    b = Box((0.1, 0.2, 0.3), (0.1, 0.1, 0.1), _rot([0, 0, 1], 0.3))
    assert a == b and hash(a) == hash(b)
    assert isinstance(a.center, tuple) and isinstance(a.rotation[0], tuple)
    with pytest.raises(AttributeError):
        a.center = (0.0, 0.0, 0.0)  # type: ignore[misc]


@pytest.mark.parametrize(
    "shape",
    [
        Sphere((0.3, -0.2, 0.5), 0.15),
        Box((0.1, 0.2, -0.3), (0.2, 0.05, 0.3), _rot([1, 2, 3], 0.7)),
        Capsule((-0.2, 0.1, 0.0), (0.3, 0.4, 0.2), 0.08),
        HalfSpace((0.0, 0.6, 0.8), 0.2),
    ],
    ids=["sphere", "box", "capsule", "halfspace"],
)
def test_rounded_box_layout(shape) -> None:
    """(16,): centre, a proper rotation (row-major), half-extents >= 0, radius >= 0."""
    prm = shape.rounded_box()
    assert prm.shape == (ROUNDED_BOX_SIZE,)
    R = prm[3:12].reshape(3, 3)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
    assert np.all(prm[12:16] >= 0.0)
    if isinstance(shape, Capsule):  # the segment lies along the box's first axis
        seg = np.subtract(shape.p1, shape.p0)
        np.testing.assert_allclose(R[:, 0], seg / np.linalg.norm(seg), atol=1e-15)
        assert prm[12] == pytest.approx(0.5 * np.linalg.norm(seg), rel=1e-15)
    if isinstance(shape, HalfSpace):  # a cube whose top face is the plane
        np.testing.assert_allclose(R[:, 2], shape.normal, atol=1e-15)
        np.testing.assert_array_equal(prm[12:15], HALFSPACE_EXTENT)


@pytest.mark.parametrize(
    "shape",
    [
        Sphere((0.3, -0.2, 0.5), 0.15),
        Box((0.1, 0.2, -0.3), (0.2, 0.05, 0.3), _rot([1, 2, 3], 0.7)),
        Capsule((-0.2, 0.1, 0.0), (0.3, 0.4, 0.2), 0.08),
    ],
    ids=["sphere", "box", "capsule"],
)
def test_moved_to_translates_the_shape(shape) -> None:
    """Distances of translated points to the moved shape equal the original distances."""
    rng = np.random.default_rng(14)
    center = np.array([1.0, -0.5, 0.25])
    old = shape.rounded_box()[:3]
    moved = shape.moved_to(center)
    np.testing.assert_allclose(moved.rounded_box()[:3], center, atol=1e-15)
    np.testing.assert_allclose(moved.rounded_box()[3:], shape.rounded_box()[3:], atol=1e-15)
    pts = old + rng.normal(scale=0.3, size=(20, 3))
    np.testing.assert_allclose(
        signed_distance(moved, pts + (center - old)), signed_distance(shape, pts), atol=1e-14
    )


def test_halfspace_moved_to_puts_the_plane_through_the_point() -> None:
    plane = HalfSpace((0.0, 0.6, 0.8), 0.2).moved_to(np.array([1.0, 2.0, 3.0]))
    assert signed_distance(plane, np.array([1.0, 2.0, 3.0]))[0] == pytest.approx(0.0, abs=1e-15)


def test_check_shape() -> None:
    s = Sphere((0, 0, 0), 1.0)
    assert check_shape(s, "obstacle") is s
    with pytest.raises(InvalidGeometry, match=r"obstacles\[3\] is a tuple.*Sphere, Box") as info:
        check_shape(((0, 0, 0), 1.0), "obstacles[3]")
    assert info.value.name == "obstacles[3]"
