"""The DDP tracking OCP's parameter vector and its cost terms.

Every stage function of `geosyn.controllers.mpc.ddp.parts` takes one parameter vector ``P``
(`parameter_vector`): tracking, effort and terminal weights, joint and torque limits,
the dry joint friction and its smoothing velocity, the soft-limit weight and the control
regularisation (last, so that a solver raising it finds it at ``P[10 n + 2]``), then (with obstacles) the clearance margin, its weight and the
obstacle slots' parameters. The stage's control is the torque net of the known
dry-friction feed-forward ``f = f_c tanh(v_r / v_s)`` on the reference velocity
(`geosyn.controllers.mpc.ocp.dynamics`): `torque_box` bounds it so that the commanded
torque ``u + f`` stays within the torque limits. `DDPCosts` says which
effort, which tracking norm and which clearance the stage costs use; `stage_terms` and
`terminal_terms` build them as the shared cost terms of
`geosyn.controllers.mpc.ocp.costs` (their Gauss-Newton derivatives, written once), with
the weights and limits as slices of ``P``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.ocp.costs import (
    EFFORT_TERMS,
    CostTerm,
    StateCost,
    StateTracking,
    TerminalStateTracking,
)
from geosyn.controllers.mpc.ocp.dynamics import FRICTION_VELOCITY
from geosyn.controllers.mpc.ocp.penalties import ClearancePenalty, StateLimitPenalty
from geosyn.metrics.base import Metric
from geosyn.robots.robot import Robot

__all__ = [
    "BOUND_INF",
    "DDPCosts",
    "n_parameters",
    "parameter_vector",
    "split_parameters",
    "stage_terms",
    "terminal_terms",
    "torque_box",
]


class DDPCosts(NamedTuple):
    """Which costs the stage functions use.

    Attributes:
        robot: the robot (its model for the metric effort and metric tracking), or None
            for the torque effort with Euclidean tracking.
        metric: the metric of the ``"metric"`` effort (the robot's kinetic energy).
        effort: ``"torque"`` or ``"metric"``.
        tracking: ``"euclidean"`` or ``"metric"`` (errors in the norm of ``M(q_r)``).
        clearance: the obstacle slots' clearance function, or None (no obstacles).
    """

    robot: Robot | None = None
    metric: Metric | None = None
    effort: str = "torque"
    tracking: str = "euclidean"
    clearance: ca.Function | None = None


BOUND_INF = 1e10
"""An infinite joint limit is passed as this value [rad, rad/s]."""


def parameter_vector(
    q_weight: np.ndarray,
    v_weight: np.ndarray,
    effort_weight: np.ndarray,
    terminal_weight: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    v_max: np.ndarray,
    tau_max: np.ndarray,
    limit_weight: float,
    regularisation: float,
    friction: np.ndarray | None = None,
    friction_velocity: float = FRICTION_VELOCITY,
) -> np.ndarray:
    """The parameter vector ``P`` of the stage functions (infinite limits -> `BOUND_INF`).

    Args:
        q_weight, v_weight: (n,) tracking weights [1/rad^2], [s^2/rad^2].
        effort_weight: (n,) torque weight [1/(N m)^2].
        terminal_weight: (2n,) terminal weight (q then v).
        q_min, q_max: (n,) position limits [rad]; v_max: (n,) velocity limits [rad/s].
        tau_max: (n,) torque limits [N m].
        limit_weight: weight of the soft state limits.
        regularisation: added to the diagonal of each stage's control Hessian.
        friction: (n,) dry joint friction ``f_c`` [N m] (None: zeros).
        friction_velocity: ``v_s`` of the feed-forward ``f_c tanh(v_r / v_s)`` [rad/s].
    """
    n = np.asarray(q_weight).size
    f_c = np.zeros(n) if friction is None else np.asarray(friction, dtype=np.float64)

    def finite(a: np.ndarray) -> np.ndarray:
        return np.clip(np.asarray(a, dtype=np.float64), -BOUND_INF, BOUND_INF)

    return np.concatenate(
        [
            q_weight,
            v_weight,
            effort_weight,
            terminal_weight,
            finite(q_min),
            finite(q_max),
            finite(v_max),
            finite(tau_max),
            f_c,
            [friction_velocity, limit_weight, regularisation],
        ]
    ).astype(np.float64)


class _Params(NamedTuple):
    wx: Any
    wu: Any
    wN: Any
    q_min: Any
    q_max: Any
    v_max: Any
    tau_max: Any
    friction: Any
    v_s: Any
    w_lim: Any
    reg: Any


def split_parameters(P: Any, n: int) -> _Params:
    """The named slices of ``P`` (`parameter_vector`'s layout)."""
    sizes = (2 * n, n, 2 * n, n, n, n, n, n, 1, 1, 1)
    parts, i = [], 0
    for s in sizes:
        parts.append(P[i : i + s])
        i += s
    return _Params(*parts)


def n_parameters(n: int, clearance: ca.Function | None = None) -> int:
    """Length of ``P`` for ``n`` joints: ``10 n + 3``, plus ``2 + m_p`` with a clearance
    function (margin [m], weight [1/m^2], the obstacle slots' ``m_p`` parameters)."""
    base = 10 * n + 3
    return base if clearance is None else base + 2 + clearance.size1_in("p")


def torque_box(P: Any, n: int, xr: Any) -> tuple[Any, Any]:
    """Bounds ``(lo, hi)`` (n,) of a stage's control, the torque net of the stage's
    dry-friction feed-forward ``f = f_c tanh(v_r / v_s)`` (``v_r = xr[n:]``, the reference
    velocity): ``-tau_max - f <= u <= tau_max - f``, so that the commanded ``u + f`` is
    within the limits (``f`` is zero without friction)."""
    p = split_parameters(P, n)
    f = p.friction * ca.tanh(xr[n:] / p.v_s)
    return -p.tau_max - f, p.tau_max - f


def _model(costs: DDPCosts) -> Any:
    return costs.robot.model if costs.tracking == "metric" and costs.robot else None


def _penalties(P: Any, n: int, costs: DDPCosts) -> list[StateCost]:
    """The soft state limits and (with a clearance function) the clearance penalty."""
    p = split_parameters(P, n)
    out: list[StateCost] = [StateLimitPenalty(p.q_min, p.q_max, p.v_max, p.w_lim)]
    if costs.clearance is not None:
        base = n_parameters(n)
        out.append(ClearancePenalty(costs.clearance, P[base + 2 :], P[base], P[base + 1]))
    return out


def stage_terms(P: Any, n: int, costs: DDPCosts) -> list[CostTerm]:
    """The stage cost terms with the weights and limits of ``P``: tracking, effort
    (`geosyn.controllers.mpc.ocp.costs.EFFORT_TERMS`, gravity on), soft limits and
    clearance."""
    p = split_parameters(P, n)
    tracking = StateTracking(p.wx[:n], p.wx[n:], _model(costs))
    effort = EFFORT_TERMS[costs.effort](p.wu, costs.robot, costs.metric, True)  # type: ignore[arg-type]
    return [tracking, effort, *_penalties(P, n, costs)]


def terminal_terms(P: Any, n: int, costs: DDPCosts) -> list[TerminalStateTracking | StateCost]:
    """The terminal cost terms with the weights and limits of ``P``: tracking, soft
    limits and clearance."""
    p = split_parameters(P, n)
    return [TerminalStateTracking(p.wN, _model(costs)), *_penalties(P, n, costs)]
