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


def tracking_acceleration(
    reference: Reference,
    t: float,
    q: Vector,
    v: Vector,
    kp: Vector,
    kd: Vector,
    out: Vector,
) -> Vector:
    """PD-corrected reference acceleration ``a_ref + Kd (v_ref - v) + Kp (q_ref - q)``.

    Args:
        reference: the reference, sampled at ``t``.
        t: time [s].
        q: (nv,) joint positions [rad].
        v: (nv,) joint velocities [rad/s].
        kp: (nv,) position gains [1/s^2].
        kd: (nv,) velocity gains [1/s].
        out: (nv,) buffer written and returned [rad/s^2].
    """
    q_ref, v_ref, a_ref = reference.sample(t)
    np.subtract(q_ref, q, out=out)
    out *= kp
    out += a_ref
    v_err = v_ref - v
    v_err *= kd
    out += v_err
    return out


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
        self._model = robot.model
        self._data = robot.model.createData()
        self._a_des = np.zeros(self.nv)

    def desired_acceleration(self, t: float, q: Vector, v: Vector) -> Vector:
        """``a_ref + Kd (v_ref - v) + Kp (q_ref - q)`` [rad/s^2] (into an internal buffer)."""
        return tracking_acceleration(
            self._reference,  # type: ignore[arg-type]
            t,
            q,
            v,
            self.kp,
            self.kd,
            self._a_des,
        )

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        a_des = self.desired_acceleration(t, q, v)
        return pin.rnea(self._model, self._data, q, v, a_des)
