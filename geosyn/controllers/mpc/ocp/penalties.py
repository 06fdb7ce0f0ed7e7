"""Soft penalties of the state: the joint limits and the obstacle clearance, as cost terms
(`geosyn.controllers.mpc.ocp.costs.StateCost`) with their Gauss-Newton derivatives.

The DDP family keeps position and velocity limits and the clearance margin this way
(stiff weights, zero inside the allowed set); the NLP family has the limits as hard
bounds. Both terms work on any stage and on the terminal state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca

from geosyn.controllers.mpc.ocp.costs import StateCost

__all__ = ["ClearancePenalty", "StateLimitPenalty"]


@dataclass(frozen=True, eq=False)
class StateLimitPenalty(StateCost):
    """``w (|max(q - q_max, 0)|^2 + |max(q_min - q, 0)|^2 + |max(|v| - v_max, 0)|^2)``.

    Attributes:
        q_min: (nv,) lower position limits [rad] (finite; see
            `geosyn.controllers.mpc.ddp.parameters.BOUND_INF`).
        q_max: (nv,) upper position limits [rad].
        v_max: (nv,) velocity limits [rad/s].
        weight: scalar weight ([1/rad^2] and [s^2/rad^2]).
    """

    q_min: Any
    q_max: Any
    v_max: Any
    weight: Any

    def state_derivatives(self, x: ca.SX, q_ref: ca.SX, v_ref: ca.SX) -> tuple[Any, Any, Any]:
        """Value, gradient (2n,) and Gauss-Newton Hessian (2n, 2n, diagonal)."""
        n, w = q_ref.numel(), self.weight
        q, v = x[:n], x[n:]
        hi_q, lo_q = ca.fmax(q - self.q_max, 0), ca.fmax(self.q_min - q, 0)
        hi_v, lo_v = ca.fmax(v - self.v_max, 0), ca.fmax(-v - self.v_max, 0)
        value = w * (ca.sumsqr(hi_q) + ca.sumsqr(lo_q) + ca.sumsqr(hi_v) + ca.sumsqr(lo_v))
        grad = 2 * w * ca.vertcat(hi_q - lo_q, hi_v - lo_v)
        active = ca.vertcat(
            ca.logic_or(q > self.q_max, q < self.q_min),
            ca.logic_or(v > self.v_max, -v > self.v_max),
        )
        return value, grad, ca.diag(2 * w * active)


@dataclass(frozen=True, eq=False)
class ClearancePenalty(StateCost):
    """``w sum max(0, m - c(q))^2`` over the clearances ``c`` of the robot's spheres to
    the obstacle slots (`geosyn.controllers.mpc.ocp.obstacles`); Gauss-Newton Hessian
    ``2 w J^T diag(active) J`` with the exact clearance Jacobian ``J``.

    Attributes:
        clearance: ``(q, p) -> (c (m,), dc_dq (m, n))``
            (`geosyn.controllers.mpc.ocp.obstacles.ObstacleSlots.clearance_function`).
        obstacles: the slots' parameters ``p`` (a symbol or numbers).
        margin: the clearance kept [m].
        weight: scalar weight [1/m^2].
    """

    clearance: ca.Function
    obstacles: Any
    margin: Any
    weight: Any

    def state_derivatives(self, x: ca.SX, q_ref: ca.SX, v_ref: ca.SX) -> tuple[Any, Any, Any]:
        """Value, gradient (2n,) and Gauss-Newton Hessian (2n, 2n) in ``x``."""
        n, w = q_ref.numel(), self.weight
        c, J = self.clearance(x[:n], self.obstacles)
        viol = ca.fmax(self.margin - c, 0)
        active = (viol > 0) @ ca.DM.ones(1, n)
        zero = ca.DM(n, n)
        grad = ca.vertcat(-2 * w * (J.T @ viol), ca.DM(n, 1))
        hess = ca.blockcat([[2 * w * (J.T @ (active * J)), zero], [zero, zero]])
        return w * ca.sumsqr(viol), grad, hess
