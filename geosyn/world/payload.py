"""`Payload`: a rigid body held at a frame of the robot (an object in the gripper, a tool).

One description serves the load shaping term (`geosyn.metrics.shaping.LoadTerm`), the
Pinocchio test plant (`geosyn.controllers.PinocchioPlant`) and the MuJoCo scene
(`geosyn.sim.build_scene`, where its mass can change during a run).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geosyn.core.types import Matrix, Vector
from geosyn.world import validation as check
from geosyn.world.errors import InvalidGeometry

MAX_MASS = 1e5
"""Largest payload mass [kg] (100 t: far above any robot's payload; larger values make
the dynamics overflow). `geosyn.world.payload.MAX_MASS` may be raised."""


@dataclass(frozen=True)
class Payload:
    """A rigid payload attached to a frame of the robot.

    Its rotational inertia about the centre of mass is ``inertia`` if given, else that of
    a solid ball of ``radius`` (``2/5 m r^2`` about every axis; a point mass for radius 0).

    Attributes:
        frame: name of the robot frame (or joint) that carries it.
        mass: mass [kg], in [0, `MAX_MASS`].
        com: (3,) centre of mass in ``frame`` [m].
        inertia: (3, 3) rotational inertia about the centre of mass, in ``frame`` axes
            [kg m^2] (symmetric positive definite, principal moments satisfying the
            triangle inequality; stored as a tuple of rows), or None for a solid ball of
            ``radius``. Needs mass > 0.
        radius: radius of the ball [m], >= 0; also the size it is drawn with.
        name: name of its body in a simulation scene; None: ``payload<i>``.

    Raises:
        InvalidGeometry: a field is out of range (the message names it).

    Example:
        >>> Payload("panda_hand_tcp", 0.5, com=(0.0, 0.0, 0.05), radius=0.04)
    """

    frame: str
    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[tuple[float, ...], ...] | None = None
    radius: float = 0.0
    name: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.frame, str):
            raise InvalidGeometry(
                f"Payload.frame must be a frame name (str), got {self.frame!r}",
                "Payload.frame",
                self.frame,
            )
        mass = check.nonnegative(self.mass, "Payload.mass", unit="kg")
        if mass > MAX_MASS:  # 1e30 kg gave NaN dynamics downstream instead of an error
            raise InvalidGeometry(
                f"Payload.mass must be in [0, {MAX_MASS:g}] [kg] (MAX_MASS), got {mass:g}",
                "Payload.mass",
                self.mass,
            )
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "com", check.point(self.com, "Payload.com"))
        radius = check.nonnegative(self.radius, "Payload.radius", unit="m")
        object.__setattr__(self, "radius", radius)
        if self.inertia is not None:
            if mass == 0.0:
                raise InvalidGeometry(
                    "Payload.inertia must be None for a payload of mass 0 [kg] "
                    "(the inertia is scaled with the mass)",
                    "Payload.inertia",
                    self.inertia,
                )
            inertia = check.inertia(self.inertia, "Payload.inertia")
            object.__setattr__(self, "inertia", tuple(tuple(map(float, r)) for r in inertia))
        if self.name is not None and not isinstance(self.name, str):
            raise InvalidGeometry(
                f"Payload.name must be a str or None, got {self.name!r}", "Payload.name", self.name
            )

    def rotational_inertia(self, mass: float | None = None) -> Matrix:
        """(3, 3) rotational inertia about the centre of mass, in frame axes [kg m^2].

        Args:
            mass: the mass [kg] to evaluate it for (default: ``self.mass``); a given
                ``inertia`` is scaled by ``mass / self.mass`` (same shape, other density).
        """
        m = self.mass if mass is None else float(mass)
        if self.inertia is None:
            return np.eye(3) * 0.4 * m * self.radius**2
        return np.array(self.inertia) * (m / self.mass)

    def principal_inertia(self, mass: float | None = None) -> tuple[Vector, Matrix]:
        """Principal moments and axes of `rotational_inertia` (what MuJoCo stores).

        Args:
            mass: the mass [kg] to evaluate it for (default: ``self.mass``).

        Returns:
            ((3,) principal moments [kg m^2], ascending for a given inertia, (3, 3)
            frame-from-principal rotation, det +1). A ball's axes are the frame's.
        """
        m = self.mass if mass is None else float(mass)
        if self.inertia is None:
            return np.full(3, 0.4 * m * self.radius**2), np.eye(3)
        moments, axes = np.linalg.eigh(np.array(self.inertia))
        if np.linalg.det(axes) < 0.0:
            axes[:, 2] *= -1.0
        return moments * (m / self.mass), axes
