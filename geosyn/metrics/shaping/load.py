"""`LoadTerm`: the exact kinetic-energy contribution of a payload held rigidly at a frame."""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.core.validation import check_positive
from geosyn.metrics.shaping.base import MetricTerm
from geosyn.metrics.shaping.errors import term_arguments
from geosyn.robots.robot import Robot
from geosyn.world.payload import Payload

__all__ = ["LoadTerm"]


class LoadTerm(MetricTerm):
    """A payload rigidly attached to a frame: the pulled-back spatial inertia.

    .. math:: G_{load}(q) = J(q)^T \\Lambda J(q)

    with ``J`` the (6, n) Jacobian of ``frame`` in its own (local) axes, linear rows first
    (Pinocchio's ``LOCAL``), and ``Lambda`` the (6, 6) spatial inertia of the payload about
    the frame origin, in frame axes:

    .. math::
        \\Lambda = \\begin{bmatrix} m I_3 & -m [c]_\\times \\\\
                                   m [c]_\\times & I_c - m [c]_\\times [c]_\\times \\end{bmatrix}

    This is exactly what the mass matrix gains when the payload is added to the robot as a
    rigid body fixed to the frame's parent link. Constant parameters (no parameter vector).
    `from_payload` builds the term of a `geosyn.world.Payload`.

    Args:
        frame: name of a Pinocchio frame of the robot (checked at `bind`).
        mass: payload mass [kg], > 0.
        com: (3,) payload centre of mass in the frame [m].
        inertia: (3, 3) rotational inertia about the com, in frame axes [kg m^2];
            symmetric positive definite and satisfying the triangle inequality of principal
            moments. None: a solid ball of ``radius`` (a point mass for radius 0).
        radius: radius of that ball [m], >= 0.

    Attributes:
        payload: the `geosyn.world.Payload` described.
        spatial_inertia: (6, 6) spatial inertia about the frame origin, linear first
            [kg, kg m, kg m^2].

    Raises:
        geosyn.world.InvalidGeometry: com not a finite (3,) vector, or inertia not a
            finite symmetric positive-definite (3, 3) matrix of a rigid body.
        InvalidTermArgument: a mass that is not finite and > 0.
        geosyn.robots.errors.UnknownFrame: at `bind`, the frame is not in the robot (the
            message lists the available frames).
    """

    def __init__(
        self,
        frame: str,
        mass: float,
        com: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
        inertia: Sequence[Sequence[float]] | np.ndarray | None = None,
        *,
        radius: float = 0.0,
    ) -> None:
        super().__init__()
        with term_arguments():
            check_positive(mass, "mass", "kg")
        rows = None if inertia is None else np.asarray(inertia, dtype=np.float64)
        self.payload = Payload(frame, mass, com, rows, radius)  # type: ignore[arg-type]
        self.spatial_inertia = np.asarray(
            pin.Inertia(
                self.payload.mass, np.array(self.payload.com), self.payload.rotational_inertia()
            ).matrix(),
            dtype=np.float64,
        )
        self.frame_index = -1

    @classmethod
    def from_payload(cls, payload: Payload) -> LoadTerm:
        """The load term of a `geosyn.world.Payload` (mass > 0).

        Raises:
            InvalidTermArgument: the payload's mass is 0.
        """
        return cls(payload.frame, payload.mass, payload.com, payload.inertia, radius=payload.radius)

    @property
    def frame(self) -> str:
        """Name of the frame carrying the payload."""
        return self.payload.frame

    @property
    def mass(self) -> float:
        """Payload mass [kg]."""
        return self.payload.mass

    @property
    def com(self) -> np.ndarray:
        """(3,) payload centre of mass in the frame [m]."""
        return np.array(self.payload.com)

    def __repr__(self) -> str:
        return f"LoadTerm({self.frame!r}, mass={self.mass}, com={list(self.payload.com)})"

    def _on_bind(self, robot: Robot) -> None:
        self.frame_index = robot.frame_id(self.frame)

    def symbolic_G(self, q: ca.SX, v: ca.SX | None = None) -> ca.SX:
        """SX ``J^T Lambda J`` with J the local-frame Jacobian (see the class docstring)."""
        from geosyn.robots import symbolic

        robot = self.robot
        jac = symbolic.frame_jacobian(robot.model, q, self.frame_index, reference="local")
        lam = ca.DM(self.spatial_inertia)
        # Lambda = L L^T is PSD; J^T L L^T J keeps the result exactly symmetric.
        return ca.mtimes(jac.T, ca.mtimes(lam, jac))
