"""The costs of the DDP tracking OCP and the layout of its parameter vector.

Every stage function of `geosyn.controllers.mpc.ddp` takes one parameter vector ``P``
(`parameter_vector`): tracking, effort and terminal weights, joint and torque limits,
the soft-limit weight and the control regularisation, then (with a clearance function)
the clearance margin, its weight and the obstacle terms' parameters. A `CostModel` says
which effort (`torque_effort`, `metric_effort`), which tracking norm (Euclidean, or the
kinetic-energy metric's at the reference, `mass_matrix_function`) and which clearance
(`geosyn.controllers.mpc.ddp_clearance`) the stage costs use.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.box_qp import spd_solve
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = [
    "BOUND_INF",
    "CostModel",
    "mass_matrix_function",
    "metric_effort",
    "n_parameters",
    "parameter_vector",
    "split_parameters",
    "stage_derivatives",
    "terminal_derivatives",
    "torque_effort",
]


class CostModel(NamedTuple):
    """Which costs the stage functions use.

    Attributes:
        effort: ``ddp_effort`` (`torque_effort` or `metric_effort`).
        clearance: ``ddp_clearance`` or None (no clearance penalty).
        tracking: ``ddp_mass`` (`mass_matrix_function`: tracking in the metric's norm)
            or None (Euclidean tracking).
    """

    effort: ca.Function
    clearance: ca.Function | None = None
    tracking: ca.Function | None = None


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
    """

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
            [limit_weight, regularisation],
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
    w_lim: Any
    reg: Any


def split_parameters(P: Any, n: int) -> _Params:
    """The named slices of ``P`` (`parameter_vector`'s layout)."""
    sizes = (2 * n, n, 2 * n, n, n, n, n, 1, 1)
    parts, i = [], 0
    for s in sizes:
        parts.append(P[i : i + s])
        i += s
    return _Params(*parts)


def n_parameters(n: int, clearance: ca.Function | None = None) -> int:
    """Length of ``P`` for ``n`` joints: ``9 n + 2``, plus ``2 + m_p`` with a clearance
    function (margin [m], weight [1/m^2], the obstacle terms' ``m_p`` parameters)."""
    base = 9 * n + 2
    return base if clearance is None else base + 2 + clearance.size1_in(1)


def _limit_terms(x: Any, p: _Params, n: int) -> tuple[Any, Any, Any]:
    """Soft state limits: (value, gradient (2n,), Gauss-Newton Hessian diagonal (2n,))."""
    q, v = x[:n], x[n:]
    hi_q, lo_q = ca.fmax(q - p.q_max, 0), ca.fmax(p.q_min - q, 0)
    hi_v, lo_v = ca.fmax(v - p.v_max, 0), ca.fmax(-v - p.v_max, 0)
    value = p.w_lim * (ca.sumsqr(hi_q) + ca.sumsqr(lo_q) + ca.sumsqr(hi_v) + ca.sumsqr(lo_v))
    grad = 2 * p.w_lim * ca.vertcat(hi_q - lo_q, hi_v - lo_v)
    active = ca.vertcat(
        ca.logic_or(q > p.q_max, q < p.q_min), ca.logic_or(v > p.v_max, -v > p.v_max)
    )
    return value, grad, 2 * p.w_lim * active


def torque_effort(n: int) -> ca.Function:
    """``ddp_effort`` of the torque effort ``|u - tau_r|^2_Wu`` (see `metric_effort`)."""
    q, u, tr, wu = (ca.SX.sym(name, n) for name in ("q", "u", "tr", "wu"))
    e = u - tr
    outs = [ca.dot(wu, e * e), ca.SX(n, 1), 2 * wu * e, ca.diag(2 * wu), ca.SX(n, n), ca.SX(n, n)]
    return ca.Function("ddp_effort", [q, u, tr, wu], outs, _EFFORT_IO[0], _EFFORT_IO[1])


def metric_effort(robot: Robot) -> ca.Function:
    """``ddp_effort: (q, u, tau_r, w_u) -> (l, l_q, l_u, l_uu, l_uq, l_qq)`` of the metric
    effort ``w (u - g(q))^T M(q)^-1 (u - g(q))`` (``w = w_u[0]``; the robot's kinetic
    energy metric, gravity on; `geosyn.controllers.mpc.costs.MetricEffort`).

    ``l``, ``l_q``, ``l_u``, ``l_uu = 2 w M^-1`` and ``l_uq`` are exact; ``l_qq`` is the
    positive semi-definite completion ``l_uq^T l_uu^-1 l_uq`` (the effort's exact
    curvature in q is dropped, Gauss-Newton style): a DDP fixed point is still the
    OCP's optimum, the gradient being exact.
    """
    n, model = robot.nv, robot.model
    g = np.asarray(robot.gravity, dtype=np.float64)
    q, u, tr, wu = (ca.SX.sym(name, n) for name in ("q", "u", "tr", "wu"))
    zeros = np.zeros(n)
    w = wu[0]
    r = u - symbolic.rnea(model, q, zeros, zeros, g)
    minv_r = symbolic.aba(model, q, zeros, u, g)  # M^-1 (u - g(q)), one recursion
    value = w * ca.dot(r, minv_r)
    lu = 2 * w * minv_r
    M = symbolic.crba(model, q)
    luu = 2 * w * spd_solve(M, ca.SX.eye(n))
    luq = ca.jacobian(lu, q)
    lqq = luq.T @ (M @ luq) / (2 * w)
    outs = [value, ca.gradient(value, q), lu, luu, luq, lqq]
    return ca.Function(
        "ddp_effort", [q, u, tr, wu], outs, _EFFORT_IO[0], _EFFORT_IO[1], {"cse": True}
    )


_EFFORT_IO = (["q", "u", "tr", "wu"], ["l", "l_q", "l_u", "l_uu", "l_uq", "l_qq"])


def _clearance_terms(q: Any, P: Any, n: int, clearance: ca.Function | None) -> tuple[Any, Any, Any]:
    """The clearance penalty (`geosyn.controllers.mpc.ddp_clearance`): value, gradient
    (n,) and Gauss-Newton Hessian (n, n) in q; zero without ``clearance``."""
    if clearance is None:
        return 0, ca.DM(n, 1), ca.DM(n, n)
    base = n_parameters(n)
    margin, weight = P[base], P[base + 1]
    c, J = clearance(q, P[base + 2 :])
    viol = ca.fmax(margin - c, 0)
    active = (viol > 0) @ ca.DM.ones(1, n)
    return weight * ca.sumsqr(viol), -2 * weight * (J.T @ viol), 2 * weight * (J.T @ (active * J))


def _tracking_terms(
    x: Any, xr: Any, wq: Any, wv: Any, n: int, tracking: ca.Function | None
) -> tuple[Any, Any, Any]:
    """State tracking: value, gradient (2n,), Hessian (2n, 2n). Euclidean
    ``|q - q_r|^2_Wq + |v - v_r|^2_Wv``, or with ``tracking`` (``M(q_r)``) the metric's
    norm ``|S_q (q - q_r)|^2_M + |S_v (v - v_r)|^2_M``, ``S = diag(sqrt(W))``."""
    e = x - xr
    if tracking is None:
        w = ca.vertcat(wq, wv)
        return ca.dot(w, e * e), 2 * w * e, ca.diag(2 * w)
    M = tracking(xr[:n])
    sq, sv = ca.sqrt(wq), ca.sqrt(wv)
    Wq = M * (sq @ sq.T)  # S_q M S_q, elementwise with the outer product of the scales
    Wv = M * (sv @ sv.T)
    grad = ca.vertcat(Wq @ e[:n], Wv @ e[n:])
    zero = ca.DM(n, n)
    hess = ca.blockcat([[Wq, zero], [zero, Wv]])
    return ca.dot(e, grad), 2 * grad, 2 * hess


def stage_derivatives(
    x: Any, u: Any, xr: Any, tr: Any, P: Any, n: int, costs: CostModel
) -> tuple[Any, Any, Any, Any, Any, Any]:
    """Stage cost and its derivatives: (l, lx (2n,), lxx (2n, 2n), lu, luu, lux (n, 2n))."""
    p = split_parameters(P, n)
    lt, lt_x, lt_xx = _tracking_terms(x, xr, p.wx[:n], p.wx[n:], n, costs.tracking)
    lim, lim_grad, lim_hess = _limit_terms(x, p, n)
    le, le_q, le_u, le_uu, le_uq, le_qq = costs.effort(x[:n], u, tr, p.wu)
    lc, lc_q, lc_qq = _clearance_terms(x[:n], P, n, costs.clearance)
    zero = ca.DM(n, n)  # structurally zero
    value = lt + le + lim + lc
    lx = lt_x + lim_grad + ca.vertcat(le_q + lc_q, ca.DM(n, 1))
    lxx = lt_xx + ca.diag(lim_hess) + ca.blockcat([[le_qq + lc_qq, zero], [zero, zero]])
    return value, lx, lxx, le_u, le_uu, ca.horzcat(le_uq, zero)


def terminal_derivatives(x: Any, xr: Any, P: Any, n: int, costs: CostModel) -> tuple[Any, Any, Any]:
    """Terminal cost and its derivatives: (l, lx (2n,), lxx (2n, 2n))."""
    p = split_parameters(P, n)
    lt, lt_x, lt_xx = _tracking_terms(x, xr, p.wN[:n], p.wN[n:], n, costs.tracking)
    lim, lim_grad, lim_hess = _limit_terms(x, p, n)
    lc, lc_q, lc_qq = _clearance_terms(x[:n], P, n, costs.clearance)
    zero = ca.DM(n, n)
    value = lt + lim + lc
    lx = lt_x + lim_grad + ca.vertcat(lc_q, ca.DM(n, 1))
    lxx = lt_xx + ca.diag(lim_hess) + ca.blockcat([[lc_qq, zero], [zero, zero]])
    return value, lx, lxx


def mass_matrix_function(robot: Robot) -> ca.Function:
    """``ddp_mass: q_r (n,) -> M(q_r) (n, n)``, the robot's mass matrix (CRBA), for
    tracking in the kinetic-energy metric's norm."""
    q = ca.SX.sym("q", robot.nv)
    return ca.Function("ddp_mass", [q], [symbolic.crba(robot.model, q)], {"cse": True})
