"""The compiled stage pieces of the Riccati (box-DDP) solver of the torque-level OCP.

One C library per robot, stage length, RK4 step count and effort (weights, limits and
the reference are inputs, so one library serves every horizon and tuning):

- ``ddp_lin``: ``(x, u) -> (A, B)``, the Jacobians of the RK4 step on the ABA (chain rule
  through RK4, `geosyn.controllers.mpc.gauss_newton.rk4_parts`);
- ``ddp_riccati``: one backward Riccati step: the stage's Q-function (Gauss-Newton: the
  dynamics' curvature is dropped; the costs are quadratic), the box-constrained QP of the
  control update (projected Newton, `geosyn.controllers.mpc.box_qp`), the feedforward ``k``, the
  feedback ``K`` on the free controls and the value function of the stage before;
- ``ddp_forward``: one step of the closed-loop rollout,
  ``u = clip(u_bar + alpha k + K (x - x_bar))`` then ``x' = F(x, u)``, with its cost;
- ``ddp_terminal``: the terminal cost and its derivatives.

Costs (as `geosyn.controllers.mpc.costs`): per stage ``|q - q_r|^2_Wq + |v - v_r|^2_Wv``
plus the effort, ``|u - tau_r|^2_Wu`` (`torque_effort`) or ``w (u - g)^T M^-1 (u - g)``
(`metric_effort`, one library per effort), plus the soft state limits
``w_lim (|max(q - q_max, 0)|^2 + |max(q_min - q, 0)|^2 + |max(|v| - v_max, 0)|^2)``
(zero inside the limits); terminal ``|x - x_r|^2_WN`` plus the same soft limits. The
torque limits are hard (the box QP, and the clip of the rollout).

Parameters ``P`` (`parameter_vector`): ``(Wq, Wv, Wu, WN, q_min, q_max, v_max, tau_max,
w_lim, reg)``.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from geosyn.controllers.mpc import box_qp as box_qp_module
from geosyn.controllers.mpc import gauss_newton
from geosyn.controllers.mpc.box_qp import BOX_ITERATIONS, box_qp, spd_solve
from geosyn.controllers.mpc.ddp_clearance import clearance_digest
from geosyn.core.codegen import compile_recipe
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = [
    "BOUND_INF",
    "SX_RICCATI_MAX_JOINTS",
    "DDPParts",
    "ddp_parts",
    "parameter_vector",
    "metric_effort",
    "n_parameters",
    "riccati_step",
    "rk4_linearisation",
    "torque_effort",
]

SX_RICCATI_MAX_JOINTS = 12
"""Robots with more joints get the MX form of the Riccati step (see `riccati_step`)."""
BOUND_INF = 1e10
"""An infinite joint limit is passed as this value [rad, rad/s]."""


class DDPParts(NamedTuple):
    """The compiled (or, without a compiler, interpreted) stage functions.

    Attributes:
        lin: ``(x (2n,), u (n,)) -> (A (2n, 2n), B (2n, n))``.
        riccati: ``(Vx, Vxx, A, B, x, u, x_r, tau_r, P) -> (Vx', Vxx', k, K, dV (2,))``.
        forward: ``(x, x_bar, u_bar, k, K, alpha, x_r, tau_r, P) -> (u, x_next, cost)``.
        terminal: ``(x, x_r, P) -> (cost, Vx, Vxx)``.
    """

    lin: ca.Function
    riccati: ca.Function
    forward: ca.Function
    terminal: ca.Function


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
    wx: ca.SX
    wu: ca.SX
    wN: ca.SX
    q_min: ca.SX
    q_max: ca.SX
    v_max: ca.SX
    tau_max: ca.SX
    w_lim: ca.SX
    reg: ca.SX


def _split(P: ca.SX, n: int) -> _Params:
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


def _limit_terms(x: ca.SX, p: _Params, n: int) -> tuple[ca.SX, ca.SX, ca.SX]:
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


def _stage_derivatives(
    x: Any,
    u: Any,
    xr: Any,
    tr: Any,
    P: Any,
    n: int,
    effort: ca.Function,
    clearance: ca.Function | None = None,
) -> tuple[Any, Any, Any, Any, Any, Any]:
    """Stage cost and its derivatives: (l, lx (2n,), lxx (2n, 2n), lu, luu, lux (n, 2n))."""
    p = _split(P, n)
    ex = x - xr
    lim, lim_grad, lim_hess = _limit_terms(x, p, n)
    le, le_q, le_u, le_uu, le_uq, le_qq = effort(x[:n], u, tr, p.wu)
    lc, lc_q, lc_qq = _clearance_terms(x[:n], P, n, clearance)
    zero = ca.DM(n, n)  # structurally zero
    value = ca.dot(p.wx, ex * ex) + le + lim + lc
    lx = 2 * p.wx * ex + lim_grad + ca.vertcat(le_q + lc_q, ca.DM(n, 1))
    lxx = ca.diag(2 * p.wx + lim_hess) + ca.blockcat([[le_qq + lc_qq, zero], [zero, zero]])
    return value, lx, lxx, le_u, le_uu, ca.horzcat(le_uq, zero)


def riccati_step(
    n: int,
    sym: Any = None,
    effort: ca.Function | None = None,
    clearance: ca.Function | None = None,
) -> ca.Function:
    """The Riccati step ``ddp_riccati`` for ``n`` joints (see `DDPParts`): ``sym`` SX
    (straight-line code) or MX (loops and an LDL^T solver); None: SX up to
    `SX_RICCATI_MAX_JOINTS` joints, MX beyond (the SX form grows as n^3: 60 MB of C at
    32 joints). ``effort``: `torque_effort` (None) or `metric_effort`; ``clearance``:
    the optional `geosyn.controllers.mpc.ddp_clearance.clearance_function`."""
    effort = torque_effort(n) if effort is None else effort
    nx = 2 * n
    if sym is None:
        sym = ca.SX if n <= SX_RICCATI_MAX_JOINTS else ca.MX
    Vx, Vxx = sym.sym("Vx", nx), sym.sym("Vxx", nx, nx)
    A, B = sym.sym("A", nx, nx), sym.sym("B", nx, n)
    x, u, xr, tr = sym.sym("x", nx), sym.sym("u", n), sym.sym("xr", nx), sym.sym("tr", n)
    P = sym.sym("P", n_parameters(n, clearance))
    p = _split(P, n)
    _, lx, lxx, lu, luu, lux = _stage_derivatives(x, u, xr, tr, P, n, effort, clearance)
    VA, VB = Vxx @ A, Vxx @ B
    Qx, Qu = lx + A.T @ Vx, lu + B.T @ Vx
    Qxx = lxx + A.T @ VA
    Qux = lux + B.T @ VA
    Quu = luu + ca.diag(p.reg * ca.DM.ones(n, 1)) + B.T @ VB
    Quu = 0.5 * (Quu + Quu.T)
    k, free, H_free = box_qp(Quu, Qu, -p.tau_max - u, p.tau_max - u, BOX_ITERATIONS)
    K = -spd_solve(H_free, (free @ ca.DM.ones(1, nx)) * Qux)
    Vx_new = Qx + K.T @ (Quu @ k + Qu) + Qux.T @ k
    # K is zero on the clamped rows and -Quu_ff^-1 Qux_f on the free ones, so
    # K^T Quu K + K^T Qux + Qux^T K = Qux^T K (the textbook form, fewer products).
    Vxx_new = Qxx + Qux.T @ K
    Vxx_new = 0.5 * (Vxx_new + Vxx_new.T)
    dV = ca.vertcat(ca.dot(k, Qu), 0.5 * ca.dot(k, Quu @ k))
    return ca.Function(
        "ddp_riccati",
        [Vx, Vxx, A, B, x, u, xr, tr, P],
        [Vx_new, Vxx_new, k, K, dV],
        ["Vx", "Vxx", "A", "B", "x", "u", "xr", "tr", "P"],
        ["Vx_prev", "Vxx_prev", "k", "K", "dV"],
        {"cse": True} if sym is ca.SX else {},
    )


def _terminal(n: int, clearance: ca.Function | None = None) -> ca.Function:
    nx = 2 * n
    x, xr = ca.SX.sym("x", nx), ca.SX.sym("xr", nx)
    P = ca.SX.sym("P", n_parameters(n, clearance))
    p = _split(P, n)
    e = x - xr
    lim, lim_grad, lim_hess = _limit_terms(x, p, n)
    lc, lc_q, lc_qq = _clearance_terms(x[:n], P, n, clearance)
    zero = ca.DM(n, n)
    cost = ca.dot(p.wN, e * e) + lim + lc
    grad = 2 * p.wN * e + lim_grad + ca.vertcat(lc_q, ca.DM(n, 1))
    hess = ca.diag(2 * p.wN + lim_hess) + ca.blockcat([[lc_qq, zero], [zero, zero]])
    return ca.Function(
        "ddp_terminal",
        [x, xr, P],
        [cost, grad, ca.densify(hess)],
        ["x", "xr", "P"],
        ["cost", "Vx", "Vxx"],
        {"cse": True},
    )


def _stage_cost(n: int, effort: ca.Function, clearance: ca.Function | None) -> ca.Function:
    nx = 2 * n
    x, u, xr, tr = ca.SX.sym("x", nx), ca.SX.sym("u", n), ca.SX.sym("xr", nx), ca.SX.sym("tr", n)
    P = ca.SX.sym("P", n_parameters(n, clearance))
    cost = _stage_derivatives(x, u, xr, tr, P, n, effort, clearance)[0]
    return ca.Function("ddp_cost", [x, u, xr, tr, P], [cost], {"cse": True})


def _forward(
    n: int, F: ca.Function, effort: ca.Function, clearance: ca.Function | None = None
) -> ca.Function:
    nx = 2 * n
    x, xb, ub = ca.MX.sym("x", nx), ca.MX.sym("xb", nx), ca.MX.sym("ub", n)
    k, K, alpha = ca.MX.sym("k", n), ca.MX.sym("K", n, nx), ca.MX.sym("alpha")
    xr, tr = ca.MX.sym("xr", nx), ca.MX.sym("tr", n)
    P = ca.MX.sym("P", n_parameters(n, clearance))
    tau_max = P[8 * n : 9 * n]  # the layout of _split
    u = ca.fmin(ca.fmax(ub + alpha * k + K @ (x - xb), -tau_max), tau_max)
    cost = _stage_cost(n, effort, clearance)(x, u, xr, tr, P)
    return ca.Function(
        "ddp_forward",
        [x, xb, ub, k, K, alpha, xr, tr, P],
        [u, F(x, u), cost],
        ["x", "xb", "ub", "k", "K", "alpha", "xr", "tr", "P"],
        ["u", "xn", "cost"],
    )


def rk4_linearisation(robot: Robot, dt: float, rk4_steps: int) -> ca.Function:
    """``ddp_lin: (x, u) -> (A, B)``, the Jacobians of the RK4 step on the ABA (gravity
    on), by the chain rule through RK4 (as `gauss_newton.rk4_parts`) with one SX call
    per RK4 stage giving the ODE's value and Jacobian together (no separate ODE call)."""
    n = robot.nv
    g = np.asarray(robot.gravity, dtype=np.float64)
    q, v, u_s, a_s = (ca.SX.sym(name, n) for name in ("q", "v", "u", "a"))
    acc = symbolic.aba(robot.model, q, v, u_s, g)
    # d(ABA)/d(q, v) = -M^-1 d(RNEA)/d(q, v) at a = ABA, d(ABA)/du = M^-1: 28 % fewer
    # operations than differentiating the ABA itself (panda: 14.1k against 19.5k).
    d_rnea = ca.jacobian(symbolic.rnea(robot.model, q, v, a_s, g), ca.vertcat(q, v))
    sens = spd_solve(symbolic.crba(robot.model, q), ca.horzcat(-d_rnea, ca.SX.eye(n)))
    sens = ca.substitute(sens, a_s, acc)
    top = ca.horzcat(ca.SX(n, n), ca.SX.eye(n))
    ode = ca.Function(
        "ddp_ode",
        [ca.vertcat(q, v), u_s],
        [
            ca.vertcat(v, acc),
            ca.vertcat(top, sens[:, : 2 * n]),
            ca.vertcat(ca.SX(n, n), sens[:, 2 * n :]),
        ],
        {"cse": True},
    )
    x, u = ca.MX.sym("x", 2 * n), ca.MX.sym("u", n)
    hs = dt / rk4_steps
    weights = (hs / 6.0, hs / 3.0, hs / 3.0, hs / 6.0)
    xk, Dx, Du = x, ca.MX.eye(2 * n), ca.MX(2 * n, n)
    for _ in range(rk4_steps):
        k_prev: ca.MX | None = None
        dx_prev, du_prev = ca.MX(2 * n, 2 * n), ca.MX(2 * n, n)
        x_next, Dx_next, Du_next = xk, Dx, Du
        for c, w in zip((0.0, 0.5 * hs, 0.5 * hs, hs), weights, strict=True):
            k_i, A, B = ode(xk if k_prev is None else xk + c * k_prev, u)
            dx_prev, du_prev = A @ (Dx + c * dx_prev), A @ (Du + c * du_prev) + B
            x_next, Dx_next, Du_next = (
                x_next + w * k_i,
                Dx_next + w * dx_prev,
                Du_next + w * du_prev,
            )
            k_prev = k_i
        xk, Dx, Du = x_next, Dx_next, Du_next
    return ca.Function("ddp_lin", [x, u], [ca.densify(Dx), ca.densify(Du)], ["x", "u"], ["A", "B"])


def make_functions(
    robot: Robot, dt: float, rk4_steps: int, effort: str, clearance: ca.Function | None = None
) -> list[ca.Function]:
    """The four stage functions of `DDPParts` (builds CasADi graphs; no compilation).

    ``effort``: ``"torque"`` or ``"metric"`` (see `torque_effort`, `metric_effort`);
    ``clearance``: an optional `geosyn.controllers.mpc.ddp_clearance.clearance_function`."""
    F = gauss_newton.rk4_parts(robot, dt, rk4_steps, gravity=True)[0]
    n = robot.nv
    eff = torque_effort(n) if effort == "torque" else metric_effort(robot)
    return [
        rk4_linearisation(robot, dt, rk4_steps),
        riccati_step(n, effort=eff, clearance=clearance),
        _forward(n, F, eff, clearance),
        _terminal(n, clearance),
    ]


_NAMES = ("ddp_lin", "ddp_riccati", "ddp_forward", "ddp_terminal")


def _recipe(robot: Robot, dt: float, rk4_steps: int, effort: str, clearance: str) -> str:
    digest = hashlib.sha256()
    for path in (Path(__file__), Path(box_qp_module.__file__)):
        digest.update(path.read_bytes())
    stage = gauss_newton.stage_recipe(robot, dt, "torque", rk4_steps, True)
    return "\0".join(["geosyn-mpc-ddp-v2", digest.hexdigest(), effort, clearance, stage])


def ddp_parts(
    robot: Robot,
    dt: float,
    rk4_steps: int,
    effort: str = "torque",
    clearance: ca.Function | None = None,
    *,
    compiled: bool = True,
    progress: Callable[[str], None] | None = None,
) -> DDPParts:
    """The stage functions of the DDP solver, compiled through the recipe cache.

    A robot, ``dt`` and ``rk4_steps`` seen before load in milliseconds; a first build
    generates and compiles C (seconds for 7 DoF; ``progress`` gets a line per step).

    Args:
        robot: the robot (its model, with gravity).
        dt: stage length [s].
        rk4_steps: RK4 steps per stage.
        effort: ``"torque"`` or ``"metric"`` (the robot's kinetic-energy metric).
        clearance: optional clearance function
            (`geosyn.controllers.mpc.ddp_clearance.clearance_function`).
        compiled: False: the same functions on CasADi's virtual machine (no compiler).
        progress: receives progress lines of a first build.

    Raises:
        CodegenError: no compiler, or compiling/loading failed (only when ``compiled``).
    """
    if not compiled:
        return DDPParts(*make_functions(robot, dt, rk4_steps, effort, clearance))
    tag = "" if clearance is None else "_clearance"
    name = re.sub(r"\W", "_", f"geosyn_ddp_{robot.name}_{effort}{tag}")
    digest = "" if clearance is None else clearance_digest(clearance)
    lib = compile_recipe(
        name,
        _recipe(robot, dt, rk4_steps, effort, digest),
        lambda: make_functions(robot, dt, rk4_steps, effort, clearance),
        load=list(_NAMES),
        progress=progress,
    )
    return DDPParts(*(lib[k] for k in _NAMES))
