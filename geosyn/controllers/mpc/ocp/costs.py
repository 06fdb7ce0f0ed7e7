"""The costs of the MPC's optimal-control problem: small terms, each with its weight, its
expression and its Gauss-Newton derivatives.

Every `CostTerm` gives its value as an SX expression in the stage symbols (`StageSymbols`:
what the NLP family minimises, `stage_cost`) and its value with its Gauss-Newton
derivatives in ``(x, u)`` (`StageDerivatives`: what the DDP family's Riccati step reads,
`stage_derivatives`). A test checks that the two agree (gradients exactly, Hessians up to
the dropped curvature). Weights may be numbers (baked into the NLP) or SX slices of a
parameter vector (the DDP's compiled functions take them as inputs).

Terms: `StateTracking` (Euclidean, or in the kinetic-energy metric's norm at the
reference), `TorqueEffort`, `AccelerationEffort`, `MetricEffort`, and the DDP's soft
penalties `geosyn.controllers.mpc.ocp.penalties`; `TerminalStateTracking` on the last
state. `EFFORT_TERMS` maps each ``effort`` name to its term.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.controllers.mpc.ocp.linalg import spd_solve
from geosyn.core.errors import InvalidArgument
from geosyn.metrics.base import Metric, sx_cholesky_solve
from geosyn.metrics.kinetic import KineticEnergyMetric
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = [
    "EFFORT_TERMS",
    "AccelerationEffort",
    "CostTerm",
    "MetricEffort",
    "StageDerivatives",
    "StageSymbols",
    "StateCost",
    "StateTracking",
    "TerminalStateTracking",
    "TorqueEffort",
    "is_robot_kinetic_metric",
    "stage_cost",
    "stage_derivatives",
    "terminal_cost",
]

Weight = Any
"""A weight: (nv,) numbers (numpy) or an SX expression of the same size."""


class StageSymbols(NamedTuple):
    """The SX symbols a stage cost is written in.

    Attributes:
        x: (2 nv,) state ``(q, v)`` [rad, rad/s].
        u: (nv,) control (torques [N m] or accelerations [rad/s^2]).
        tau: (nv,) joint torques of the stage [N m] (``u`` itself in torque control).
        q_ref: (nv,) reference positions [rad].
        v_ref: (nv,) reference velocities [rad/s].
        effort_ref: (nv,) reference of the effort: inverse-dynamics torques [N m], or
            accelerations [rad/s^2] for `AccelerationEffort`.
        metric_p: (n_p,) parameters of a parameterised metric.
    """

    x: ca.SX
    u: ca.SX
    tau: ca.SX
    q_ref: ca.SX
    v_ref: ca.SX
    effort_ref: ca.SX
    metric_p: ca.SX


class StageDerivatives(NamedTuple):
    """A stage cost's value and Gauss-Newton derivatives (torque control: ``tau = u``).

    Attributes:
        value: the cost (scalar).
        lx: (2 nv,) gradient in the state.
        lxx: (2 nv, 2 nv) Hessian in the state (curvature of nonlinear maps dropped).
        lu: (nv,) gradient in the control.
        luu: (nv, nv) Hessian in the control.
        lux: (nv, 2 nv) mixed Hessian.
    """

    value: Any
    lx: Any
    lxx: Any
    lu: Any
    luu: Any
    lux: Any


class CostTerm(ABC):
    """One weighted term of a stage cost: its expression and its derivatives."""

    @abstractmethod
    def expression(self, s: StageSymbols) -> ca.SX:
        """The term's value (a scalar SX) in the stage symbols ``s``."""

    @abstractmethod
    def derivatives(self, s: StageSymbols) -> StageDerivatives:
        """The term's value and Gauss-Newton derivatives in ``(s.x, s.u)``."""


class StateCost(CostTerm):
    """A term of the state alone, usable on a stage and on the terminal state."""

    @abstractmethod
    def state_derivatives(self, x: ca.SX, q_ref: ca.SX, v_ref: ca.SX) -> tuple[Any, Any, Any]:
        """Value, gradient (2 nv,) and Gauss-Newton Hessian (2 nv, 2 nv) in ``x``."""

    def expression(self, s: StageSymbols) -> ca.SX:
        return self.state_derivatives(s.x, s.q_ref, s.v_ref)[0]

    def derivatives(self, s: StageSymbols) -> StageDerivatives:
        n = s.u.numel()
        value, lx, lxx = self.state_derivatives(s.x, s.q_ref, s.v_ref)
        return StageDerivatives(value, lx, lxx, ca.DM(n, 1), ca.DM(n, n), ca.DM(n, 2 * n))


def _control_derivatives(value: Any, lu: Any, luu: Any, n: int) -> StageDerivatives:
    """Derivatives of a term of the control alone."""
    return StageDerivatives(value, ca.DM(2 * n, 1), ca.DM(2 * n, 2 * n), lu, luu, ca.DM(n, 2 * n))


def _control_tracking(s: StageSymbols, w: Weight) -> StageDerivatives:
    """``|u - effort_ref|^2_W`` and its (exact) derivatives."""
    e = s.u - s.effort_ref
    return _control_derivatives(ca.dot(w, e * e), 2 * w * e, ca.diag(2 * w), s.u.numel())


def _sqrt(w: Weight) -> Any:
    return ca.sqrt(w) if isinstance(w, ca.SX | ca.MX) else ca.DM(np.sqrt(np.asarray(w)))


def _tracking(
    e_q: ca.SX, e_v: ca.SX, wq: Weight, wv: Weight, q_ref: ca.SX, model: pin.Model | None
) -> ca.SX:
    """``|e_q|^2_Wq + |e_v|^2_Wv``, or in the norm of ``M(q_ref)`` scaled by the square
    roots of the weights (``model`` given): ``|S_q e_q|^2_M + |S_v e_v|^2_M``."""
    if model is None:
        return ca.dot(wq, e_q**2) + ca.dot(wv, e_v**2)
    M = symbolic.crba(model, q_ref)
    a, b = _sqrt(wq) * e_q, _sqrt(wv) * e_v
    return ca.dot(a, M @ a) + ca.dot(b, M @ b)


def _tracking_derivatives(
    e: ca.SX, wq: Weight, wv: Weight, q_ref: ca.SX, model: pin.Model | None
) -> tuple[Any, Any, Any]:
    """`_tracking` of ``e = x - x_ref`` with its gradient and (exact) Hessian."""
    n = q_ref.numel()
    if model is None:
        w: Any = ca.vertcat(wq, wv)
        return ca.dot(w, e * e), 2 * w * e, ca.diag(2 * w)
    M = symbolic.crba(model, q_ref)
    sq, sv = _sqrt(wq), _sqrt(wv)
    Wq = M * (sq @ sq.T)  # S_q M S_q, elementwise with the outer product of the scales
    Wv = M * (sv @ sv.T)
    grad = ca.vertcat(Wq @ e[:n], Wv @ e[n:])
    zero = ca.DM(n, n)
    hess: Any = ca.blockcat([[Wq, zero], [zero, Wv]])
    return ca.dot(e, grad), 2 * grad, 2 * hess


@dataclass(frozen=True, eq=False)
class StateTracking(StateCost):
    """``|q - q_ref|^2_Wq + |v - v_ref|^2_Wv``, or with ``model`` the kinetic-energy
    metric's norm at the reference, ``|S_q (q - q_ref)|^2_M(q_ref) + |S_v (v -
    v_ref)|^2_M(q_ref)`` with ``S = diag(sqrt(W))``. Quadratic: exact Hessians.

    Attributes:
        q_weight: (nv,) [1/rad^2].
        v_weight: (nv,) [s^2/rad^2].
        model: Pinocchio model whose mass matrix weighs the errors, or None (Euclidean).
    """

    q_weight: Weight
    v_weight: Weight
    model: pin.Model | None = None

    def expression(self, s: StageSymbols) -> ca.SX:
        n = s.q_ref.numel()
        e_q, e_v = s.x[:n] - s.q_ref, s.x[n:] - s.v_ref
        return _tracking(e_q, e_v, self.q_weight, self.v_weight, s.q_ref, self.model)

    def state_derivatives(self, x: ca.SX, q_ref: ca.SX, v_ref: ca.SX) -> tuple[Any, Any, Any]:
        e = x - ca.vertcat(q_ref, v_ref)
        return _tracking_derivatives(e, self.q_weight, self.v_weight, q_ref, self.model)


@dataclass(frozen=True, eq=False)
class TorqueEffort(CostTerm):
    """``|tau - tau_ref|^2_W`` with ``tau_ref`` the reference's inverse dynamics.

    Attributes:
        weight: (nv,) [1/(N m)^2].
    """

    weight: Weight

    def expression(self, s: StageSymbols) -> ca.SX:
        return ca.dot(self.weight, (s.tau - s.effort_ref) ** 2)

    def derivatives(self, s: StageSymbols) -> StageDerivatives:
        """Torque control (``tau = u``)."""
        return _control_tracking(s, self.weight)


@dataclass(frozen=True, eq=False)
class AccelerationEffort(CostTerm):
    """``|u - a_ref|^2_W`` on the acceleration control (the torque enters only limits).

    Attributes:
        weight: (nv,) [s^4/rad^2].
    """

    weight: Weight

    def expression(self, s: StageSymbols) -> ca.SX:
        return ca.dot(self.weight, (s.u - s.effort_ref) ** 2)

    def derivatives(self, s: StageSymbols) -> StageDerivatives:
        return _control_tracking(s, self.weight)


def is_robot_kinetic_metric(metric: Metric, robot: Robot) -> bool:
    """True if ``metric`` is the kinetic-energy metric of ``robot``'s own model."""
    return isinstance(metric, KineticEnergyMetric) and metric.robot.model is robot.model


@dataclass(frozen=True, eq=False)
class MetricEffort(CostTerm):
    """``w (tau - g(q))^T G(q)^{-1} (tau - g(q))``: the squared Riemannian norm of the
    covariant acceleration (for the kinetic-energy metric ``G = M``: ``M qdd + C v``).

    ``M^{-1}`` is applied by the ABA with zero velocity for the robot's kinetic-energy
    metric, by a symbolic Cholesky solve otherwise; never by a symbolic inverse. The
    symbols of a parameterised metric become the stage symbol ``metric_p``.

    Attributes:
        weight: scalar weight [1/(N m)^2] (a number or an SX scalar).
        robot: the robot (its model and gravity).
        metric: the metric ``G``.
        gravity: subtract the gravity torque ``g(q)``.
    """

    weight: Any
    robot: Robot
    metric: Metric
    gravity: bool

    def _gravity(self) -> np.ndarray:
        return np.asarray(self.robot.gravity, dtype=np.float64) if self.gravity else np.zeros(3)

    def expression(self, s: StageSymbols) -> ca.SX:
        model, n, g = self.robot.model, self.robot.nv, self._gravity()
        q, tau = s.x[:n], s.tau
        zeros = np.zeros(n)
        w = tau - symbolic.rnea(model, q, zeros, zeros, g) if self.gravity else tau
        kinetic = is_robot_kinetic_metric(self.metric, self.robot)
        if kinetic:
            # aba(q, 0, tau, g) = M^-1 (tau - g(q)): one recursion, no symbolic inverse.
            minv_w = symbolic.aba(model, q, zeros, tau, g)
        else:
            minv_w = sx_cholesky_solve(self.metric.symbolic_G(q), w)
        eff = self.weight * ca.dot(w, minv_w)
        if s.metric_p.numel() and not kinetic:
            eff = ca.substitute(eff, self.metric.symbolic_parameters(), s.metric_p)
        return eff

    def derivatives(self, s: StageSymbols) -> StageDerivatives:
        """Torque control, the robot's kinetic-energy metric: ``l``, ``l_q``, ``l_u``,
        ``l_uu = 2 w M^-1`` and ``l_uq`` exact; ``l_qq`` the positive semi-definite
        completion ``l_uq^T l_uu^-1 l_uq`` (the exact curvature in q dropped,
        Gauss-Newton style: a DDP fixed point is still the OCP's optimum, the gradient
        being exact).

        Raises:
            InvalidArgument: the metric is not the robot's own kinetic-energy metric.
        """
        if not is_robot_kinetic_metric(self.metric, self.robot):
            raise InvalidArgument(
                "MetricEffort derivatives need the robot's own KineticEnergyMetric, got "
                f"{type(self.metric).__name__}"
            )
        model, n, g, w = self.robot.model, self.robot.nv, self._gravity(), self.weight
        q, u = s.x[:n], s.u
        zeros = np.zeros(n)
        r = u - symbolic.rnea(model, q, zeros, zeros, g) if self.gravity else u
        minv_r = symbolic.aba(model, q, zeros, u, g)  # M^-1 (u - g(q)), one recursion
        value = w * ca.dot(r, minv_r)
        lu = 2 * w * minv_r
        M = symbolic.crba(model, q)
        luu = 2 * w * spd_solve(M, ca.SX.eye(n))
        luq = ca.jacobian(lu, q)
        lqq = luq.T @ (M @ luq) / (2 * w)
        zero = ca.DM(n, n)
        return StageDerivatives(
            value,
            ca.vertcat(ca.gradient(value, q), ca.DM(n, 1)),
            ca.blockcat([[lqq, zero], [zero, zero]]),
            lu,
            luu,
            ca.horzcat(luq, zero),
        )


EFFORT_TERMS: dict[str, Callable[[Weight, Robot, Metric, bool], CostTerm]] = {
    "torque": lambda weight, robot, metric, gravity: TorqueEffort(weight),
    "acceleration": lambda weight, robot, metric, gravity: AccelerationEffort(weight),
    # The metric effort is a scalar weight on the Riemannian norm: the first entry.
    "metric": lambda weight, robot, metric, gravity: MetricEffort(
        weight[0] if isinstance(weight, ca.SX | ca.MX) else float(weight[0]),
        robot,
        metric,
        gravity,
    ),
}
"""The effort term of each ``effort`` name, from ``(weight, robot, metric, gravity)``;
both solver families build their effort here."""


@dataclass(frozen=True, eq=False)
class TerminalStateTracking:
    """``|x_N - (q_ref, v_ref)|^2_W`` on the last state (in the metric's norm with
    ``model``, as `StateTracking`).

    Attributes:
        weight: (2 nv,) weight on the position then velocity error.
        model: Pinocchio model whose mass matrix weighs the errors, or None (Euclidean).
    """

    weight: Weight
    model: pin.Model | None = None

    def _stage(self, n: int) -> StateTracking:
        return StateTracking(self.weight[:n], self.weight[n:], self.model)

    def expression(self, x: ca.SX, q_ref: ca.SX, v_ref: ca.SX) -> ca.SX:
        """The term's value in the state ``x`` (2 nv,) and references ``q_ref, v_ref``."""
        n = q_ref.numel()
        w = self.weight if isinstance(self.weight, ca.SX | ca.MX) else np.asarray(self.weight)
        return _tracking(x[:n] - q_ref, x[n:] - v_ref, w[:n], w[n:], q_ref, self.model)

    def state_derivatives(self, x: ca.SX, q_ref: ca.SX, v_ref: ca.SX) -> tuple[Any, Any, Any]:
        """Value, gradient and Hessian in ``x`` (see `StateCost.state_derivatives`)."""
        return self._stage(q_ref.numel()).state_derivatives(x, q_ref, v_ref)


def stage_derivatives(terms: Sequence[CostTerm], s: StageSymbols) -> StageDerivatives:
    """The sum of the terms' `CostTerm.derivatives`."""
    parts = [t.derivatives(s) for t in terms]
    return StageDerivatives(*(sum(p[i] for p in parts[1:]) + parts[0][i] for i in range(6)))


def stage_cost(terms: Sequence[CostTerm], nv: int, n_p: int) -> ca.Function:
    """The stage cost ``L(x, u, tau, q_ref, v_ref, effort_ref, metric_p)``, a sum of terms.

    Args:
        terms: the cost terms.
        nv: number of joints.
        n_p: number of metric parameters.

    Returns:
        An SX function named ``"L"`` with a scalar output.
    """
    x, u = ca.SX.sym("x", 2 * nv), ca.SX.sym("u", nv)
    qr, vr, tr, tau = (ca.SX.sym(s, nv) for s in ("qr", "vr", "tr", "tau"))
    mp = ca.SX.sym("mp", n_p)
    symbols = StageSymbols(x, u, tau, qr, vr, tr, mp)
    total: ca.SX = ca.SX(0)
    for term in terms:
        total = total + term.expression(symbols)
    return ca.Function("L", list(symbols), [total], {"cse": True})


def terminal_cost(term: TerminalStateTracking | None, nv: int) -> ca.Function:
    """The terminal cost ``Lf(x, q_ref, v_ref)`` (zero without a term).

    Args:
        term: the terminal term, or None.
        nv: number of joints.

    Returns:
        An SX function named ``"Lf"`` with a scalar output.
    """
    x, qr, vr = ca.SX.sym("x", 2 * nv), ca.SX.sym("qr", nv), ca.SX.sym("vr", nv)
    value = ca.SX(0) if term is None else term.expression(x, qr, vr)
    return ca.Function("Lf", [x, qr, vr], [value])
