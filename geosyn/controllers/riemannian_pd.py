"""A passivity-based (Slotine-Li) tracking controller on the configuration manifold."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from geosyn.controllers.base import FRICTION_VELOCITY, Controller, check_gain
from geosyn.controllers.reference import Reference
from geosyn.core.types import Vector
from geosyn.core.validation import check_positive
from geosyn.robots.robot import Robot

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric


class RiemannianPD(Controller):
    """Slotine-Li passivity-based tracking with the Christoffel-symbol Coriolis matrix.

    With ``e = q - q_r``, the reference velocity and acceleration are shifted by the
    position error and the sliding variable ``s`` measures the velocity mismatch:

    .. math::
        v_r = \\dot q_r - \\Lambda e, \\quad a_r = \\ddot q_r - \\Lambda \\dot e,
        \\quad s = \\dot q - v_r = \\dot e + \\Lambda e,

    .. math::
        \\tau = M(q) a_r + C(q, \\dot q) v_r + g(q) + D v_r
               + f_c \\tanh(v_r / v_s) - K s,

    where ``C_ij = sum_k Gamma_ijk qdot_k`` is built from the Christoffel symbols of the
    first kind of the kinetic-energy metric ``M`` (``pin.computeCoriolisMatrix``), the
    Levi-Civita connection of the configuration manifold. Only ``C(q, qdot) v_r`` (not
    ``C v``) appears, which is what makes the law passive rather than a cancellation.

    ``D`` is the robot file's viscous joint damping (``robot.damping``; zero when the file
    has none), the plant's ``-D qdot`` compensated along ``v_r`` so that the closed loop
    keeps its form with ``K + D`` in place of ``K``. ``f_c`` is the file's dry joint
    friction (``robot.frictionloss``), compensated along ``v_r`` too, smoothed over
    ``v_s`` (``friction_velocity``): the mismatch with the plant's ``f_c sign(qdot)`` adds
    ``s^T f_c (tanh(v_r / v_s) - sign(qdot))`` to ``Vdot`` below, which is ``<= 0`` up to
    the smoothing (``s = qdot - v_r`` and the sign is monotone), so passivity is kept.

    Stability. With an exact model the closed loop is ``M s' + C s + (K + D) s = 0``. Because
    ``Mdot - 2C`` is skew-symmetric for the Christoffel ``C``, the function

    .. math:: V = \\tfrac12 s^T M(q) s + e^T \\Lambda K e

    satisfies (``Lambda``, ``K`` diagonal positive, so ``Lambda K`` is symmetric)

    .. math::
        \\dot V = -s^T K s + 2 e^T \\Lambda K \\dot e
                = -\\dot e^T K \\dot e - e^T \\Lambda K \\Lambda e \\le 0,

    negative definite in ``(e, edot)``: the tracking error converges exponentially
    (``V`` is bounded above and below by quadratics in ``(e, edot)``). Under bounded
    model errors (an unknown payload) the error stays bounded. `lyapunov` evaluates
    ``V`` and the last value is in ``diagnostics.extra["lyapunov"]``.

    As for `ComputedTorque`, ``metric`` only shapes references and replanning; the
    control law uses the robot's dynamics.

    Args:
        robot: the robot (dynamics model and torque limits).
        lam: ``Lambda``, scalar or (nv,) [1/s], > 0 for convergence.
        k: ``K``, scalar or (nv,) [N m s/rad], > 0 for convergence.
        metric: optional metric used only for reference generation and replanning.
        reference: optional reference to track.
        friction_velocity: velocity [rad/s or m/s] over which the dry-friction
            compensation goes smoothly from 0 to ``f_c`` (a smoothed sign), > 0.

    `compute` allocates the reference sample, ``M`` and ``C`` (Pinocchio returns copies).
    """

    def __init__(
        self,
        robot: Robot,
        lam: float | np.ndarray,
        k: float | np.ndarray,
        metric: Metric | None = None,
        reference: Reference | None = None,
        *,
        friction_velocity: float = FRICTION_VELOCITY,
    ) -> None:
        super().__init__(robot, reference, metric)
        self.lam = check_gain(lam, self.nv, "lam")
        self.k = check_gain(k, self.nv, "k")
        self._e = np.zeros(self.nv)
        self._s = np.zeros(self.nv)
        damping = np.asarray(robot.damping, dtype=np.float64)
        self._damping = damping.copy() if damping.size and np.any(damping) else None
        if self._damping is not None:
            self.diagnostics.notes["damping"] = (
                f"joint damping {self._damping.tolist()} compensated along v_r"
            )
        self.friction_velocity = check_positive(friction_velocity, "friction_velocity")
        friction = np.asarray(robot.frictionloss, dtype=np.float64)
        self._friction = friction.copy() if friction.size and np.any(friction) else None
        if self._friction is not None:
            self.diagnostics.notes["frictionloss"] = (
                f"dry joint friction {self._friction.tolist()} compensated along v_r"
                f" (f_c tanh(v_r / {self.friction_velocity:g}))"
            )

    def lyapunov(self, t: float, q: Vector, v: Vector) -> float:
        """``V = 1/2 s^T M s + e^T Lambda K e`` at the state (allocates).

        Args:
            t: time [s].
            q: (nq,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].
        """
        q_ref, v_ref, _ = self._reference.sample(t)  # type: ignore[union-attr]
        e = q - q_ref
        s = v - v_ref + self.lam * e
        M = pin.crba(self._model, self._data, q)
        return float(0.5 * s @ M @ s + e @ (self.lam * self.k * e))

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        q_ref, v_ref, a_ref = self._reference.sample(t)  # type: ignore[union-attr]
        lam = self.lam
        e = self._e
        np.subtract(q, q_ref, out=e)
        # v_ref becomes v_r = v_ref - lam e; a_ref becomes a_r = a_ref - lam (v - v_ref).
        a_ref -= lam * (v - v_ref)
        v_ref -= lam * e
        s = self._s
        np.subtract(v, v_ref, out=s)
        model, data = self._model, self._data
        M = pin.crba(model, data, q)  # full symmetric matrix (pinocchio >= 3)
        C = pin.computeCoriolisMatrix(model, data, q, v)
        tau = M @ a_ref
        tau += C @ v_ref
        tau += pin.computeGeneralizedGravity(model, data, q)
        if self._damping is not None:
            tau += self._damping * v_ref
        if self._friction is not None:
            tau += self._friction * np.tanh(v_ref / self.friction_velocity)
        tau -= self.k * s
        self.diagnostics.extra["lyapunov"] = 0.5 * float(s @ M @ s) + float(e @ (lam * self.k * e))
        return tau
