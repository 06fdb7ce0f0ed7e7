"""The joint-limit guard: a safety filter between a controller's torque and the motors
(`JointLimitGuard`), and how a controller applies and reports it every tick
(`GuardedCommand`).

The guard keeps the joint position and velocity limits as hard constraints whatever law
produced the torque (an MPC whose limits are penalties, a plan followed between solves,
a fallback). With the torque held over the next control period ``h``, it takes the
smallest change of the torque, in the inverse mass matrix's norm, that puts the
acceleration ``a = M^{-1} (tau - b)`` (``b = RNEA(q, v, 0) + D v``: bias torques and the
robot file's viscous damping) inside the box of `geosyn.controllers.limit_bounds`
(velocity limit one period ahead, position limit one period ahead, braking curve) and the
torque inside its limits:

.. math::
    \\min_{\\tau'}\\; (\\tau' - \\tau)^T M^{-1} (\\tau' - \\tau)
    \\quad\\text{s.t.}\\quad a_{lo} \\le M^{-1}(\\tau' - b) \\le a_{hi},\\;
    |\\tau'| \\le \\tau_{max}

Solved in the acceleration ``a'`` (``tau' = M a' + b``): ``min (a' - a)^T M (a' - a)``
with ``a'`` in a box and ``M a'`` in a box (proxsuite, dense, warm-started). The
``M^{-1}`` norm is the kinetic-energy metric's norm of the acceleration change, so the
guard removes the least motion energy from what the law asked for; a torque already
inside both boxes is returned unchanged (one ``ABA`` and a few vector operations,
no QP). When the boxes cannot be met together (a state beyond a limit, or one the torque
limits cannot brake in time) the guard clips the acceleration to its box and then the
torque to its limits, and says so (status ``"infeasible"``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import proxsuite

from geosyn.controllers.base import ControllerDiagnostics
from geosyn.controllers.limit_bounds import AccelerationBounds, check_braking_acceleration
from geosyn.core.types import Vector
from geosyn.robots.robot import Robot

__all__ = [
    "BRAKING_SHARE",
    "POSITION_MARGIN",
    "VELOCITY_MARGIN",
    "GuardedCommand",
    "JointLimitGuard",
    "default_braking_acceleration",
]

BRAKING_SHARE = 0.25
"""Share of a joint's torque limit spent on braking by default (the rest is left for
gravity, Coriolis forces and the other joints' coupling): `default_braking_acceleration`."""
POSITION_MARGIN = 1e-4
"""The guard keeps positions this far inside the limits [rad] (the acceleration varies a
little over a period; the bounds assume it constant)."""
VELOCITY_MARGIN = 1e-2
"""The guard keeps velocities this far inside the limits [rad/s], likewise."""
_ACCELERATION_TOL = 1e-6  # [rad/s^2]: a torque this close to the box is inside
_TORQUE_TOL = 1e-9  # [N m]


def default_braking_acceleration(robot: Robot) -> Vector:
    """(nv,) braking acceleration [rad/s^2]: `BRAKING_SHARE` of each joint's torque limit
    over its diagonal inertia ``M_jj`` (armature included) at the neutral configuration."""
    data = robot.model.createData()
    inertia = np.diag(pin.crba(robot.model, data, robot.neutral())).copy()
    return BRAKING_SHARE * np.asarray(robot.tau_max, dtype=np.float64) / inertia


class JointLimitGuard:
    """Safety filter keeping the joint position and velocity limits over the next period
    (the module's QP; `filter`).

    Args:
        robot: the robot (dynamics, limits ``q_min, q_max, v_max, tau_max``).
        braking_acceleration: scalar or (nv,) deceleration [rad/s^2] of the braking
            curve; None: `default_braking_acceleration`.
        damping: (nv,) viscous joint damping D [N m s/rad] of the plant, or None.

    Attributes:
        braking_acceleration: (nv,) the braking acceleration in use [rad/s^2].
        status: outcome of the last `filter`: ``"inside"`` (torque unchanged),
            ``"corrected"`` (the QP's torque) or ``"infeasible"`` (clipped, see module).
        over_box: (nv,) bool, True where the last torque given exceeded ``tau_max``.
        bounds: the `AccelerationBounds` of the last `filter`.

    The constructor allocates (proxsuite's QP, once); `filter` allocates small arrays
    only when it changes the torque.
    """

    def __init__(
        self,
        robot: Robot,
        braking_acceleration: float | np.ndarray | None = None,
        damping: Vector | None = None,
    ) -> None:
        n = robot.nv
        self._model, self._data = robot.model, robot.model.createData()
        self._tau_max = np.asarray(robot.tau_max, dtype=np.float64).copy()
        b = check_braking_acceleration(braking_acceleration, n)
        self.braking_acceleration = default_braking_acceleration(robot) if b is None else b
        self._damping = None if damping is None else np.asarray(damping, dtype=np.float64)
        q_min = np.asarray(robot.q_min, dtype=np.float64) + POSITION_MARGIN
        q_max = np.asarray(robot.q_max, dtype=np.float64) - POSITION_MARGIN
        v_max = np.maximum(np.asarray(robot.v_max, dtype=np.float64) - VELOCITY_MARGIN, 0.0)
        self.bounds = AccelerationBounds(q_min, q_max, v_max, None, self.braking_acceleration)
        self._zero = np.zeros(n)
        self._tau_drive = np.zeros(n)
        self.over_box = np.zeros(n, dtype=bool)
        self.status = "inside"
        self.qp = proxsuite.proxqp.dense.QP(n, 0, n, True)
        s = self.qp.settings
        s.eps_abs, s.eps_rel, s.verbose = 1e-10, 0.0, False
        # proxsuite has no time limit: bound a tick's work (QPController's defaults; a
        # state far outside the limits, e.g. under velocity noise, is infeasible anyway).
        s.max_iter, s.max_iter_in = 100, 30
        eye = np.eye(n)
        big = np.full(n, 1e3)
        self.qp.init(eye, self._zero, None, None, eye, -big, big, -big, big)

    def filter(self, q: Vector, v: Vector, tau: Vector, period: float) -> Vector:
        """The guarded torque for the state ``(q, v)``.

        Args:
            q: (nv,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].
            tau: (nv,) the law's torque [N m].
            period: how long the torque is held [s] (> 0).

        Returns:
            (nv,) ``tau`` itself when it is inside both boxes, else a new array inside
            the torque limits (the QP's answer, or the clipped one; `status` says which).
        """
        tau_max = self._tau_max
        bounds = self.bounds
        bounds.update(q, v, period)
        np.greater(np.abs(tau), tau_max + _TORQUE_TOL, out=self.over_box)
        np.copyto(self._tau_drive, tau)
        if self._damping is not None:
            self._tau_drive -= self._damping * v
        a = pin.aba(self._model, self._data, q, v, self._tau_drive)
        inside = not self.over_box.any()
        inside = inside and bool(np.all(a >= bounds.lower - _ACCELERATION_TOL))
        if inside and bool(np.all(a <= bounds.upper + _ACCELERATION_TOL)):
            self.status = "inside"
            return tau
        return self._correct(q, v, a.copy())

    def _correct(self, q: Vector, v: Vector, a: Vector) -> Vector:
        """The QP of the module from the law's acceleration ``a`` (or its clipped form)."""
        model, data, tau_max = self._model, self._data, self._tau_max
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        bias = pin.rnea(model, data, q, v, self._zero).copy()
        if self._damping is not None:
            bias += self._damping * v
        lo, hi = self.bounds.lower, self.bounds.upper
        if bool(np.all(lo <= hi)):
            qp = self.qp
            qp.update(H=M, g=-(M @ a), C=M, l=-tau_max - bias, u=tau_max - bias, l_box=lo, u_box=hi)
            qp.solve()
            if qp.results.info.status.name == "PROXQP_SOLVED":
                self.status = "corrected"
                return np.clip(M @ qp.results.x + bias, -tau_max, tau_max)
        self.status = "infeasible"
        return np.clip(M @ np.minimum(np.maximum(a, lo), hi) + bias, -tau_max, tau_max)


class GuardedCommand:
    """A controller's last step before the motors: the `JointLimitGuard` (``guard``
    True) or a clamp to the torque limits (False), with everything it changed recorded.

    The guard's period is the time between the last two `apply` calls (the rate the
    controller is called at), ``first_period`` before the second call after a `reset`.

    Reports, in the controller's `ControllerDiagnostics`: ``extra["guard"]`` 1.0 on a tick
    whose torque the guard changed (2.0 when infeasible, see the module),
    ``extra["guard_dtau"]`` the largest change [N m], ``extra["guard_count"]`` the ticks
    changed since the last reset, and ``notes["joint_limit_guard"]`` a sentence with the
    count and the last change; a torque over its limit is a saturation (`over_box`, which
    the controller adds to ``diagnostics.saturated``).

    Args:
        robot: the robot.
        guard: apply the guard (True) or only clamp to the torque limits (False).
        first_period: the guard's period before two calls were seen [s].
        damping: (nv,) viscous joint damping [N m s/rad] of the plant, or None.

    Attributes:
        guard: the `JointLimitGuard`, or None.
        count: ticks whose torque the guard changed since the last `reset`.
        infeasible_count: of those, the ticks where it could not meet every limit.
        over_box: (nv,) bool, the joints whose law torque exceeded the limit last tick.
    """

    def __init__(
        self, robot: Robot, guard: bool, first_period: float, damping: Vector | None = None
    ) -> None:
        self.guard = JointLimitGuard(robot, damping=damping) if guard else None
        self._tau_max = np.asarray(robot.tau_max, dtype=np.float64).copy()
        self.first_period = first_period
        self.over_box = np.zeros(robot.nv, dtype=bool)
        self.reset()

    def reset(self) -> None:
        """Forget the call times and the counts."""
        self._t_last: float | None = None
        self._period = self.first_period
        self.count = 0
        self.infeasible_count = 0

    def apply(
        self, t: float, q: Vector, v: Vector, tau: Vector, diagnostics: ControllerDiagnostics
    ) -> Vector:
        """The torque to command at time ``t`` [s] for the law's ``tau`` (nv,) [N m]."""
        if self._t_last is not None and t - self._t_last > 1e-12:
            self._period = t - self._t_last
        self._t_last = t
        if self.guard is None:
            np.greater(np.abs(tau), self._tau_max + _TORQUE_TOL, out=self.over_box)
            return np.clip(tau, -self._tau_max, self._tau_max) if self.over_box.any() else tau
        out = self.guard.filter(q, v, tau, self._period)
        np.copyto(self.over_box, self.guard.over_box)
        if out is not tau:
            self._record(t, tau, out, diagnostics)
        return out

    def _record(
        self, t: float, tau: Vector, out: Vector, diagnostics: ControllerDiagnostics
    ) -> None:
        infeasible = self.guard is not None and self.guard.status == "infeasible"
        self.count += 1
        self.infeasible_count += int(infeasible)
        change = np.abs(out - tau)
        extra = diagnostics.extra
        extra["guard"] = 2.0 if infeasible else 1.0
        extra["guard_dtau"] = float(change.max())
        extra["guard_count"] = float(self.count)
        diagnostics.notes["joint_limit_guard"] = (
            f"changed the commanded torque on {self.count} ticks since reset"
            f" ({self.infeasible_count} without meeting every limit); last at t={t:.6g} s,"
            f" joints {np.flatnonzero(change > _TORQUE_TOL).tolist()},"
            f" max |dtau| {change.max():.3g} N m"
        )
