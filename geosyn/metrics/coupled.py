"""The pull-back metric of linearly coupled joints: ``G_z(z) = S^T G(S z + c) S``.

A robot whose joints are coupled, ``q = S z + c`` (`geosyn.robots.Coupling`, read from the
file's joint and fixed-tendon equalities or URDF mimics), moves on the affine subspace of
q it spans; its kinetic energy in the independent coordinates z is
``1/2 z_dot^T S^T M(q) S z_dot``. Because S is constant, the Coriolis term pulls back too:

.. math::
    c_z(z, \\dot z) = S^T c(S z + c, S \\dot z),

so geodesics, synergies and everything built on a `Metric` work in z with the base
metric's fast paths (Pinocchio, RNEA/ABA symbolic forms).

Controllers work in the joints q: a trajectory in z is lifted exactly (S is constant) to
``q = S z + c``, ``q_dot = S z_dot``, ``q_ddot = S z_ddot`` and tracked on the robot's
dynamics, by `geosyn.controllers.CoupledReference` (a z-reference such as a
`GeodesicReference` of this metric, sampled in q) or `geosyn.robots.Coupling.lift`
(sampled arrays)::

    metric = CoupledMetric(KineticEnergyMetric(robot), robot.coupling)
    z_ref = GeodesicReference(exp(metric, z0, z_dot0), metric)
    controller.set_reference(CoupledReference(z_ref, robot.coupling))
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Matrix, Vector
from geosyn.metrics.base import Metric, check_metric
from geosyn.robots.couplings import Coupling


class CoupledMetric(Metric):
    """A metric pulled back through a linear coupling ``q = S z + c``.

    Args:
        base: metric on the joints q (e.g. `KineticEnergyMetric` of the robot).
        coupling: the coupling (``robot.coupling``); ``coupling.S`` has ``base.n`` rows.
        compile: compile this metric's functions to C (see `Metric`).

    Attributes:
        base: the metric on q.
        coupling: the coupling.
        n: number of independent coordinates.

    Every method takes independent coordinates z (and their velocities) where a `Metric`
    takes q; `q` maps z to the joints. To track its geodesics, see the module doc.

    `G`, `coriolis` and `geodesic_acceleration` allocate a few small arrays.
    """

    def __init__(self, base: Metric, coupling: Coupling, *, compile: bool = False) -> None:
        self.base = check_metric(base)
        if not isinstance(coupling, Coupling):
            raise InvalidArgument(
                f"coupling must be a geosyn.robots.Coupling, got {type(coupling).__name__}"
            )
        if coupling.S.shape[0] != base.n:
            raise InvalidArgument(
                f"coupling maps to {coupling.S.shape[0]} joints, but the base metric has n={base.n}"
            )
        self.coupling = coupling
        self.n = coupling.nz
        self.compile = bool(compile)
        self._S = np.asarray(coupling.S, dtype=np.float64)
        self._c = np.asarray(coupling.c, dtype=np.float64)

    def __repr__(self) -> str:
        return f"CoupledMetric({self.base!r}, n={self.n})"

    def q(self, z: Vector) -> Vector:
        """(nq,) joint positions ``S z + c`` of the independent coordinates (n,)."""
        return self._S @ self._check(z, "z") + self._c

    def G(self, q: Vector) -> Matrix:
        """``S^T G(S z + c) S``.

        Args:
            q: (n,) independent coordinates z [rad].

        Returns:
            (n, n) symmetric positive-definite metric tensor.
        """
        S = self._S
        return S.T @ self.base.G(self.q(q)) @ S

    def coriolis(self, q: Vector, v: Vector) -> Vector:
        """``S^T c(S z + c, S z_dot)``: the base's Coriolis term pulled back.

        Args:
            q: (n,) independent coordinates z [rad].
            v: (n,) their velocities [rad/s].
        """
        v = self._check(v, "v")
        return self._S.T @ self.base.coriolis(self.q(q), self._S @ v)

    def geodesic_acceleration(self, q: Vector, v: Vector) -> Vector:
        """``-G_z^-1 c_z`` [rad/s^2].

        Args:
            q: (n,) independent coordinates z [rad].
            v: (n,) their velocities [rad/s].
        """
        return np.asarray(-np.linalg.solve(self.G(q), self.coriolis(q, v)), dtype=np.float64)

    # -- symbolic ---------------------------------------------------------------------
    def symbolic_G(self, q: ca.SX) -> ca.SX:
        """SX ``S^T G(S z + c) S`` from the base's symbolic form."""
        S = ca.DM(self._S)
        return S.T @ self.base.symbolic_G(S @ q + ca.DM(self._c)) @ S

    def symbolic_coriolis(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX ``S^T c(S z + c, S z_dot)`` from the base's (RNEA for the kinetic metric)."""
        S = ca.DM(self._S)
        return S.T @ self.base.symbolic_coriolis(S @ q + ca.DM(self._c), S @ v)

    def symbolic_parameters(self) -> ca.SX:
        """The base metric's parameters."""
        return self.base.symbolic_parameters()

    def parameter_values(self) -> np.ndarray:
        """The base metric's parameter values."""
        return self.base.parameter_values()
