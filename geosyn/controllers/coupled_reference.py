"""`CoupledReference`: a reference in the independent coordinates z of coupled joints
(``q = S z + c``, `geosyn.robots.Coupling`), lifted to the joints so that any controller
tracks it."""

from __future__ import annotations

import numpy as np

from geosyn.controllers.reference import Reference, ReferenceSample
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.robots.couplings import Coupling

__all__ = ["CoupledReference"]


class CoupledReference(Reference):
    """A reference in independent coordinates z, lifted to the coupled joints.

    For a robot whose joints are coupled, ``q = S z + c`` (``robot.coupling``), geodesics
    and synergies live in z (`geosyn.metrics.CoupledMetric`, ``G_z = S^T G S``); the
    controllers work in the joints q, on the robot's full dynamics. Because S is constant,
    the lift is exact at every time:

    .. math::
        q = S z + c, \\qquad \\dot q = S \\dot z, \\qquad \\ddot q = S \\ddot z,

    so a computed-torque (or QP, MPC) controller of the robot tracks the z-geodesic on the
    coupled manifold. The controller commands every joint, dependent ones included, on
    the robot's unconstrained dynamics; as the reference satisfies the constraints, the
    simulated constraint forces stay small (computed torque inside the coupled fixture
    file: RMS error ~1e-4 rad, tests/test_couplings.py). Typical use::

        metric = CoupledMetric(KineticEnergyMetric(robot), robot.coupling)
        geodesic = GeodesicReference(exp(metric, z0, z_dot0), metric)  # in z
        ref = CoupledReference(geodesic, robot.coupling)  # in q
        controller.set_reference(ref)  # any joint-space controller

    Args:
        reference: the reference in z (anything with ``sample(t) -> (z, z_dot, z_ddot)``,
            ``goal()``, ``n``, ``duration`` and ``t0``; ``n`` must equal ``coupling.nz``).
        coupling: the coupling ``q = S z + c``.

    Attributes:
        inner: the reference in z.
        coupling: the coupling.
        n: number of joints (rows of S).

    `sample` allocates its three result arrays (and what the inner reference allocates).

    Raises:
        InvalidArgument: ``coupling`` is not a `Coupling`, ``reference`` has no
            ``sample``, or its dimension is not ``coupling.nz``.
    """

    def __init__(self, reference: Reference, coupling: Coupling) -> None:
        if not isinstance(coupling, Coupling):
            raise InvalidArgument(
                f"coupling must be a geosyn.robots.Coupling, got {type(coupling).__name__}"
            )
        if not callable(getattr(reference, "sample", None)):
            raise InvalidArgument(
                f"reference must have sample(t) (a geosyn Reference), got {type(reference).__name__}"
            )
        nz = getattr(reference, "n", None)
        if nz != coupling.nz:
            raise InvalidArgument(
                f"reference has dimension n={nz}, but the coupling has nz={coupling.nz}"
                f" independent coordinates {coupling.independent}"
            )
        self.inner = reference
        self.coupling = coupling
        self.n = int(coupling.S.shape[0])
        self.t0 = float(reference.t0)
        self.duration = float(reference.duration)
        self._S = np.asarray(coupling.S, dtype=np.float64)
        self._c = np.asarray(coupling.c, dtype=np.float64)

    def sample(self, t: float) -> ReferenceSample:
        """Joint reference at time ``t`` [s].

        Returns:
            (n,) ``S z + c`` [rad], (n,) ``S z_dot`` [rad/s], (n,) ``S z_ddot`` [rad/s^2].
        """
        z, z_dot, z_ddot = self.inner.sample(t)
        S = self._S
        return ReferenceSample(S @ z + self._c, S @ z_dot, S @ z_ddot)

    def goal(self) -> Vector:
        """(n,) final joint configuration ``S z_goal + c`` [rad]."""
        return self._S @ np.asarray(self.inner.goal(), dtype=np.float64) + self._c
