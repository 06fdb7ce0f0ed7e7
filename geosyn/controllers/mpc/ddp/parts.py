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
from geosyn.controllers.mpc import ddp_costs, gauss_newton
from geosyn.controllers.mpc.box_qp import BOX_ITERATIONS, box_qp, spd_solve
from geosyn.controllers.mpc.ddp_clearance import clearance_digest
from geosyn.controllers.mpc.ddp_costs import (
    CostModel,
    mass_matrix_function,
    metric_effort,
    n_parameters,
    split_parameters,
    stage_derivatives,
    terminal_derivatives,
    torque_effort,
)
from geosyn.core.codegen import compile_recipe
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = [
    "SX_RICCATI_MAX_JOINTS",
    "DDPParts",
    "ddp_parts",
    "make_functions",
    "riccati_step",
    "rk4_linearisation",
]

SX_RICCATI_MAX_JOINTS = 12
"""Robots with more joints get the MX form of the Riccati step (see `riccati_step`)."""


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


def riccati_step(n: int, sym: Any = None, costs: CostModel | None = None) -> ca.Function:
    """The Riccati step ``ddp_riccati`` for ``n`` joints (see `DDPParts`): ``sym`` SX
    (straight-line code) or MX (loops and an LDL^T solver); None: SX up to
    `SX_RICCATI_MAX_JOINTS` joints, MX beyond (the SX form grows as n^3: 60 MB of C at
    32 joints). ``costs``: the `CostModel` (None: the torque effort, Euclidean
    tracking, no clearance)."""
    costs = CostModel(torque_effort(n)) if costs is None else costs
    nx = 2 * n
    if sym is None:
        sym = ca.SX if n <= SX_RICCATI_MAX_JOINTS else ca.MX
    Vx, Vxx = sym.sym("Vx", nx), sym.sym("Vxx", nx, nx)
    A, B = sym.sym("A", nx, nx), sym.sym("B", nx, n)
    x, u, xr, tr = sym.sym("x", nx), sym.sym("u", n), sym.sym("xr", nx), sym.sym("tr", n)
    P = sym.sym("P", n_parameters(n, costs.clearance))
    p = split_parameters(P, n)
    _, lx, lxx, lu, luu, lux = stage_derivatives(x, u, xr, tr, P, n, costs)
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


def _terminal(n: int, costs: CostModel) -> ca.Function:
    nx = 2 * n
    x, xr = ca.SX.sym("x", nx), ca.SX.sym("xr", nx)
    P = ca.SX.sym("P", n_parameters(n, costs.clearance))
    cost, grad, hess = terminal_derivatives(x, xr, P, n, costs)
    return ca.Function(
        "ddp_terminal",
        [x, xr, P],
        [cost, grad, ca.densify(hess)],
        ["x", "xr", "P"],
        ["cost", "Vx", "Vxx"],
        {"cse": True},
    )


def _stage_cost(n: int, costs: CostModel) -> ca.Function:
    nx = 2 * n
    x, u, xr, tr = ca.SX.sym("x", nx), ca.SX.sym("u", n), ca.SX.sym("xr", nx), ca.SX.sym("tr", n)
    P = ca.SX.sym("P", n_parameters(n, costs.clearance))
    cost = stage_derivatives(x, u, xr, tr, P, n, costs)[0]
    return ca.Function("ddp_cost", [x, u, xr, tr, P], [cost], {"cse": True})


def _forward(n: int, F: ca.Function, costs: CostModel) -> ca.Function:
    nx = 2 * n
    x, xb, ub = ca.MX.sym("x", nx), ca.MX.sym("xb", nx), ca.MX.sym("ub", n)
    k, K, alpha = ca.MX.sym("k", n), ca.MX.sym("K", n, nx), ca.MX.sym("alpha")
    xr, tr = ca.MX.sym("xr", nx), ca.MX.sym("tr", n)
    P = ca.MX.sym("P", n_parameters(n, costs.clearance))
    tau_max = split_parameters(P, n).tau_max
    u = ca.fmin(ca.fmax(ub + alpha * k + K @ (x - xb), -tau_max), tau_max)
    cost = _stage_cost(n, costs)(x, u, xr, tr, P)
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
    robot: Robot,
    dt: float,
    rk4_steps: int,
    effort: str,
    clearance: ca.Function | None = None,
    tracking: str = "euclidean",
) -> list[ca.Function]:
    """The four stage functions of `DDPParts` (builds CasADi graphs; no compilation).

    ``effort``: ``"torque"`` or ``"metric"`` (see `torque_effort`, `metric_effort`);
    ``clearance``: an optional `geosyn.controllers.mpc.ddp_clearance.clearance_function`;
    ``tracking``: ``"euclidean"`` or ``"metric"`` (errors in the norm of ``M(q_r)``)."""
    F = gauss_newton.rk4_parts(robot, dt, rk4_steps, gravity=True)[0]
    n = robot.nv
    costs = CostModel(
        torque_effort(n) if effort == "torque" else metric_effort(robot),
        clearance,
        mass_matrix_function(robot) if tracking == "metric" else None,
    )
    return [
        rk4_linearisation(robot, dt, rk4_steps),
        riccati_step(n, costs=costs),
        _forward(n, F, costs),
        _terminal(n, costs),
    ]


_NAMES = ("ddp_lin", "ddp_riccati", "ddp_forward", "ddp_terminal")


def _recipe(robot: Robot, dt: float, rk4_steps: int, *choices: str) -> str:
    digest = hashlib.sha256()
    for path in (Path(__file__), Path(box_qp_module.__file__), Path(ddp_costs.__file__)):
        digest.update(path.read_bytes())
    stage = gauss_newton.stage_recipe(robot, dt, "torque", rk4_steps, True)
    return "\0".join(["geosyn-mpc-ddp-v3", digest.hexdigest(), *choices, stage])


def ddp_parts(
    robot: Robot,
    dt: float,
    rk4_steps: int,
    effort: str = "torque",
    clearance: ca.Function | None = None,
    tracking: str = "euclidean",
    *,
    compiled: bool = True,
    progress: Callable[[str], None] | None = None,
) -> DDPParts:
    """The stage functions of the DDP solver, compiled through the recipe cache.

    A robot, ``dt``, ``rk4_steps`` and cost choices seen before load in milliseconds; a
    first build generates and compiles C (seconds for 7 DoF; ``progress`` gets a line
    per step).

    Args:
        robot: the robot (its model, with gravity).
        dt: stage length [s].
        rk4_steps: RK4 steps per stage.
        effort: ``"torque"`` or ``"metric"`` (the robot's kinetic-energy metric).
        clearance: optional clearance function
            (`geosyn.controllers.mpc.ddp_clearance.clearance_function`).
        tracking: ``"euclidean"`` or ``"metric"`` (see `make_functions`).
        compiled: False: the same functions on CasADi's virtual machine (no compiler).
        progress: receives progress lines of a first build.

    Raises:
        CodegenError: no compiler, or compiling/loading failed (only when ``compiled``).
    """
    if not compiled:
        return DDPParts(*make_functions(robot, dt, rk4_steps, effort, clearance, tracking))
    tags = [effort] + (["metric_tracking"] if tracking == "metric" else [])
    tags += [] if clearance is None else ["clearance"]
    name = re.sub(r"\W", "_", "_".join(["geosyn_ddp", robot.name, *tags]))
    digest = "" if clearance is None else clearance_digest(clearance)
    lib = compile_recipe(
        name,
        _recipe(robot, dt, rk4_steps, effort, tracking, digest),
        lambda: make_functions(robot, dt, rk4_steps, effort, clearance, tracking),
        load=list(_NAMES),
        progress=progress,
    )
    return DDPParts(*(lib[k] for k in _NAMES))
