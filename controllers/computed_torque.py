"""Computed-torque (inverse-dynamics) tracking of a joint reference."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from geosyn.controllers.base import Controller, check_gain
from geosyn.controllers.reference import Reference
from geosyn.core.errors import InvalidArgument
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
        super().__init__(robot, reference)
        self.kp = check_gain(kp, self.nv, "kp")
        self.kd = check_gain(kd, self.nv, "kd")
        if metric is not None and getattr(metric, "n", None) != self.nv:
            raise InvalidArgument(
                f"metric must have dimension nv={self.nv}, got {getattr(metric, 'n', metric)!r}"
            )
        self.metric = metric
        self._model = robot.model
        self._data = robot.model.createData()
        self._a_des = np.zeros(self.nv)

    def desired_acceleration(self, t: float, q: Vector, v: Vector) -> Vector:
        """``a_ref + Kd (v_ref - v) + Kp (q_ref - q)`` [rad/s^2] (into an internal buffer)."""
        q_ref, v_ref, a_ref = self._reference.sample(t)  # type: ignore[union-attr]
        a = self._a_des
        np.subtract(q_ref, q, out=a)
        a *= self.kp
        a += a_ref
        v_ref -= v
        v_ref *= self.kd
        a += v_ref
        return a

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        a_des = self.desired_acceleration(t, q, v)
        return pin.rnea(self._model, self._data, q, v, a_des)
