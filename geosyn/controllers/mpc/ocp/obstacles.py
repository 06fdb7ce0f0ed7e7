"""Obstacle slots of the OCP: world shapes, and the clearance of the robot's spheres to them.

``GeodesicMPC(obstacles=[...], clearance_margin=m)`` adds to every stage (and the
terminal state) the stiff penalty

.. math:: w_c \\sum_{s,o} \\max(0,\\ m - c_{so}(q))^2

(`geosyn.controllers.mpc.ocp.costs.ClearancePenalty`) over the robot's collision spheres
``s`` and the obstacle slots ``o``: clearance ``c_so = sd_o(x_s(q)) - r_s`` [m], with
``sd_o`` the exact signed distance of the slot's rounded box
(`geosyn.world.distance.rounded_box_distance`); an empty slot reports
`EMPTY_SLOT_CLEARANCE` and never counts. Each slot holds one `geosyn.world` shape as its
rounded box plus an active flag (`SLOT_SIZE` numbers), so the compiled functions take the
obstacles as a parameter: moving or replacing them (`ObstacleSlots.set_obstacles`) is a
parameter write, read at the next solve.

A penalty, not a constraint: the margin holds to within a few millimetres when the
reference passes near an obstacle (the intended use: a collision-free reference, the
clearance guarding against disturbances). A reference running *through* an obstacle
makes the OCP trade tracking against clearance at full torque, and with stiff weights
the closed loop can become violent: keep the reference collision-free.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.robots import symbolic
from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.robots.sphere_cover import report_sphere_miss, resolve_spheres
from geosyn.world.distance import rounded_box_distance
from geosyn.world.shapes import ROUNDED_BOX_SIZE, Shape, check_shape

__all__ = [
    "EMPTY_SLOT_CLEARANCE",
    "SLOT_SIZE",
    "ObstacleSlots",
    "clearance_digest",
    "obstacle_slots",
]

SLOT_SIZE = ROUNDED_BOX_SIZE + 1
"""Parameters per slot (17): the shape's rounded box (16, `geosyn.world.shapes`) and an
active flag (1). The layout of `geosyn.metrics.shaping.ObstacleTerm`'s slots as well."""

EMPTY_SLOT_CLEARANCE = 10.0
"""Clearance [m] an empty slot reports (far beyond any margin)."""


class ObstacleSlots:
    """World shapes in a fixed number of slots, and the symbolic clearance to them.

    Args:
        robot: the robot.
        obstacles: `geosyn.world` shapes (`Sphere`, `Box`, `Capsule`, `Cylinder` as its
            enclosing capsule, `HalfSpace`).
        capacity: number of slots (>= len(obstacles)); None: one per obstacle.
        spheres: the robot's spheres kept clear: None (``robot.collision_spheres()``),
            ``"file"`` (covering its file's collision geometry) or the spheres
            (`geosyn.robots.sphere_cover.resolve_spheres`).

    Raises:
        InvalidArgument: no obstacles and no capacity, a capacity below the obstacle
            count, or a robot without collision spheres.
        geosyn.world.InvalidGeometry: an obstacle is not a shape.
    """

    def __init__(
        self,
        robot: Robot,
        obstacles: Sequence[Shape],
        capacity: int | None = None,
        spheres: Sequence[CollisionSphere] | str | None = None,
    ) -> None:
        obstacles = list(obstacles)
        self.capacity = len(obstacles) if capacity is None else int(capacity)
        if self.capacity < max(len(obstacles), 1):
            raise InvalidArgument(
                f"obstacles: {len(obstacles)} shapes in {self.capacity} slots; give at "
                "least one shape (a geosyn.world Sphere, Box, Capsule, ...) and no more "
                "than the capacity"
            )
        self.spheres = resolve_spheres(robot, spheres, "clearance_spheres")
        if not self.spheres:
            raise InvalidArgument(f"obstacles: robot {robot.name!r} has no collision spheres")
        fix = "clearance_spheres='file' (in YAML too)"
        report_sphere_miss(robot, self.spheres, "MPC clearance", fix)  # warned once
        self._robot = robot
        self._values = np.zeros(self.capacity * SLOT_SIZE)
        self._obstacles: tuple[Shape, ...] = ()
        self.set_obstacles(obstacles)

    @property
    def obstacles(self) -> tuple[Shape, ...]:
        """The shapes in the slots, in slot order."""
        return self._obstacles

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """Replace the shapes (a parameter write, read by the next solve).

        Raises:
            InvalidArgument: more shapes than slots.
            geosyn.world.InvalidGeometry: an element is not a shape.
        """
        shapes = [check_shape(ob, f"obstacles[{i}]") for i, ob in enumerate(obstacles)]
        if len(shapes) > self.capacity:
            raise InvalidArgument(
                f"obstacles: {len(shapes)} shapes, but the OCP has {self.capacity} slots"
            )
        slots = self._values.reshape(self.capacity, SLOT_SIZE)
        slots[:] = 0.0
        slots[:, 3:12] = np.eye(3).ravel()  # a harmless identity rotation in empty slots
        for i, shape in enumerate(shapes):
            slots[i, :ROUNDED_BOX_SIZE] = shape.rounded_box()
            slots[i, ROUNDED_BOX_SIZE] = 1.0
        self._obstacles = tuple(shapes)

    def values(self) -> np.ndarray:
        """(capacity * `SLOT_SIZE`,) the slots' parameters (the live array: do not modify)."""
        return self._values

    def clearance_function(self) -> ca.Function:
        """``mpc_clearance: (q (n,), p (capacity * 17,)) -> (c (m,), dc_dq (m, n))``, the
        clearance of every sphere to every slot (sphere-major rows, ``m = n_spheres *
        capacity``) and its exact Jacobian (builds an SX graph)."""
        robot, n = self._robot, self._robot.nv
        q = ca.SX.sym("q", n)
        p = ca.SX.sym("p", self.capacity * SLOT_SIZE)
        dist = rounded_box_distance()
        placements = symbolic.joint_placements(robot.model, q)
        rows = []
        for sphere in self.spheres:
            R, t = placements[robot.joint_id(sphere.joint)]
            x = ca.mtimes(R, ca.DM(sphere.center)) + t
            for o in range(self.capacity):
                prm = p[o * SLOT_SIZE : o * SLOT_SIZE + ROUNDED_BOX_SIZE]
                active = p[o * SLOT_SIZE + ROUNDED_BOX_SIZE]
                sd = dist(x, prm)[0] - sphere.radius
                rows.append(active * sd + (1.0 - active) * EMPTY_SLOT_CLEARANCE)
        c = ca.vertcat(*rows)
        return ca.Function(
            "mpc_clearance", [q, p], [c, ca.jacobian(c, q)], ["q", "p"], ["c", "dc_dq"],
            {"cse": True},
        )  # fmt: skip


def obstacle_slots(
    robot: Robot,
    margin: float | None,
    obstacles: Sequence[Shape] | None,
    spheres: Sequence[CollisionSphere] | str | None = None,
) -> ObstacleSlots | None:
    """`GeodesicMPC`'s slots of ``obstacles`` (None without them; the backend names what
    is missing when ``clearance_margin`` is set: obstacles reach the MPC as shapes, never
    through its metric).

    Raises:
        InvalidArgument: ``obstacles`` or ``spheres`` without a ``margin``
            (``clearance_margin``).
    """
    if obstacles is not None and margin is None:
        raise InvalidArgument("obstacles need clearance_margin (the clearance [m] kept)")
    if spheres is not None and margin is None:
        raise InvalidArgument("clearance_spheres needs clearance_margin (and obstacles)")
    return None if obstacles is None else ObstacleSlots(robot, obstacles, spheres=spheres)


def clearance_digest(fun: ca.Function) -> str:
    """sha256 of a serialised clearance function (part of a compiled library's key)."""
    return hashlib.sha256(fun.serialize().encode()).hexdigest()
