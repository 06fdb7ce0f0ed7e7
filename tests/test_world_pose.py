"""Orientations: rpy angles, a frame around an axis, quaternions, against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from geosyn.core import InvalidArgument
from geosyn.world import rotation_from_rpy
from geosyn.world.pose import quaternion_wxyz, rotation_with_axis


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_rpy_is_the_urdf_convention() -> None:
    rng = np.random.default_rng(15)
    for roll, pitch, yaw in rng.uniform(-np.pi, np.pi, size=(20, 3)):
        np.testing.assert_allclose(
            rotation_from_rpy([roll, pitch, yaw]), _rz(yaw) @ _ry(pitch) @ _rx(roll), atol=1e-15
        )
    with pytest.raises(InvalidArgument, match="rpy"):
        rotation_from_rpy([0.0, 1.0])


@pytest.mark.parametrize("column", [0, 1, 2])
def test_rotation_with_axis(column: int) -> None:
    rng = np.random.default_rng(16 + column)
    axes = [np.eye(3)[i] for i in range(3)] + list(rng.normal(size=(20, 3)))
    for a in axes:
        a = a / np.linalg.norm(a)
        R = rotation_with_axis(a, column)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-15)
        np.testing.assert_allclose(R[:, column], a, atol=1e-15)


def test_quaternion_rotates_like_the_matrix() -> None:
    """v' = q v q* (Hamilton product, w first) equals R v."""
    rng = np.random.default_rng(17)
    for rpy in rng.uniform(-np.pi, np.pi, size=(20, 3)):
        R = rotation_from_rpy(rpy)
        w, x, y, z = quaternion_wxyz(R)
        assert w * w + x * x + y * y + z * z == pytest.approx(1.0, abs=1e-15)
        u = np.array([x, y, z])
        v = rng.normal(size=3)
        rotated = v + 2.0 * w * np.cross(u, v) + 2.0 * np.cross(u, np.cross(u, v))
        np.testing.assert_allclose(rotated, R @ v, atol=1e-14)
