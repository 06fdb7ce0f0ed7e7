"""The kinetic-energy metric: G(q) = M(q), the robot's mass-inertia matrix."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_rows
from geosyn.metrics.base import Metric
from geosyn.metrics.errors import FloatingBaseUnsupported, NonFiniteResult
from geosyn.robots.robot import Robot

# |q|^2 + |v|^2 below this keeps pin.aba finite on the fast path of geodesic_acceleration.
_FAST_BOUND = 1e200


def _raise_non_finite(quantity: str, value: np.ndarray, v: np.ndarray) -> None:
    """Raise `NonFiniteResult` if ``value`` holds inf/NaN (its squared norm may just
    overflow for finite entries beyond ~1e154, which is returned as is)."""
    if np.all(np.isfinite(value)):
        return
    raise NonFiniteResult(
        f"{quantity}: not finite for v with max |v_i| = {np.max(np.abs(v)):.3g} rad/s"
        " (float64 overflow); velocities this large are not physical",
        quantity,
    )


class KineticEnergyMetric(Metric):
    """The kinetic-energy metric of a robot: ``G(q) = M(q)`` (armature included).

    Geodesics of this metric solve ``M(q) qdd + C(q, qd) qd = 0``: passive motions without
    gravity or torque. Two paths compute it:

    - numeric (fast) on Pinocchio: `G` is ``pin.crba``, `coriolis` is ``pin.rnea`` with
      zero gravity and zero acceleration, `geodesic_acceleration` is ``pin.aba`` with zero
      gravity and zero torque;
    - symbolic on CasADi SX from geosyn's own recursive algorithms (CRBA, RNEA, ABA in
      `geosyn.robots.symbolic`), from which `Metric` derives dG/dq and the Christoffel
      symbols, optionally compiled to C and cached on disk (``compile=True``).

    Args:
        robot: a fixed-base robot (a floating base takes
            `geosyn.metrics.FloatingKineticEnergyMetric`).
        compile: compile the CasADi functions to C (cached on disk by a hash of the
            generated code) on first use. Falls back to CasADi's VM, with a warning, when
            no C compiler is available.

    Methods `G`, `coriolis` and `geodesic_acceleration` allocate only their result.

    Raises:
        InvalidArgument: ``robot`` is not a `Robot`.
        FloatingBaseUnsupported: a floating-base robot (the message names its metric).
    """

    def __init__(self, robot: Robot, *, compile: bool = False) -> None:
        if not isinstance(robot, Robot):
            raise InvalidArgument(f"robot must be a geosyn Robot, got {type(robot).__name__}")
        if robot.floating:
            raise FloatingBaseUnsupported(
                f"robot {robot.name!r} has a floating base (q on SE(3) x R^{robot.nv - 6},"
                f" nq={robot.nq}, nv={robot.nv}): its kinetic-energy metric is"
                " geosyn.metrics.FloatingKineticEnergyMetric(robot); or load it with"
                " fixed_base=True"
            )
        self.robot = robot
        self.n = robot.nv
        self.compile = bool(compile)
        self._model = robot.model
        self._data = robot.model.createData()
        # A zero-gravity copy: geodesics are passive motions without gravity.
        self._model0 = pin.Model(robot.model)
        self._model0.gravity = pin.Motion.Zero()
        self._data0 = self._model0.createData()
        self._zero = np.zeros(self.n)
        # Velocity indices of the root joints (children of the universe): one for a serial
        # arm, several for hands and humanoids (see `G`).
        self._roots = tuple(
            int(robot.model.joints[j].idx_v)
            for j in range(1, robot.model.njoints)
            if robot.model.parents[j] == 0
        )
        self._root, self._other_roots = self._roots[0], self._roots[1:]

    def __repr__(self) -> str:
        return f"KineticEnergyMetric({self.robot.name!r}, n={self.n})"

    # -- numeric fast path -----------------------------------------------------------
    def G(self, q: Vector) -> Matrix:
        """Mass matrix M(q).

        Args:
            q: (n,) joint positions [rad].

        Returns:
            (n, n) symmetric positive-definite mass matrix [kg m^2].
        """
        # Fast path. Pinocchio itself rejects a wrong size (ValueError). A NaN or inf in
        # the angle of a non-root joint propagates through the composite inertias into the
        # diagonal entry M[r, r] of its root joint r; a root joint's own angle leaves M
        # finite. So the sum of M[r, r] + q[r] over the root joints (one for a serial arm,
        # several for a hand or a humanoid) is finite exactly when q and M are: a few
        # scalar reads, no O(n) reduction (tests inject NaN/inf into each coordinate and
        # count the pin.crba calls).
        try:
            M = pin.crba(self._model, self._data, q)
            r = self._root
            q_r = q.item(r)
            check = M.item(r, r) + q_r
            for r in self._other_roots:
                check += M.item(r, r) + q.item(r)
            if math.isfinite(check) and type(q_r) is float:  # not bool/int: checked below
                return M
        except (AttributeError, TypeError, ValueError, IndexError):
            pass
        return pin.crba(self._model, self._data, self._check(q, "q"))

    def coriolis(self, q: Vector, v: Vector) -> Vector:
        """Coriolis and centrifugal torques ``C(q, v) v`` [N m] (no gravity).

        Args:
            q: (n,) joint positions [rad].
            v: (n,) joint velocities [rad/s].
        """
        q = self._check(q, "q")
        v = self._check(v, "v")
        c = pin.rnea(self._model0, self._data0, q, v, self._zero).copy()
        if not math.isfinite(c.dot(c)):
            _raise_non_finite("coriolis", c, v)
        return c

    def quadratic_gradient(self, q: Vector, d: Vector) -> Vector:
        """Gradient in ``q`` of ``d^T M(q) d`` [kg m^2], ``2 C(q, d)^T d`` with
        Pinocchio's Coriolis matrix (``M' = C + C^T`` and ``C(q, d) d`` the Coriolis
        torque give ``d/dq (1/2 d^T M d) = C^T d``; the armature is constant).

        Args:
            q: (n,) joint positions [rad].
            d: (n,) a tangent vector [rad].
        """
        q = self._check(q, "q")
        d = self._check(d, "d")
        C = pin.computeCoriolisMatrix(self._model, self._data, q, d)
        g = 2.0 * (C.T @ d)
        if not math.isfinite(g.dot(g)):
            _raise_non_finite("quadratic_gradient", g, d)
        return g

    def G_many(self, Q: np.ndarray) -> np.ndarray:
        """Mass matrices at K configurations (``pin.crba`` on each row, the input checked
        once).

        Args:
            Q: (K, n) joint positions [rad].

        Returns:
            (K, n, n) mass matrices [kg m^2].
        """
        Q = check_rows(Q, self.n, "Q")
        out = np.empty((len(Q), self.n, self.n))
        model, data = self._model, self._data
        for k in range(len(Q)):
            out[k] = pin.crba(model, data, Q[k])
        return out

    def quadratic_gradients(self, Q: np.ndarray, D: np.ndarray) -> np.ndarray:
        """`quadratic_gradient` at K pairs: ``2 C(Q[k], D[k])^T D[k]`` with Pinocchio's
        Coriolis matrix, the input checked once.

        Args:
            Q: (K, n) joint positions [rad].
            D: (K, n) tangent vectors [rad].

        Returns:
            (K, n) gradients [kg m^2].
        """
        Q, D = self._pairs(Q, D)
        C = np.empty((len(Q), self.n, self.n))
        model, data = self._model, self._data
        for k in range(len(Q)):
            C[k] = pin.computeCoriolisMatrix(model, data, Q[k], D[k])
        g = 2.0 * np.einsum("kij,ki->kj", C, D)
        if not math.isfinite(float(np.vdot(g, g))):
            _raise_non_finite("quadratic_gradients", g, D)
        return g

    def geodesic_acceleration(self, q: Vector, v: Vector) -> Vector:
        """``-M(q)^-1 C(q, v) v`` [rad/s^2], by ``pin.aba`` with zero gravity and torque.

        Args:
            q: (n,) joint positions [rad].
            v: (n,) joint velocities [rad/s].
        """
        # Fast path: finite q and |v|^2 < 1e200 keep -M^-1 C(q, v) v finite (it grows as
        # |v|^2), so only the input needs a check; larger or non-finite input takes the
        # checked path below, which also checks the result.
        try:
            if q.dot(q) + v.dot(v) < _FAST_BOUND:
                return pin.aba(self._model0, self._data0, q, v, self._zero)
        except (AttributeError, TypeError, ValueError):
            pass
        q = self._check(q, "q")
        v = self._check(v, "v")
        a = pin.aba(self._model0, self._data0, q, v, self._zero)
        if not math.isfinite(a.dot(a)):
            _raise_non_finite("geodesic_acceleration", a, v)
        return a

    # -- symbolic path ---------------------------------------------------------------
    def symbolic_G(self, q: ca.SX) -> ca.SX:
        """SX mass matrix from geosyn's recursive CRBA (armature included)."""
        from geosyn.robots import symbolic

        return symbolic.crba(self._model, q)

    def symbolic_coriolis(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX ``C(q, v) v`` from the recursive RNEA with zero gravity and acceleration."""
        from geosyn.robots import symbolic

        return symbolic.rnea(self._model, q, v, ca.SX.zeros(self.n), np.zeros(3))

    def symbolic_geodesic_acceleration(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX geodesic acceleration from the recursive ABA (no symbolic inverse)."""
        from geosyn.robots import symbolic

        return symbolic.aba(self._model, q, v, ca.SX.zeros(self.n), np.zeros(3))
