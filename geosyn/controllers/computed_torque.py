"""Computed-torque (inverse-dynamics) tracking of a joint reference."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from geosyn.controllers.base import FRICTION_VELOCITY, Controller, check_gain
from geosyn.controllers.reference import Reference
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_positive
from geosyn.robots.robot import Robot

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric


class ComputedTorque(Controller):
    """Computed torque: feedback linearisation plus PD on the tracking error.

    .. math::
        \\tau = M(q)\\,(\\ddot q_r + K_d (\\dot q_r - \\dot q) + K_p (q_r - q))
                + C(q, \\dot q)\\dot q + g(q)

    evaluated in one recursive Newton-Euler pass, ``pin.rnea(model, data, q, v, a_des)``.
    With an exact model the closed-loop error obeys ``e'' + Kd e' + Kp e = 0``. Joint
    damping and dry friction of the robot file (not part of M, C, g) are added when
    ``compensate_friction`` is on (by default, when the robot has them).

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
        compensate_friction: add the robot's joint friction to the torque,
            ``D v + f_c tanh(v_r / friction_velocity)`` (``robot.damping``,
            ``robot.frictionloss``: the file's viscous damping and dry friction). Dry
            friction is a feed-forward on the reference velocity ``v_r``: compensated on the
            measured velocity, its smoothed sign is a high-gain positive feedback near rest
            that destabilises light joints (it spun the xarm7's wrist up from rest). ``None`` (default): on exactly when
            the robot has joint friction; the choice is recorded in ``diagnostics.notes``.
        friction_velocity: velocity [rad/s or m/s] over which the dry-friction
            compensation goes smoothly from 0 to ``f_c`` (a smoothed sign), > 0.

    `compute` allocates a few (nv,) arrays (the reference sample and the torque).
    """

    def __init__(
        self,
        robot: Robot,
        kp: float | np.ndarray,
        kd: float | np.ndarray,
        metric: Metric | None = None,
        reference: Reference | None = None,
        *,
        compensate_friction: bool | None = None,
        friction_velocity: float = FRICTION_VELOCITY,
    ) -> None:
        super().__init__(robot, reference, metric)
        self.kp = check_gain(kp, self.nv, "kp")
        self.kd = check_gain(kd, self.nv, "kd")
        self._a_des = np.zeros(self.nv)
        if compensate_friction is not None and not isinstance(compensate_friction, bool):
            raise InvalidArgument(
                f"compensate_friction must be true, false or None, got {compensate_friction!r}"
            )
        self.friction_velocity = check_positive(friction_velocity, "friction_velocity")
        self._v_ref = np.zeros(robot.model.nv)  # last reference velocity [rad/s]
        has = robot.has_joint_friction
        self.compensate_friction = has if compensate_friction is None else compensate_friction
        if self.compensate_friction:
            why = " (on by default: the robot has joint friction)" if has else ""
            self.diagnostics.notes["compensate_friction"] = (
                f"joint damping {robot.damping.tolist()} and dry friction"
                f" {robot.frictionloss.tolist()} compensated"
                + (why if compensate_friction is None else "")
            )
        self._damping = np.asarray(robot.damping, dtype=np.float64)
        self._friction = np.asarray(robot.frictionloss, dtype=np.float64)

    def joint_friction(self, v: Vector, v_ref: Vector) -> Vector:
        """The robot's joint friction torque to compensate, ``D v + f_c tanh(v_r / v_s)``.

        Args:
            v: (nv,) measured joint velocities [rad/s] (viscous damping).
            v_ref: (nv,) reference joint velocities [rad/s] (dry friction, feed-forward).

        Returns:
            (nv,) torques [N m] (a new array).
        """
        out = np.tanh(v_ref / self.friction_velocity)
        out *= self._friction
        out += self._damping * v
        return out

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
        self._v_ref = v_ref
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
        tau = pin.rnea(self._model, self._data, q, v, a_des)
        if self.compensate_friction:
            tau = tau + self.joint_friction(v, self._v_ref)
        return tau
