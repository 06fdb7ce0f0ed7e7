"""Orientations of shapes and payloads: rotation matrices built from angles or an axis,
and their quaternions.

A rotation ``R`` (3, 3) maps the shape's (or body's) axes to the world's: its columns are
the shape's axes in world coordinates, so a point ``p`` in the shape frame is at
``c + R p`` in the world (``c`` the shape's centre).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_vec3


def rotation_from_rpy(rpy: object) -> Matrix:
    """Rotation matrix of roll, pitch, yaw angles (URDF convention).

    .. math:: R = R_z(\\mathrm{yaw})\\, R_y(\\mathrm{pitch})\\, R_x(\\mathrm{roll})

    Args:
        rpy: (3,) roll, pitch, yaw about the world's x, y, z axes [rad].

    Returns:
        (3, 3) rotation matrix.

    Raises:
        geosyn.core.InvalidArgument: ``rpy`` is not a finite (3,) vector.
    """
    roll, pitch, yaw = check_vec3(rpy, "rpy")
    return np.asarray(pin.rpy.rpyToMatrix(roll, pitch, yaw), dtype=np.float64)


def rotation_with_axis(axis: Vector, column: int) -> Matrix:
    """A rotation matrix whose column ``column`` is the unit vector ``axis``.

    The two other columns complete a right-handed orthonormal frame (their angle about
    ``axis`` is arbitrary but deterministic).

    Args:
        axis: (3,) unit vector.
        column: 0, 1 or 2.

    Returns:
        (3, 3) rotation matrix (det +1).
    """
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    cols = [e1, e2]
    cols.insert(column, axis)
    R = np.column_stack(cols)
    if np.linalg.det(R) < 0:
        R[:, (column + 1) % 3] *= -1.0
    return R


def quaternion_wxyz(rotation: Matrix) -> Vector:
    """(4,) unit quaternion ``(w, x, y, z)`` of a rotation matrix (MuJoCo's order).

    Args:
        rotation: (3, 3) rotation matrix.
    """
    q = pin.Quaternion(np.asarray(rotation, dtype=np.float64))
    q.normalize()
    return np.array([q.w, q.x, q.y, q.z])
