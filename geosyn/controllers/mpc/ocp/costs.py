"""The costs of the MPC's optimal-control problem: small terms, each with its weight.

A stage cost is a sum of `CostTerm` expressions in the stage symbols (`StageSymbols`),
turned into one CasADi function by `stage_cost`; the terminal cost is
`TerminalStateTracking`, turned into a function by `terminal_cost`. All are quadratic
except `MetricEffort`, so their Hessians are cheap and exact.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.core.types import Vector
from geosyn.metrics.base import Metric, sx_cholesky_solve
from geosyn.metrics.kinetic import KineticEnergyMetric
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = [
    "AccelerationEffort",
    "CostTerm",
    "MetricEffort",
    "StageSymbols",
    "StateTracking",
    "TerminalStateTracking",
    "TorqueEffort",
    "is_robot_kinetic_metric",
    "stage_cost",
    "terminal_cost",
]


class StageSymbols(NamedTuple):
    """The SX symbols a stage cost is written in.

    Attributes:
        x: (2 nv,) state ``(q, v)`` [rad, rad/s].
        u: (nv,) control (torques [N m] or accelerations [rad/s^2]).
        tau: (nv,) joint torques of the stage [N m].
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


class CostTerm(ABC):
    """One weighted term of a stage cost."""

    @abstractmethod
    def expression(self, s: StageSymbols) -> ca.SX:
        """The term's value (a scalar SX) in the stage symbols ``s``."""


def _tracking(
    e_q: ca.SX, e_v: ca.SX, wq: Vector, wv: Vector, q_ref: ca.SX, model: pin.Model | None
) -> ca.SX:
    """``|e_q|^2_Wq + |e_v|^2_Wv``, or in the norm of ``M(q_ref)`` scaled by the square
    roots of the weights (``model`` given): ``|S_q e_q|^2_M + |S_v e_v|^2_M``."""
    if model is None:
        return ca.dot(wq, e_q**2) + ca.dot(wv, e_v**2)
    M = symbolic.crba(model, q_ref)
    a, b = np.sqrt(wq) * e_q, np.sqrt(wv) * e_v
    return ca.dot(a, M @ a) + ca.dot(b, M @ b)


@dataclass(frozen=True, eq=False)
class StateTracking(CostTerm):
    """``|q - q_ref|^2_Wq + |v - v_ref|^2_Wv``, or with ``model`` the kinetic-energy
    metric's norm at the reference, ``|S_q (q - q_ref)|^2_M(q_ref) + |S_v (v -
    v_ref)|^2_M(q_ref)`` with ``S = diag(sqrt(W))``.

    Attributes:
        q_weight: (nv,) [1/rad^2].
        v_weight: (nv,) [s^2/rad^2].
        model: Pinocchio model whose mass matrix weighs the errors, or None (Euclidean).
    """

    q_weight: Vector
    v_weight: Vector
    model: pin.Model | None = None

    def expression(self, s: StageSymbols) -> ca.SX:
        n = self.q_weight.size
        e_q, e_v = s.x[:n] - s.q_ref, s.x[n:] - s.v_ref
        return _tracking(e_q, e_v, self.q_weight, self.v_weight, s.q_ref, self.model)


@dataclass(frozen=True, eq=False)
class TorqueEffort(CostTerm):
    """``|tau - tau_ref|^2_W`` with ``tau_ref`` the reference's inverse dynamics.

    Attributes:
        weight: (nv,) [1/(N m)^2].
    """

    weight: Vector

    def expression(self, s: StageSymbols) -> ca.SX:
        return ca.dot(self.weight, (s.tau - s.effort_ref) ** 2)


@dataclass(frozen=True, eq=False)
class AccelerationEffort(CostTerm):
    """``|u - a_ref|^2_W`` on the acceleration control (the torque enters only limits).

    Attributes:
        weight: (nv,) [s^4/rad^2].
    """

    weight: Vector

    def expression(self, s: StageSymbols) -> ca.SX:
        return ca.dot(self.weight, (s.u - s.effort_ref) ** 2)


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
        weight: scalar weight [1/(N m)^2].
        robot: the robot (its model and gravity).
        metric: the metric ``G``.
        gravity: subtract the gravity torque ``g(q)``.
    """

    weight: float
    robot: Robot
    metric: Metric
    gravity: bool

    def expression(self, s: StageSymbols) -> ca.SX:
        model, n = self.robot.model, self.robot.nv
        g = np.asarray(self.robot.gravity, dtype=np.float64) if self.gravity else np.zeros(3)
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


@dataclass(frozen=True, eq=False)
class TerminalStateTracking:
    """``|x_N - (q_ref, v_ref)|^2_W`` on the last state (in the metric's norm with
    ``model``, as `StateTracking`).

    Attributes:
        weight: (2 nv,) weight on the position then velocity error.
        model: Pinocchio model whose mass matrix weighs the errors, or None (Euclidean).
    """

    weight: Vector
    model: pin.Model | None = None

    def expression(self, x: ca.SX, q_ref: ca.SX, v_ref: ca.SX) -> ca.SX:
        """The term's value in the state ``x`` (2 nv,) and references ``q_ref, v_ref``."""
        n = q_ref.numel()
        w = np.asarray(self.weight)
        return _tracking(x[:n] - q_ref, x[n:] - v_ref, w[:n], w[n:], q_ref, self.model)


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
