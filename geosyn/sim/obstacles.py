"""Obstacles of a simulation scene: `geosyn.world` shapes as MuJoCo geoms, and the minimum
clearance between them and the robot's collision spheres.

=============  ==========================================  ===================
shape          fields                                      MuJoCo geom
=============  ==========================================  ===================
Sphere         ``center`` (3,) [m], ``radius`` [m]         ``sphere``
Box            ``center``, ``half_extents`` (3,) [m],      ``box``
               ``rotation`` (3, 3) world-from-box
Capsule        ``p0``, ``p1`` (3,) [m], ``radius`` [m]     ``capsule``
Cylinder       ``center``, ``radius``, ``half_length``     ``cylinder``
               ``rotation`` (axis: third column)
HalfSpace      ``normal`` (3,), ``offset`` [m]             ``plane``
=============  ==========================================  ===================

Minimum clearance: the robot's collision spheres (`Robot.collision_spheres`) are placed
with the MuJoCo body poses (a MuJoCo body frame is its Pinocchio joint frame) and their
signed distances to the obstacles (`geosyn.world.signed_distance`) are taken, minus the
sphere radius. This is the geometry the obstacle shaping terms see; negative means
penetration.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np
import pinocchio as pin

import geosyn.world as world
from geosyn.robots.mjcf import body_name
from geosyn.robots.mjcf import mjcf_number as _f
from geosyn.robots.mjcf import mjcf_vector as _vec
from geosyn.robots.robot import Robot
from geosyn.world.pose import quaternion_wxyz
from geosyn.world.shapes import check_shape

#: Collision bit of the robot's and payloads' geoms when ``contact=True``.
ROBOT_BIT = 2


def _quat_z_to(n: np.ndarray) -> np.ndarray:
    """(4,) wxyz quaternion rotating the z axis onto the unit vector ``n``."""
    q = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), n)
    return np.array([q.w, q.x, q.y, q.z])


def _sphere_geom(s: world.Sphere) -> str:
    return f'type="sphere" size="{_f(s.radius)}" pos="{_vec(s.center)}"'


def _box_geom(s: world.Box) -> str:
    size = np.maximum(s.half_extents, 1e-4)  # MuJoCo needs positive sizes; the distance uses h
    quat = quaternion_wxyz(np.asarray(s.rotation))
    return f'type="box" size="{_vec(size)}" pos="{_vec(s.center)}" quat="{_vec(quat)}"'


def _capsule_geom(s: world.Capsule) -> str:
    if np.allclose(s.p0, s.p1):
        return f'type="sphere" size="{_f(s.radius)}" pos="{_vec(s.p0)}"'
    return f'type="capsule" size="{_f(s.radius)}" fromto="{_vec(s.p0)} {_vec(s.p1)}"'


def _cylinder_geom(s: world.Cylinder) -> str:
    quat = quaternion_wxyz(np.asarray(s.rotation))
    size = f"{_f(s.radius)} {_f(max(s.half_length, 1e-4))}"
    return f'type="cylinder" size="{size}" pos="{_vec(s.center)}" quat="{_vec(quat)}"'


def _halfspace_geom(s: world.HalfSpace) -> str:
    n = np.asarray(s.normal)
    pos, quat = n * s.offset, _quat_z_to(n)
    return f'type="plane" size="1.5 1.5 0.02" pos="{_vec(pos)}" quat="{_vec(quat)}"'


#: The MuJoCo geom attributes of each shape class.
GEOMS: dict[type, Callable[..., str]] = {
    world.Sphere: _sphere_geom,
    world.Box: _box_geom,
    world.Capsule: _capsule_geom,
    world.Cylinder: _cylinder_geom,
    world.HalfSpace: _halfspace_geom,
}


@dataclass(frozen=True)
class ObstacleGeom:
    """An obstacle shape and its MuJoCo geom.

    Attributes:
        shape: the `geosyn.world` shape.
        xml: the ``<geom>`` element.
    """

    shape: world.Shape
    xml: str

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance of points to the shape [m], negative inside.

        Args:
            points: (S, 3) points in the world frame [m].

        Returns:
            (S,) distances [m].
        """
        return world.signed_distance(self.shape, points)


def obstacle_geom(obstacle: world.Shape, index: int, contact: bool = False) -> ObstacleGeom:
    """The MuJoCo geom ``obstacle<index>`` of a shape.

    Args:
        obstacle: a `Sphere`, `Box`, `Capsule` or `HalfSpace` of `geosyn.world`.
        index: index in the scene, used for the geom name ``obstacle<index>``.
        contact: whether the geom collides with the robot.

    Raises:
        geosyn.world.InvalidGeometry: ``obstacle`` is not a shape.
    """
    shape = check_shape(obstacle, f"obstacles[{index}]")
    name = quoteattr(f"obstacle{index}")
    flags = f'contype="0" conaffinity="{ROBOT_BIT if contact else 0}"'
    style = 'rgba="0.85 0.3 0.25 0.6" group="2"'
    return ObstacleGeom(shape, f"<geom name={name} {flags} {style} {GEOMS[type(shape)](shape)}/>")


def obstacle_contact_force(
    model: mujoco.MjModel, data: mujoco.MjData, obstacle_geoms: frozenset[int], buf: np.ndarray
) -> float:
    """Sum of the normal forces [N] of the active contacts that involve an obstacle geom.

    Reads ``data.contact`` as the last collision detection left it (``mj_step1`` or
    ``mj_forward``); ``buf`` is a (6,) scratch array. 0 when obstacles do not collide.
    """
    total = 0.0
    for i in range(data.ncon):
        c = data.contact[i]
        if c.geom1 in obstacle_geoms or c.geom2 in obstacle_geoms:
            mujoco.mj_contactForce(model, data, i, buf)
            total += abs(float(buf[0]))
    return total


# -- clearance ------------------------------------------------------------------------
_ROUNDED = (world.Sphere, world.Box, world.Capsule)
"""Shapes whose rounded box is exactly themselves (a half-space's is a large box, a
cylinder's its enclosing capsule)."""


class Clearance:
    """Minimum signed distance between the robot's collision spheres and the obstacles.

    Built once per scene; each call only evaluates. Spheres, boxes and capsules: given
    the joint positions, the planner's compiled sphere check
    (`geosyn.metrics.planning.sphere_native`: its own kinematics, ~4 µs); without them, or
    where that check cannot model the robot (warned once), numpy on MuJoCo's body poses,
    all together as rounded boxes (`geosyn.world.shapes`: the same exact distance to
    round-off). Cylinders and half-spaces: numpy, each by its own formula
    (`geosyn.world.signed_distance`).
    """

    def __init__(
        self, robot: Robot, model: mujoco.MjModel, obstacles: Sequence[ObstacleGeom]
    ) -> None:
        spheres = robot.collision_spheres()
        self.obstacles = tuple(obstacles)
        self.body_ids = np.array(
            [
                mujoco.mj_name2id(
                    model, mujoco.mjtObj.mjOBJ_BODY, body_name(robot.model, robot.joint_id(s.joint))
                )
                for s in spheres
            ],
            dtype=np.int64,
        )
        self.centers = np.array([s.center for s in spheres], dtype=np.float64).reshape(-1, 3)
        self.radii = np.array([s.radius for s in spheres], dtype=np.float64)
        batched = [o.shape for o in self.obstacles if isinstance(o.shape, _ROUNDED)]
        self._others = tuple(o for o in self.obstacles if not isinstance(o.shape, _ROUNDED))
        P = np.array([b.rounded_box() for b in batched], dtype=np.float64).reshape(-1, 16)
        self._c, self._R = P[:, None, 0:3], P[:, 3:12].reshape(-1, 3, 3)  # world-from-box
        self._h, self._r = P[:, None, 12:15], P[:, 15:16] + self.radii[None, :]
        self._native = _native_check(robot, spheres, batched) if batched else None

    def sphere_centers(self, xpos: np.ndarray, xmat: np.ndarray) -> np.ndarray:
        """(S, 3) world positions of the sphere centres [m] from MuJoCo body poses.

        Args:
            xpos: (nbody, 3) body positions [m] (``MjData.xpos``).
            xmat: (nbody, 9) body orientations, row-major (``MjData.xmat``).
        """
        R = xmat[self.body_ids].reshape(-1, 3, 3)
        return xpos[self.body_ids] + np.einsum("sij,sj->si", R, self.centers)

    def __call__(self, xpos: np.ndarray, xmat: np.ndarray, q: np.ndarray | None = None) -> float:
        """Minimum clearance [m] (``inf`` without obstacles or spheres; < 0 penetrating).

        Args:
            xpos: (nbody, 3) body positions [m] (``MjData.xpos``).
            xmat: (nbody, 9) body orientations, row-major (``MjData.xmat``).
            q: (nq,) the same state's joint positions [rad], for the compiled check.
        """
        if not self.obstacles or len(self.radii) == 0:
            return float("inf")
        best, compiled = math.inf, False
        if self._native is not None and q is not None:  # the spheres, boxes and capsules
            best, compiled = float(self._native.clearances(q.reshape(1, -1))[0]), True
            if not self._others:
                return best
        pts = self.sphere_centers(xpos, xmat)
        if len(self._R) and not compiled:  # p = R^T (x - c) per obstacle: (O, S, 3)
            p = np.abs(np.matmul(pts[None, :, :] - self._c, self._R)) - self._h
            sd = np.sqrt((np.maximum(p, 0.0) ** 2).sum(axis=2)) + np.minimum(p.max(axis=2), 0.0)
            best = float((sd - self._r).min())
        for o in self._others:
            best = min(best, float(np.min(o.signed_distance(pts) - self.radii)))
        return best


def _native_check(robot: Robot, spheres: Sequence[Any], shapes: Sequence[world.Shape]) -> Any:
    """The planner's compiled sphere check of ``spheres`` against ``shapes``, or None
    (warned once per reason) where it cannot model the robot or no compiler is there."""
    from geosyn.core.codegen import CodegenError
    from geosyn.metrics.planning.sphere_native import NativeSphereCheck

    try:
        check = NativeSphereCheck(robot, spheres)
    except (ValueError, CodegenError) as err:
        _warn_numpy(f"{type(err).__name__}: {err}")
        return None
    check.set_obstacles(shapes)
    return check


@functools.cache
def _warn_numpy(why: str) -> None:
    warnings.warn(
        f"simulation clearance in numpy (slower per tick): {why}", RuntimeWarning, stacklevel=5
    )


__all__ = ["GEOMS", "ROBOT_BIT", "Clearance", "ObstacleGeom", "obstacle_geom"]
