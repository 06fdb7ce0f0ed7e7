"""Computed-torque (inverse-dynamics) tracking of a joint reference."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from geosyn.controllers.base import Controller, check_gain
from geosyn.controllers.reference import Reference
from geosyn.core.types import Vector
from geosyn.robots.robot import Robot

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric


class ComputedTorque(Controller):
    """Computed torque: feedback linearisation plus PD on the tracking error.

    .. math::
        \\tau = M(q)\\,(\\ddot q_r + K_d (\\dot q_r - \\dot q) + K_p (q_r - q))
                + C(q, \\dot q)\\dot q + g(q)

    evaluated in one recursive Newton-Euler pass, ``pin.rnea(model, data, q, v, a_des)``.
    With an exact model the closed-loop error obeys ``e'' + Kd e' + Kp e = 0``.

    The controller's model of the plant is the robot's rigid-body dynamics. ``metric``
    (e.g. a shaped metric) is *not* used in the control law: it only shapes references
    (`GeodesicReference`, `replan_geodesic`); it is kept as an attribute so that a
    supervisor can replan with ``replan_geodesic(ctl.metric, q, v, ctl.reference.goal())``.

    Args:
        robot: the robot (dynamics model and torque limits).
        kp: position gain, scalar or (nv,) [1/s^2], >= 0.
        kd: velocity gain, scalar or (nv,) [1/s], >= 0.
        metric: optional metric used only for reference generation and replanning.
        reference: optional reference to track.

    `compute` allocates a few (nv,) arrays (the reference sample and the torque).
    """

    def __init__(
        self,
        robot: Robot,
        kp: float | np.ndarray,
        kd: float | np.ndarray,
        metric: Metric | None = None,
        reference: Reference | None = None,
    ) -> None:
        super().__init__(robot, reference, metric)
        self.kp = check_gain(kp, self.nv, "kp")
        self.kd = check_gain(kd, self.nv, "kd")
        self._a_des = np.zeros(self.nv)

    def desired_acceleration(self, t: float, q: Vector, v: Vector) -> Vector:
        """PD-corrected reference acceleration ``a_ref + Kd (v_ref - v) + Kp (q_ref - q)``.

        Args:
            t: time [s] (a reference must be set).
            q: (nv,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].

        Returns:
            (nv,) acceleration [rad/s^2], in an internal buffer overwritten by the next call.
        """
        q_ref, v_ref, a_ref = self._reference.sample(t)  # type: ignore[union-attr]
        out = self._a_des
        np.subtract(q_ref, q, out=out)
        out *= self.kp
        out += a_ref
        v_err = v_ref - v
        v_err *= self.kd
        out += v_err
        return out

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        a_des = self.desired_acceleration(t, q, v)
        return pin.rnea(self._model, self._data, q, v, a_des)
