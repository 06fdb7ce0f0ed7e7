"""A Pinocchio plant: forward dynamics (``pin.aba``) integrated by RK4, for tests.

Controllers are tested against it without MuJoCo. The torque is held constant over a
step (zero-order hold, as a digital controller applies it). The robot file's armature
(in the model) and viscous joint damping (``-D v``) are part of the plant, as in MuJoCo;
its dry friction (``frictionloss``, a constraint in MuJoCo) is not modelled and is
reported (a `RobotWarning` and `PinocchioPlant.unmodelled`). An optional payload
(`geosyn.world.Payload`), rigidly attached to a frame of a copy of the model, gives the
plant dynamics the controller does not know about.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_positive, check_vector
from geosyn.robots.errors import RobotWarning
from geosyn.robots.robot import Robot
from geosyn.world.payload import Payload

if TYPE_CHECKING:
    from geosyn.controllers.base import Controller


class Rollout(NamedTuple):
    """A closed-loop simulation.

    Attributes:
        t: (T,) time stamps [s] (T = steps + 1, the first is the initial state).
        q: (T, nq) joint positions [rad].
        v: (T, nv) joint velocities [rad/s].
        tau: (T-1, nv) torques applied over each step [N m].
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray


class PinocchioPlant:
    """Rigid-body plant: ``qdd = aba(q, v, tau - D v)``, RK4 with zero-order-hold torque.

    Args:
        robot: the robot (its model, with armature and gravity, is the plant).
        dt: integration step [s], > 0 (1 kHz by default).
        payload: optional `geosyn.world.Payload` (or the tuple of its first fields,
            ``(frame, mass[, com[, inertia[, radius]]])``) added to the plant only, not to
            ``robot``.

    Attributes:
        model: the plant's Pinocchio model (a copy of ``robot.model`` with the payload).
        damping: (nv,) the file's viscous joint damping D, applied as ``-D v`` [N m s/rad].
        unmodelled: what the file states that this plant does not model (e.g. dry
            friction), each also reported once as a `RobotWarning`.
        q, v, t: current state [rad], [rad/s] and time [s] (read via the properties).

    `step` allocates the RK4 stages (4 ``pin.aba`` calls).
    """

    def __init__(
        self, robot: Robot, dt: float = 1e-3, payload: Payload | tuple | None = None
    ) -> None:
        if not isinstance(robot, Robot):
            raise InvalidArgument(f"robot must be a geosyn Robot, got {type(robot).__name__}")
        robot.require_fixed_base("PinocchioPlant (its RK4 integrates q + v dt)")
        dt = check_positive(dt, "dt", "s")
        self.robot = robot
        self.dt = dt
        self.model = pin.Model(robot.model)
        self.payload = None if payload is None else self._attach(payload)
        self.data = self.model.createData()
        self.damping = np.asarray(robot.damping, dtype=np.float64).copy()
        self._damped = bool(np.any(self.damping))
        self.unmodelled: tuple[str, ...] = ()
        if np.any(robot.frictionloss):
            self.unmodelled = (
                f"dry joint friction (frictionloss {robot.frictionloss.tolist()} N m)",
            )
            warnings.warn(
                f"PinocchioPlant of {robot.name!r} does not model the file's"
                f" {self.unmodelled[0]}; simulate the file in MuJoCo (plant='file') for it",
                RobotWarning,
                stacklevel=2,
            )
        self._q = robot.neutral()
        self._v = np.zeros(robot.nv)
        self._t = 0.0

    def _attach(self, payload: Payload | tuple) -> Payload:
        try:
            p = payload if isinstance(payload, Payload) else Payload(*payload)
        except TypeError as err:
            raise InvalidArgument(
                "payload must be a geosyn.world.Payload or (frame, mass[, com[, inertia]]),"
                f" got {payload!r}"
            ) from err
        frame = self.model.frames[self.robot.frame_id(p.frame)]
        body = pin.Inertia(p.mass, np.array(p.com), p.rotational_inertia())
        jid = frame.parentJoint
        # Express the payload in the parent joint's frame and lump it into that body.
        self.model.inertias[jid] = self.model.inertias[jid] + frame.placement.act(body)
        return p

    # -- state ------------------------------------------------------------------------
    @property
    def q(self) -> Vector:
        """(nq,) joint positions [rad] (a copy)."""
        return self._q.copy()

    @property
    def v(self) -> Vector:
        """(nv,) joint velocities [rad/s] (a copy)."""
        return self._v.copy()

    @property
    def t(self) -> float:
        """Current time [s]."""
        return self._t

    def reset(self, q: Vector, v: Vector, t: float = 0.0) -> None:
        """Set the state.

        Args:
            q: (nq,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].
            t: time [s].
        """
        self._q = check_vector(q, self.robot.nq, "q").copy()
        self._v = check_vector(v, self.robot.nv, "v").copy()
        self._t = float(t)

    # -- dynamics ---------------------------------------------------------------------
    def acceleration(self, q: Vector, v: Vector, tau: Vector) -> Vector:
        """Forward dynamics of the plant (payload and joint damping included).

        Args:
            q: (nq,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].
            tau: (nv,) applied joint torques [N m].

        Returns:
            (nv,) joint accelerations [rad/s^2] (a new array).
        """
        if self._damped:
            tau = tau - self.damping * v
        return pin.aba(self.model, self.data, q, v, tau).copy()

    def step(self, tau: Vector) -> tuple[Vector, Vector]:
        """Advance one step ``dt`` with the torque held constant.

        Args:
            tau: (nv,) joint torques [N m].

        Returns:
            The new ``(q, v)`` (copies).
        """
        tau = check_vector(tau, self.robot.nv, "tau")
        h = self.dt
        q, v = self._q, self._v
        a1 = self.acceleration(q, v, tau)
        v2 = v + 0.5 * h * a1
        a2 = self.acceleration(q + 0.5 * h * v, v2, tau)
        v3 = v + 0.5 * h * a2
        a3 = self.acceleration(q + 0.5 * h * v2, v3, tau)
        v4 = v + h * a3
        a4 = self.acceleration(q + h * v3, v4, tau)
        self._q = q + (h / 6.0) * (v + 2.0 * v2 + 2.0 * v3 + v4)
        self._v = v + (h / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        self._t += h
        return self._q.copy(), self._v.copy()

    def rollout(
        self,
        controller: Controller,
        duration: float,
        callback: Callable[[float, Vector, Vector, Vector], None] | None = None,
    ) -> Rollout:
        """Closed loop from the current state: ``tau = controller.compute(t, q, v)``.

        Args:
            controller: any `Controller` (reference already set).
            duration: simulated time [s].
            callback: optional ``f(t, q, v, tau)`` called before each step.

        Returns:
            The `Rollout` (allocates its arrays).
        """
        steps = int(round(float(duration) / self.dt))
        if steps < 1:
            raise InvalidArgument(
                f"duration must be at least one step dt={self.dt}, got {duration}"
            )
        nq, nv = self.robot.nq, self.robot.nv
        t = np.empty(steps + 1)
        qs = np.empty((steps + 1, nq))
        vs = np.empty((steps + 1, nv))
        taus = np.empty((steps, nv))
        t[0], qs[0], vs[0] = self._t, self._q, self._v
        for k in range(steps):
            tau = controller.compute(self._t, self._q, self._v)
            if callback is not None:
                callback(self._t, self._q, self._v, tau)
            taus[k] = tau
            self.step(tau)
            t[k + 1], qs[k + 1], vs[k + 1] = self._t, self._q, self._v
        return Rollout(t, qs, vs, taus)
