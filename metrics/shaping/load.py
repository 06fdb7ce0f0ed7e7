"""`LoadTerm`: the exact kinetic-energy contribution of a payload held rigidly at a frame."""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.metrics.shaping.base import MetricTerm
from geosyn.metrics.shaping.errors import InvalidPayload
from geosyn.robots.robot import Robot

__all__ = ["LoadTerm"]

_SYM_TOL = 1e-12


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

    Args:
        frame: name of a Pinocchio frame of the robot (checked at `bind`).
        mass: payload mass [kg], > 0.
        com: (3,) payload centre of mass in the frame [m].
        inertia: (3, 3) rotational inertia about the com, in frame axes [kg m^2];
            symmetric positive definite and satisfying the triangle inequality of principal
            moments. None: a point mass.

    Raises:
        InvalidPayload: non-positive or non-finite mass, com not a finite (3,) vector, or
            inertia not a finite symmetric positive-definite (3, 3) matrix.
        geosyn.robots.errors.UnknownFrame: at `bind`, the frame is not in the robot (the
            message lists the available frames).
    """

    def __init__(
        self,
        frame: str,
        mass: float,
        com: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
        inertia: Sequence[Sequence[float]] | np.ndarray | None = None,
    ) -> None:
        super().__init__()
        if not isinstance(frame, str):
            raise InvalidPayload(f"frame must be a frame name (str), got {frame!r}")
        try:
            m = float(mass)
        except (TypeError, ValueError) as err:
            raise InvalidPayload(f"mass must be a positive number [kg], got {mass!r}") from err
        if not (np.isfinite(m) and m > 0.0):
            raise InvalidPayload(f"mass must be finite and > 0 [kg], got {mass!r}")
        try:
            c = np.asarray(com, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise InvalidPayload(f"com must be a (3,) vector [m], got {com!r}") from err
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise InvalidPayload(f"com must be a finite (3,) vector [m], got {com!r}")
        if inertia is None:
            inertia_c = np.zeros((3, 3))
        else:
            inertia_c = self._check_inertia(inertia)
        self.frame = frame
        self.mass = m
        self.com = c
        self.inertia = inertia_c
        self.spatial_inertia = np.asarray(pin.Inertia(m, c, inertia_c).matrix(), dtype=np.float64)
        """(6, 6) spatial inertia about the frame origin, linear first [kg, kg m, kg m^2]."""
        self.frame_index = -1

    @staticmethod
    def _check_inertia(inertia: object) -> np.ndarray:
        try:
            inertia_c = np.asarray(inertia, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise InvalidPayload(
                f"inertia must be a (3, 3) matrix [kg m^2] or None, got {inertia!r}"
            ) from err
        if inertia_c.shape != (3, 3) or not np.all(np.isfinite(inertia_c)):
            raise InvalidPayload(
                f"inertia must be a finite (3, 3) matrix [kg m^2] or None, got {inertia!r}"
            )
        scale = max(float(np.max(np.abs(inertia_c))), 1e-300)
        if np.max(np.abs(inertia_c - inertia_c.T)) > _SYM_TOL * scale:
            raise InvalidPayload(f"inertia must be symmetric, got {inertia_c.tolist()}")
        eig = np.linalg.eigvalsh(inertia_c)
        if eig[0] <= 0.0:
            raise InvalidPayload(
                f"inertia must be positive definite, got eigenvalues {eig.tolist()} "
                f"of {inertia_c.tolist()}"
            )
        if eig[0] + eig[1] < eig[2] * (1.0 - 1e-12):
            raise InvalidPayload(
                f"inertia principal moments {eig.tolist()} violate the triangle inequality "
                "(I1 + I2 >= I3); no rigid body has this inertia"
            )
        return inertia_c

    def __repr__(self) -> str:
        return f"LoadTerm({self.frame!r}, mass={self.mass}, com={self.com.tolist()})"

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
