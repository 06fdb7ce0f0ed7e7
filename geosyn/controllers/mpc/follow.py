"""Following an MPC plan between solves (`PlanFollower`), and the reference when there
is no plan."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from geosyn.controllers.mpc.ocp.dynamics import dry_friction
from geosyn.controllers.mpc.ocp.plan import EPS_T, MPCPlan
from geosyn.controllers.reference import Reference
from geosyn.core.interpolation import hermite_point
from geosyn.core.types import Vector

__all__ = ["PlanFollower", "plan_state"]


def plan_state(plan: MPCPlan, t: float, dt: float) -> tuple[int, np.ndarray, np.ndarray]:
    """Stage index and planned ``(q, v)`` at time ``t``: cubic Hermite between stages.

    Args:
        plan: the plan.
        t: time [s]; before ``plan.t`` it is the first state, past the horizon the last.
        dt: stage length [s].

    Returns:
        ``(j, q, v)``: the stage ``j`` containing ``t``, (nv,) positions [rad] and
        velocities [rad/s].
    """
    N = plan.u.shape[0]
    n = plan.u.shape[1]
    s = max(t - plan.t, 0.0)
    j = min(int(s / dt + EPS_T), N - 1)
    frac = min((s - j * dt) / dt, 1.0)
    x0, x1 = plan.x[j], plan.x[j + 1]
    q, v = hermite_point(x0[:n], x0[n:], x1[:n], x1[n:], dt, frac)
    return j, q, v


class PlanFollower:
    """Follows a plan between solves, and the reference when there is no plan.

    On a plan, the first control of the current stage ``j`` is held and a feedback keeps
    the plant on the planned states:

    .. math::
        \\tau = u^*_j + M(q) (K_p (q^*(t) - q) + K_d (v^*(t) - v))

    (torque control), or ``tau = RNEA(q, v, u^*_j + K_p (q^* - q) + K_d (v^* - v))``
    (acceleration control), with ``(q^*, v^*)`` the cubic Hermite interpolation of the
    planned states (`plan_state`). A plan with DDP gains (``plan.K``) is followed by its
    own feedback, saturated at the torque limits like the DDP rollout:
    ``tau = clip(u^*_j + K_j ((q, v) - (q^*, v^*)), -tau_max, tau_max)`` (the saturated
    joints in `clipped`, which `GeodesicMPC` flags in its diagnostics). A plan's
    dry-friction feed-forward of the stage (`MPCPlan.friction`) is added to each of
    these torques; the computed torque on the reference adds ``f_c tanh(v_r / v_s)``.

    Args:
        model: Pinocchio model of the plant.
        data: its workspace (shared with the caller; used per call).
        control: ``"torque"`` or ``"acceleration"``: what the plan's controls are.
        dt: stage length [s].
        kp: (nv,) stiffness [1/s^2].
        kd: (nv,) damping [1/s].
        plan_tolerance: max joint deviation from a plan that may still be followed [rad].
        tau_max: (nv,) torque limits [N m] saturating the DDP feedback (None: no plan
            with gains is expected).
        damping: (nv,) the robot file's viscous joint damping D [N m s/rad] added to
            the inverse dynamics (``RNEA + D v``), or None.
        friction: (nv,) the robot file's dry joint friction ``f_c`` [N m], fed forward
            on the reference velocity by `reference_torque`, or None.

    Each method allocates only (nv,) arrays (and ``M`` in torque control).
    """

    def __init__(
        self,
        model: pin.Model,
        data: pin.Data,
        control: str,
        dt: float,
        kp: Vector,
        kd: Vector,
        plan_tolerance: float,
        tau_max: Vector | None = None,
        damping: Vector | None = None,
        friction: Vector | None = None,
    ) -> None:
        self._model, self._data = model, data
        self._damping = damping
        self._friction = friction
        self.tau_max = None if tau_max is None else np.asarray(tau_max, dtype=np.float64)
        self.torque_control = control == "torque"
        self.dt, self.kp, self.kd = dt, kp, kd
        self.plan_tolerance = plan_tolerance
        #: (nv,) joints whose DDP feedback torque the last `torque` call saturated.
        self.clipped = np.zeros(model.nv, dtype=bool)

    def torque(self, plan: MPCPlan, t: float, q: Vector, v: Vector) -> Vector:
        """(nv,) torque [N m] that follows ``plan`` at time ``t`` from the state ``(q, v)``."""
        j, q_p, v_p = plan_state(plan, t, self.dt)
        f = 0.0 if plan.friction is None else plan.friction[j]
        self.clipped[:] = False
        if plan.K is not None and self.tau_max is not None:
            tau = plan.u[j] + f + plan.K[j] @ np.concatenate([q - q_p, v - v_p])
            np.greater(np.abs(tau), self.tau_max, out=self.clipped)
            return np.clip(tau, -self.tau_max, self.tau_max)
        fb = self.kp * (q_p - q) + self.kd * (v_p - v)
        if self.torque_control:
            M = pin.crba(self._model, self._data, q)
            return plan.u[j] + f + M @ fb
        return self._inverse_dynamics(q, v, plan.u[j] + fb) + f

    def usable(self, plan: MPCPlan | None, t: float, q: Vector) -> bool:
        """A successful plan that still covers ``t`` and is within tolerance of ``q``."""
        if plan is None or not plan.success:
            return False
        if t - plan.t >= plan.u.shape[0] * self.dt - EPS_T:
            return False
        _, q_p, _ = plan_state(plan, t, self.dt)
        return float(np.max(np.abs(q_p - q))) <= self.plan_tolerance

    def reference_torque(self, reference: Reference, t: float, q: Vector, v: Vector) -> Vector:
        """(nv,) computed torque [N m] on ``reference`` with the same gains (no plan)."""
        self.clipped[:] = False
        q_ref, v_ref, a_ref = reference.sample(t)
        a = a_ref + self.kp * (q_ref - q) + self.kd * (v_ref - v)
        tau = self._inverse_dynamics(q, v, a)
        if self._friction is not None:
            tau += dry_friction(self._friction, v_ref)
        return tau

    def _inverse_dynamics(self, q: Vector, v: Vector, a: Vector) -> Vector:
        """(nv,) ``RNEA(q, v, a) + D v`` [N m] (a new array)."""
        tau = pin.rnea(self._model, self._data, q, v, a).copy()
        if self._damping is not None:
            tau += self._damping * v
        return tau
