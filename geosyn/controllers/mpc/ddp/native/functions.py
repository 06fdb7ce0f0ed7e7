"""The generated per-stage functions of the hand-written DDP backward pass.

The C backward pass (``geosyn_ddp.c`` beside this file; geosyn's Python solver and the C
export both use it) runs the Python solver's backward pass
(`geosyn.controllers.mpc.ddp.riccati.backward_graph`: the RK4 step's Jacobians, then the
Riccati recursion with the box QP) as loops over small dense matrices; CasADi generates
only what is specific to the robot and the costs:

- ``geosyn_mpc_dyn: (x, u) -> (M, r)`` and ``geosyn_mpc_drnea: (x, a) -> dR``: the mass
  matrix, the torque left for acceleration ``r = u - RNEA(q, v, 0) - D v`` and the
  Jacobian ``dR`` of ``RNEA(q, v, a) + D v`` in ``(q, v)``; from them the C code forms
  what `geosyn.controllers.mpc.ocp.rk4.rk4_linearisation`'s ODE gives at one point:
  ``a = M^-1 r`` (the ABA's value), ``d a / d(q, v) = -M^-1 dR`` at that ``a`` and
  ``d a / du = M^-1`` (one Cholesky factor of ``M``, vectorised solves);
- ``geosyn_mpc_stage: (x, u, xr, tr, P) -> (lx, lxx, lu, luu, lux, lo, hi)``: the stage's
  Gauss-Newton cost derivatives (`geosyn.controllers.mpc.ddp.parts.stage_function`) and
  the bounds of its control (`geosyn.controllers.mpc.ddp.parameters.torque_box`: the
  torque limits net of the stage's dry-friction feed-forward);
- ``geosyn_mpc_terminal: (x, xr, P) -> (Vx, Vxx)``: the terminal cost's derivatives.

Every output is dense (the C code reads full column-major matrices).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.ddp.parameters import DDPCosts, torque_box
from geosyn.controllers.mpc.ddp.parts import stage_function, terminal_cost
from geosyn.controllers.mpc.ocp.dynamics import joint_damping
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = [
    "dynamics_function",
    "inverse_jacobian_function",
    "stage_box_function",
    "terminal_function",
]


def _inverse_dynamics(robot: Robot, q: ca.SX, v: ca.SX, a: ca.SX) -> ca.SX:
    """``RNEA(q, v, a) + D v`` (gravity on)."""
    g = np.asarray(robot.gravity, dtype=np.float64)
    tau = symbolic.rnea(robot.model, q, v, a, g)
    d = joint_damping(robot)
    return tau if d is None else tau + ca.DM(d) * v


def dynamics_function(robot: Robot) -> ca.Function:
    """``geosyn_mpc_dyn: (x (2n,), u (n,)) -> (M (n, n), r (n,))`` with
    ``r = u - RNEA(q, v, 0) - D v``: the acceleration is ``M^-1 r`` (the ABA's value;
    the C code solves with M's Cholesky factor, which it reuses for the Jacobian)."""
    n = robot.nv
    q, v, u = (ca.SX.sym(name, n) for name in ("q", "v", "u"))
    r = u - _inverse_dynamics(robot, q, v, ca.SX.zeros(n))
    M = ca.densify(symbolic.crba(robot.model, q))
    return ca.Function(
        "geosyn_mpc_dyn", [ca.vertcat(q, v), u], [M, r], ["x", "u"], ["M", "r"], {"cse": True}
    )


def inverse_jacobian_function(robot: Robot) -> ca.Function:
    """``geosyn_mpc_drnea: (x (2n,), a (n,)) -> dR (n, 2n)``, the Jacobian of
    ``RNEA(q, v, a) + D v`` in ``(q, v)``, by reverse mode (n adjoint sweeps: 23 % fewer
    operations than forward mode for the Panda). With ``a`` the ABA's acceleration,
    ``d ABA / d(q, v) = -M^-1 dR`` and ``d ABA / du = M^-1``."""
    n = robot.nv
    q, v, a = (ca.SX.sym(name, n) for name in ("q", "v", "a"))
    x = ca.vertcat(q, v)
    dR = ca.jtimes(_inverse_dynamics(robot, q, v, a), x, ca.SX.eye(n), True).T
    return ca.Function(
        "geosyn_mpc_drnea", [x, a], [ca.densify(dR)], ["x", "a"], ["dR"], {"cse": True}
    )


def stage_box_function(n: int, costs: DDPCosts, n_p: int) -> ca.Function:
    """``geosyn_mpc_stage`` for ``n`` joints, the costs ``costs`` and ``n_p`` parameters."""
    nx = 2 * n
    x, u, xr, tr = ca.SX.sym("x", nx), ca.SX.sym("u", n), ca.SX.sym("xr", nx), ca.SX.sym("tr", n)
    P = ca.SX.sym("P", n_p)
    d = stage_function(n, costs)(x=x, u=u, xr=xr, tr=tr, P=P)
    lo, hi = torque_box(P, n, xr)
    names = ["lx", "lxx", "lu", "luu", "lux"]
    return ca.Function(
        "geosyn_mpc_stage",
        [x, u, xr, tr, P],
        [*(ca.densify(d[k]) for k in names), ca.densify(lo), ca.densify(hi)],
        ["x", "u", "xr", "tr", "P"],
        [*names, "lo", "hi"],
        {"cse": True},
    )


def terminal_function(n: int, costs: DDPCosts) -> ca.Function:
    """``geosyn_mpc_terminal: (x, xr, P) -> (Vx, Vxx)``: the solver's own terminal cost's
    derivatives (`geosyn.controllers.mpc.ddp.parts.terminal_cost`) without its value."""
    terminal = terminal_cost(n, costs)
    ins = terminal.sx_in()
    out = terminal.call(ins)
    return ca.Function(
        "geosyn_mpc_terminal", ins, [ca.densify(out[1]), ca.densify(out[2])], ["x", "xr", "P"],
        ["Vx", "Vxx"], {"cse": True},
    )  # fmt: skip
