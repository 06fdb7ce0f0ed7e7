"""The compiled stage pieces of the Riccati (box-DDP) solver of the torque-level OCP.

One C library per robot, stage length, RK4 step count and cost choices (weights, limits
and the reference are inputs, so one library serves every horizon and tuning). Each
function has named inputs and outputs (listed in `DDPParts`); callers pass them by name:

- ``ddp_lin``: ``(x, u) -> (A, B)``, the Jacobians of the RK4 step on the ABA (chain rule
  through RK4, `geosyn.controllers.mpc.ocp.rk4.rk4_linearisation`);
- ``ddp_riccati``: one backward Riccati step: the stage's Q-function (Gauss-Newton: the
  dynamics' curvature is dropped; the costs' derivatives are their
  `geosyn.controllers.mpc.ocp.costs.CostTerm.derivatives`), the box-constrained QP of the
  control update (projected Newton, `geosyn.controllers.mpc.ddp.box_qp`), the
  feedforward ``k``, the feedback ``K`` on the free controls and the value function of
  the stage before;
- ``ddp_forward``: one step of the closed-loop rollout,
  ``u = clip(u_bar + alpha k + K (x - x_bar))`` then ``x' = F(x, u)``, with its cost;
- ``ddp_terminal``: the terminal cost and its derivatives.

Costs (`geosyn.controllers.mpc.ddp.parameters.stage_terms`): per stage the tracking, the
effort (``"torque"`` or ``"metric"``), the soft state limits and (with obstacles) the
clearance penalty; terminal: tracking, soft limits, clearance. The torque limits are hard
(the box QP, and the clip of the rollout), on the commanded torque: the control is the
torque net of the dry-friction feed-forward
(`geosyn.controllers.mpc.ddp.parameters.torque_box`). Parameters ``P``:
`geosyn.controllers.mpc.ddp.parameters.parameter_vector`.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import casadi as ca

from geosyn.controllers.mpc.ddp import box_qp as box_qp_module
from geosyn.controllers.mpc.ddp import parameters as parameters_module
from geosyn.controllers.mpc.ddp.box_qp import BOX_ITERATIONS, box_qp
from geosyn.controllers.mpc.ddp.parameters import (
    DDPCosts,
    n_parameters,
    split_parameters,
    stage_terms,
    terminal_terms,
    torque_box,
)
from geosyn.controllers.mpc.ocp import costs as costs_module
from geosyn.controllers.mpc.ocp import penalties as penalties_module
from geosyn.controllers.mpc.ocp import rk4 as rk4_module
from geosyn.controllers.mpc.ocp.compiled import stage_recipe
from geosyn.controllers.mpc.ocp.costs import StageSymbols, stage_derivatives
from geosyn.controllers.mpc.ocp.linalg import spd_solve
from geosyn.controllers.mpc.ocp.obstacles import clearance_digest
from geosyn.controllers.mpc.ocp.rk4 import rk4_linearisation, rk4_step
from geosyn.core.codegen import compile_recipe
from geosyn.robots.robot import Robot

__all__ = [
    "SX_RICCATI_MAX_JOINTS",
    "DDPParts",
    "ForwardInputs",
    "ddp_parts",
    "make_functions",
    "riccati_step",
    "stage_function",
    "terminal_cost",
]

SX_RICCATI_MAX_JOINTS = 12
"""Robots with more joints get the MX form of the Riccati step (see `riccati_step`)."""


class DDPParts(NamedTuple):
    """The compiled (or, without a compiler, interpreted) stage functions, with named
    inputs and outputs.

    Attributes:
        lin: ``ddp_lin: (x (2n,), u (n,)) -> (A (2n, 2n), B (2n, n))`` (None: built
            without the backward pass's functions, ``ddp_parts(with_backward=False)``).
        riccati: ``ddp_riccati: (Vx, Vxx, A, B, x, u, xr, tr, P) -> (Vx_prev, Vxx_prev,
            k, K, dV (2,))`` (None as ``lin``).
        forward: ``ddp_forward: (x, xb, ub, k, K, alpha, xr, tr, P) -> (u, xn, cost)``.
        terminal: ``ddp_terminal: (x, xr, P) -> (cost, Vx, Vxx)``.
    """

    lin: ca.Function | None
    riccati: ca.Function | None
    forward: ca.Function
    terminal: ca.Function


class ForwardInputs(NamedTuple):
    """The inputs of ``ddp_forward`` (`DDPParts.forward`), in its order and with its
    names, for numeric calls (``numpy_function(parts.forward)(*ForwardInputs(...))``).

    Attributes:
        x: (2n,) state [rad, rad/s]; xb: (2n,) nominal state; ub: (n,) nominal torque
            [N m]; k: (n,) feedforward step; K: (n, 2n) feedback gain; alpha: step
            length; xr: (2n,) reference state; tr: (n,) reference torque [N m]; P: the
            parameter vector.
    """

    x: Any
    xb: Any
    ub: Any
    k: Any
    K: Any
    alpha: Any
    xr: Any
    tr: Any
    P: Any


def stage_function(n: int, costs: DDPCosts) -> ca.Function:
    """``ddp_stage: (x, u, xr, tr, P) -> (l, lx, lxx, lu, luu, lux)``, the stage cost and
    its Gauss-Newton derivatives (SX; the sum of the terms'
    `geosyn.controllers.mpc.ocp.costs.CostTerm.derivatives`)."""
    nx = 2 * n
    x, u, xr, tr = ca.SX.sym("x", nx), ca.SX.sym("u", n), ca.SX.sym("xr", nx), ca.SX.sym("tr", n)
    P = ca.SX.sym("P", n_parameters(n, costs.clearance))
    s = StageSymbols(x, u, u, xr[:n], xr[n:], tr, ca.SX(0, 1))
    d = stage_derivatives(stage_terms(P, n, costs), s)
    return ca.Function(
        "ddp_stage",
        [x, u, xr, tr, P],
        [d.value, d.lx, d.lxx, d.lu, d.luu, d.lux],
        ["x", "u", "xr", "tr", "P"],
        ["l", "lx", "lxx", "lu", "luu", "lux"],
        {"cse": True},
    )


def riccati_step(n: int, sym: Any = None, costs: DDPCosts | None = None) -> ca.Function:
    """The Riccati step ``ddp_riccati`` for ``n`` joints (see `DDPParts`): ``sym`` SX
    (straight-line code) or MX (loops and an LDL^T solver); None: SX up to
    `SX_RICCATI_MAX_JOINTS` joints, MX beyond (the SX form grows as n^3: 60 MB of C at
    32 joints). ``costs``: the `DDPCosts` (None: the torque effort, Euclidean
    tracking, no clearance)."""
    costs = DDPCosts() if costs is None else costs
    nx = 2 * n
    if sym is None:
        sym = ca.SX if n <= SX_RICCATI_MAX_JOINTS else ca.MX
    Vx, Vxx = sym.sym("Vx", nx), sym.sym("Vxx", nx, nx)
    A, B = sym.sym("A", nx, nx), sym.sym("B", nx, n)
    x, u, xr, tr = sym.sym("x", nx), sym.sym("u", n), sym.sym("xr", nx), sym.sym("tr", n)
    P = sym.sym("P", n_parameters(n, costs.clearance))
    p = split_parameters(P, n)
    d = stage_function(n, costs)(x=x, u=u, xr=xr, tr=tr, P=P)
    VA, VB = Vxx @ A, Vxx @ B
    Qx, Qu = d["lx"] + A.T @ Vx, d["lu"] + B.T @ Vx
    Qxx = d["lxx"] + A.T @ VA
    Qux = d["lux"] + B.T @ VA
    Quu = d["luu"] + ca.diag(p.reg * ca.DM.ones(n, 1)) + B.T @ VB
    Quu = 0.5 * (Quu + Quu.T)
    lo, hi = torque_box(P, n, xr)
    k, free, H_free = box_qp(Quu, Qu, lo - u, hi - u, BOX_ITERATIONS)
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


def terminal_cost(n: int, costs: DDPCosts) -> ca.Function:
    """``ddp_terminal: (x, xr, P) -> (cost, Vx, Vxx)``, the terminal cost and its
    Gauss-Newton derivatives (SX)."""
    nx = 2 * n
    x, xr = ca.SX.sym("x", nx), ca.SX.sym("xr", nx)
    P = ca.SX.sym("P", n_parameters(n, costs.clearance))
    parts = [t.state_derivatives(x, xr[:n], xr[n:]) for t in terminal_terms(P, n, costs)]
    cost, grad, hess = (sum(p[i] for p in parts[1:]) + parts[0][i] for i in range(3))
    return ca.Function(
        "ddp_terminal",
        [x, xr, P],
        [cost, grad, ca.densify(hess)],
        ["x", "xr", "P"],
        ["cost", "Vx", "Vxx"],
        {"cse": True},
    )


def _forward(n: int, F: ca.Function, costs: DDPCosts) -> ca.Function:
    nx = 2 * n
    ins = ForwardInputs(
        ca.MX.sym("x", nx), ca.MX.sym("xb", nx), ca.MX.sym("ub", n), ca.MX.sym("k", n),
        ca.MX.sym("K", n, nx), ca.MX.sym("alpha"), ca.MX.sym("xr", nx), ca.MX.sym("tr", n),
        ca.MX.sym("P", n_parameters(n, costs.clearance)),
    )  # fmt: skip
    x, xb, ub, k, K, alpha, xr, tr, P = ins
    lo, hi = torque_box(P, n, xr)
    u = ca.fmin(ca.fmax(ub + alpha * k + K @ (x - xb), lo), hi)
    sx = ca.SX.sym("x", nx), ca.SX.sym("u", n), ca.SX.sym("xr", nx), ca.SX.sym("tr", n)
    sP = ca.SX.sym("P", P.numel())
    s = StageSymbols(sx[0], sx[1], sx[1], sx[2][:n], sx[2][n:], sx[3], ca.SX(0, 1))
    value = sum(t.expression(s) for t in stage_terms(sP, n, costs))
    cost = ca.Function("ddp_cost", [*sx, sP], [value], {"cse": True})(x, u, xr, tr, P)
    return ca.Function(
        "ddp_forward", list(ins), [u, F(x, u), cost], list(ForwardInputs._fields),
        ["u", "xn", "cost"],
    )  # fmt: skip


def make_functions(
    robot: Robot, dt: float, rk4_steps: int, costs: DDPCosts, with_backward: bool = True
) -> list[ca.Function]:
    """The four stage functions of `DDPParts` (builds CasADi graphs; no compilation);
    ``with_backward`` False: only ``ddp_forward`` and ``ddp_terminal``."""
    F = rk4_step(robot, dt, rk4_steps, gravity=True).F
    n = robot.nv
    backward = [rk4_linearisation(robot, dt, rk4_steps), riccati_step(n, costs=costs)]
    return [*(backward if with_backward else []), _forward(n, F, costs), terminal_cost(n, costs)]


_NAMES = ("ddp_lin", "ddp_riccati", "ddp_forward", "ddp_terminal")
_CODE = (
    __file__, box_qp_module.__file__, parameters_module.__file__, costs_module.__file__,
    penalties_module.__file__, rk4_module.__file__,
)  # fmt: skip


def _recipe(robot: Robot, dt: float, rk4_steps: int, *choices: str) -> str:
    digest = hashlib.sha256()
    for path in _CODE:
        digest.update(Path(path).read_bytes())
    stage = stage_recipe(robot, dt, "torque", rk4_steps, True)
    return "\0".join(["geosyn-mpc-ddp-v4", digest.hexdigest(), *choices, stage])


def ddp_parts(
    robot: Robot,
    dt: float,
    rk4_steps: int,
    costs: DDPCosts,
    *,
    compiled: bool = True,
    progress: Callable[[str], None] | None = None,
    with_backward: bool = True,
) -> DDPParts:
    """The stage functions of the DDP solver, compiled through the recipe cache.

    A robot, ``dt``, ``rk4_steps`` and cost choices seen before load in milliseconds; a
    first build generates and compiles C (seconds for 7 DoF; ``progress`` gets a line
    per step).

    Args:
        robot: the robot (its model, with gravity).
        dt: stage length [s].
        rk4_steps: RK4 steps per stage.
        costs: the effort, tracking and clearance (`DDPCosts`, its ``robot`` this one).
        compiled: False: the same functions on CasADi's virtual machine (no compiler).
        progress: receives progress lines of a first build.
        with_backward: False: without ``ddp_lin`` and ``ddp_riccati`` (None in the
            result), for a solver that runs the native backward pass
            (`geosyn.controllers.mpc.ddp.native`): a far shorter first build.

    Raises:
        CodegenError: no compiler, or compiling/loading failed (only when ``compiled``).
    """
    if not compiled:
        return DDPParts(*make_functions(robot, dt, rk4_steps, costs))
    names = _NAMES if with_backward else _NAMES[2:]
    tags = [costs.effort] + (["metric_tracking"] if costs.tracking == "metric" else [])
    tags += [] if costs.clearance is None else ["clearance"]
    name = re.sub(r"\W", "_", "_".join(["geosyn_ddp", robot.name, *tags]))
    name += "" if with_backward else "_rollout"
    digest = "" if costs.clearance is None else clearance_digest(costs.clearance)
    part = () if with_backward else ("rollout",)
    lib = compile_recipe(
        name,
        _recipe(robot, dt, rk4_steps, costs.effort, costs.tracking, digest, *part),
        lambda: make_functions(robot, dt, rk4_steps, costs, with_backward),
        load=list(names),
        progress=progress,
    )
    return DDPParts(
        lib.get("ddp_lin"), lib.get("ddp_riccati"), lib["ddp_forward"], lib["ddp_terminal"]
    )
