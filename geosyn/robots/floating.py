"""The floating base's configuration group SE(3) x R^n, in Pinocchio's conventions.

A floating-base robot (a humanoid, a quadruped) has a free-flyer root joint, Pinocchio's
``JointModelFreeFlyer``, followed by its n joints:

- configuration ``q = [x, y, z, qx, qy, qz, qw, q_1 .. q_n]`` (nq = n + 7): the base
  frame's position in the world [m] and its orientation as a unit quaternion in
  Pinocchio's (x, y, z, w) order, then the joint positions [rad or m];
- velocity ``v = [v_x, v_y, v_z, w_x, w_y, w_z, qd_1 .. qd_n]`` (nv = n + 6): the base's
  linear [m/s] and angular [rad/s] velocity, both in the base frame, then the joint rates.

Configurations move on the group: ``q' = pinocchio.integrate(model, q, v dt)``
(``q * exp(v dt)``), never ``q + v dt``.

MuJoCo's free joint orders and expresses things differently: ``qpos = [x, y, z, qw, qx,
qy, qz, ...]`` and ``qvel = [linear velocity in the world frame, angular velocity in the
body frame, ...]``; `from_mujoco` and `to_mujoco` convert.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from geosyn.core.types import Vector
from geosyn.core.validation import check_vector
from geosyn.robots.errors import FloatingBaseError

__all__ = [
    "FREE_FLYER",
    "QUATERNION_TOL",
    "check_floating_q",
    "from_mujoco",
    "is_floating",
    "neutral_base",
    "random_base",
    "to_mujoco",
]

FREE_FLYER = "JointModelFreeFlyer"
"""Pinocchio's short name of the free-flyer joint."""

QUATERNION_TOL = 1e-9
"""Largest accepted | |quaternion| - 1 | of a base orientation (dimensionless)."""


def is_floating(model: pin.Model) -> bool:
    """Whether the model's first joint is a free flyer (a floating base)."""
    return model.njoints > 1 and model.joints[1].shortname() == FREE_FLYER


def check_floating_q(q: object, nq: int, name: str = "q", robot: str = "robot") -> Vector:
    """``q`` as a float64 (nq,) array whose base quaternion is unit, or raise.

    Args:
        q: candidate configuration (nq,) (layout in the module docstring).
        nq: configuration size, n + 7.
        name: argument name for the messages.
        robot: robot name for the messages.

    Raises:
        InvalidArgument: wrong shape or non-finite values.
        FloatingBaseError: the quaternion ``q[3:7]`` is not unit within `QUATERNION_TOL`.
    """
    q = check_vector(q, nq, name)
    norm = float(np.linalg.norm(q[3:7]))
    if abs(norm - 1.0) > QUATERNION_TOL:
        raise FloatingBaseError(
            f"{name}[3:7] = {q[3:7].tolist()} is the base orientation of floating-base robot"
            f" {robot!r} as a quaternion (x, y, z, w) and must be unit (|norm - 1| <="
            f" {QUATERNION_TOL:g}); its norm is {norm:.12g}: divide it by its norm"
        )
    return q


def neutral_base() -> Vector:
    """(7,) the base at the world origin, not rotated: ``[0, 0, 0, 0, 0, 0, 1]``."""
    return np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])


def random_base(rng: np.random.Generator, half_width: float = 1.0) -> Vector:
    """(7,) a random base pose: position uniform in a cube, orientation uniform on SO(3).

    Args:
        rng: seeded random generator.
        half_width: half the cube's edge, centred at the origin [m].
    """
    quat = rng.normal(size=4)
    return np.concatenate([rng.uniform(-half_width, half_width, 3), quat / np.linalg.norm(quat)])


def from_mujoco(qpos: Vector, qvel: Vector) -> tuple[Vector, Vector]:
    """Pinocchio's ``(q, v)`` from MuJoCo's ``(qpos, qvel)`` of a free-joint root.

    Args:
        qpos: (n + 7,) ``[x, y, z, qw, qx, qy, qz, joints]`` [m, -, rad].
        qvel: (n + 6,) ``[linear velocity (world frame), angular velocity (body frame),
            joint rates]`` [m/s, rad/s].

    Returns:
        ``q`` (n + 7,) and ``v`` (n + 6,) in the module docstring's layout.
    """
    qpos = np.asarray(qpos, dtype=np.float64)
    qvel = np.asarray(qvel, dtype=np.float64)
    q = qpos.copy()
    q[3:7] = qpos[[4, 5, 6, 3]]
    R = pin.Quaternion(qpos[3], qpos[4], qpos[5], qpos[6]).normalized().matrix()
    v = qvel.copy()
    v[:3] = R.T @ qvel[:3]
    return q, v


def to_mujoco(q: Vector, v: Vector) -> tuple[Vector, Vector]:
    """MuJoCo's ``(qpos, qvel)`` of a free-joint root from Pinocchio's ``(q, v)``.

    The inverse of `from_mujoco` (same shapes and units).
    """
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    qpos = q.copy()
    qpos[3:7] = q[[6, 3, 4, 5]]
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).normalized().matrix()
    qvel = v.copy()
    qvel[:3] = R @ v[:3]
    return qpos, qvel
