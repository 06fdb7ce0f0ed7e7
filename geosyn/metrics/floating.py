"""The kinetic-energy metric of a floating-base robot, on SE(3) x R^n.

A humanoid or a quadruped (`Robot.floating`) has configurations ``q`` (nq = n + 7: base
position, unit quaternion, joints) and velocities ``v`` (nv = n + 6: base twist in the
base frame, joint rates; `geosyn.robots.floating`). Its kinetic energy is
``1/2 v^T M(q) v`` with ``M`` the mass matrix of the free-flyer model (Pinocchio's CRBA),
a left-invariant metric in the base's pose: ``M`` depends on the joints only.

Geodesics of this metric are the robot's passive motions without gravity or contacts:
its total momentum is conserved and its centre of mass moves on a straight line.
`geosyn.metrics.geodesic.exp` integrates them on the group (`geosyn.metrics.geodesic.
group_rk4`); operations written for vector spaces (log, transport, path energy, PGA,
the planner) refuse this metric with `FloatingBaseUnsupported`.
"""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Matrix, Vector
from geosyn.metrics.base import Metric
from geosyn.metrics.errors import FloatingBaseUnsupported
from geosyn.robots.robot import Robot

__all__ = ["FloatingKineticEnergyMetric"]


class FloatingKineticEnergyMetric(Metric):
    """``G(q) = M(q)``, the free-flyer mass matrix of a floating-base robot (nv x nv).

    Numeric only (Pinocchio): `G` is ``pin.crba``, `coriolis` ``pin.rnea`` and
    `geodesic_acceleration` ``pin.aba``, both without gravity; configurations move by
    `integrate` (``pin.integrate``, the group's exponential). Tangent vectors have ``n``
    = nv entries; configurations ``nq`` = nv + 1.

    Args:
        robot: a floating-base robot (`Robot.floating`).

    Raises:
        InvalidArgument: ``robot`` is not a floating-base `Robot` (a fixed-base robot
            takes `geosyn.metrics.KineticEnergyMetric`).

    Attributes:
        robot: the robot.
        n: tangent dimension nv = joints + 6.
        nq: configuration size nv + 1.
    """

    def __init__(self, robot: Robot) -> None:
        if not isinstance(robot, Robot) or not robot.floating:
            what = type(robot).__name__ if not isinstance(robot, Robot) else repr(robot.name)
            raise InvalidArgument(
                f"robot must be a floating-base geosyn Robot, got {what}; a fixed-base robot"
                " takes geosyn.metrics.KineticEnergyMetric"
            )
        self.robot = robot
        self.n = robot.nv
        self.nq = robot.nq
        self._model = robot.model
        self._data = robot.model.createData()
        # A zero-gravity copy: geodesics are passive motions without gravity.
        self._model0 = pin.Model(robot.model)
        self._model0.gravity = pin.Motion.Zero()
        self._data0 = self._model0.createData()
        self._zero = np.zeros(self.n)

    def __repr__(self) -> str:
        return f"FloatingKineticEnergyMetric({self.robot.name!r}, nq={self.nq}, nv={self.n})"

    # -- the metric ------------------------------------------------------------------
    def G(self, q: Vector) -> Matrix:
        """Mass matrix of the free-flyer model.

        Args:
            q: (nq,) configuration (unit quaternion) [m, -, rad].

        Returns:
            (nv, nv) symmetric positive-definite mass matrix [kg, kg m, kg m^2].

        Raises:
            InvalidArgument: wrong shape or non-finite values.
            FloatingBaseError: the quaternion is not unit.
        """
        q = self.robot.check_q(q)
        return np.array(pin.crba(self._model, self._data, q))

    def coriolis(self, q: Vector, v: Vector) -> Vector:
        """Coriolis and centrifugal forces ``C(q, v) v`` (nv,) [N, N m] (no gravity).

        Args:
            q: (nq,) configuration.
            v: (nv,) velocity (base twist in the base frame, joint rates).
        """
        q = self.robot.check_q(q)
        v = self._check(v, "v")
        return np.array(pin.rnea(self._model0, self._data0, q, v, self._zero))

    def geodesic_acceleration(self, q: Vector, v: Vector) -> Vector:
        """``-M(q)^-1 C(q, v) v`` (nv,) by ``pin.aba`` without gravity or torque.

        The time derivative of the velocity coordinates (base-frame twist, joint rates)
        [m/s^2, rad/s^2].

        Args:
            q: (nq,) configuration.
            v: (nv,) velocity.
        """
        q = self.robot.check_q(q)
        v = self._check(v, "v")
        return np.array(pin.aba(self._model0, self._data0, q, v, self._zero))

    # -- the group -------------------------------------------------------------------
    def integrate(self, q: Vector, dq: Vector) -> Vector:
        """``q * exp(dq)``: the configuration reached from ``q`` along ``dq`` (nq,).

        Args:
            q: (nq,) configuration.
            dq: (nv,) tangent displacement (base twist in the base frame times time,
                joint displacements).
        """
        return np.array(pin.integrate(self._model, self.robot.check_q(q), self._check(dq, "dq")))

    def difference(self, q0: Vector, q1: Vector) -> Vector:
        """``log(q0^-1 q1)`` (nv,): the tangent displacement with ``integrate(q0, .) = q1``."""
        q0 = self.robot.check_q(q0, "q0")
        q1 = self.robot.check_q(q1, "q1")
        return np.array(pin.difference(self._model, q0, q1))

    def unchecked(self) -> tuple[Callable[[Vector, Vector], Vector], Callable[..., Vector]]:
        """``(geodesic_acceleration, integrate)`` without input checks, for inner loops.

        The caller guarantees shapes, finite values and a unit quaternion; the results
        are Pinocchio's own arrays (copy them to keep them past the next call).
        """
        model, model0, data0, zero = self._model, self._model0, self._data0, self._zero

        def acc(q: Vector, v: Vector) -> Vector:
            return pin.aba(model0, data0, q, v, zero)

        def integrate(q: Vector, dq: Vector) -> Vector:
            return pin.integrate(model, q, dq)

        return acc, integrate

    # -- the physics the geodesics conserve -----------------------------------------
    def momentum(self, q: Vector, v: Vector) -> Vector:
        """(6,) total momentum about the centre of mass, world axes: ``[p, L]``.

        Pinocchio's centroidal momentum: linear [kg m/s] then angular [kg m^2/s].
        """
        q = self.robot.check_q(q)
        v = self._check(v, "v")
        h = pin.computeCentroidalMomentum(self._model, self._data, q, v)
        return np.array(h.vector)

    def center_of_mass(self, q: Vector) -> Vector:
        """(3,) centre of mass in the world frame [m]."""
        return np.array(pin.centerOfMass(self._model, self._data, self.robot.check_q(q)))

    # -- what the group does not have (yet) ------------------------------------------
    def _unsupported(self, what: str) -> FloatingBaseUnsupported:
        return FloatingBaseUnsupported(
            f"{what} of {self!r}: configurations of a floating base live on SE(3) x"
            f" R^{self.n - 6}, not in a vector space, and geosyn has no symbolic form or"
            " coordinate derivatives there yet; available: G, inner, norm, energy,"
            " coriolis, geodesic_acceleration, integrate, difference and exp"
        )

    def symbolic_G(self, q: ca.SX) -> ca.SX:
        """Not available on the group.

        Raises:
            FloatingBaseUnsupported: always.
        """
        raise self._unsupported("symbolic_G")

    def symbolic_coriolis(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """Not available on the group (raises `FloatingBaseUnsupported`)."""
        raise self._unsupported("symbolic_coriolis")

    def symbolic_geodesic_acceleration(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """Not available on the group (raises `FloatingBaseUnsupported`)."""
        raise self._unsupported("symbolic_geodesic_acceleration")

    def dG(self, q: Vector) -> np.ndarray:
        """Not available on the group (raises `FloatingBaseUnsupported`)."""
        raise self._unsupported("dG")

    def christoffel(self, q: Vector) -> np.ndarray:
        """Not available on the group (raises `FloatingBaseUnsupported`)."""
        raise self._unsupported("christoffel")
