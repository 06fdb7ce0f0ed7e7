"""The RK4 step of the torque-controlled robot and its Jacobians, by the chain rule
through RK4: the dynamics' derivative parts shared by every solver family.

Differentiating the expanded RK4 step gives straight-line code with the ABA's Jacobian
inlined four times per RK4 step (megabytes of C for 7 DoF, minutes at ``-O1``). Here the
ODE ``(x, u) -> (v, ABA(q, v, u))`` and its Jacobian are SX functions; the step and its
Jacobian are MX functions that call them (the generated C calls them in a loop-free
sequence), with the exact same derivative:
``dk_i = A_i (D + c_i dk_{i-1})`` (+ ``B_i`` for ``u``) and
``D' = D + h/6 (dk_1 + 2 dk_2 + 2 dk_3 + dk_4)``.

`rk4_step` gives the step ``mpc_F<g|0>`` and its Jacobian (the compiled, curvature-free
dynamics of the NLP family, `geosyn.controllers.mpc.ocp.compiled`, and the DDP's
rollout); `rk4_linearisation` the Jacobians alone in the form the DDP's backward pass
calls (``ddp_lin``).
"""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.ocp.dynamics import damped_torque, joint_damping
from geosyn.controllers.mpc.ocp.linalg import spd_solve
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = ["RK4Step", "rk4_linearisation", "rk4_step"]


class RK4Step(NamedTuple):
    """The RK4 step of one stage and its Jacobian (MX functions).

    Attributes:
        F: ``mpc_F<g|0>: (x (2n,), u (n,)) -> xn (2n,)``.
        jacobian: ``jac_mpc_F<g|0>: (x, u, out_xn) -> (jac_xn_x (2n, 2n), jac_xn_u
            (2n, n))`` (CasADi's naming of ``F.jacobian()``; ``out_xn`` is unused).
    """

    F: ca.Function
    jacobian: ca.Function


def rk4_step(robot: Robot, dt: float, rk4_steps: int, gravity: bool) -> RK4Step:
    """The RK4 step on the ABA and its Jacobian by the chain rule (builds graphs).

    Args:
        robot: the robot.
        dt: stage length [s].
        rk4_steps: RK4 steps per stage.
        gravity: include the robot's gravity.
    """
    n = robot.nv
    tag = "g" if gravity else "0"
    g = np.asarray(robot.gravity, dtype=np.float64) if gravity else np.zeros(3)
    xs, us = ca.SX.sym("x", 2 * n), ca.SX.sym("u", n)
    tau = damped_torque(robot, xs[n:], us)
    xdot = ca.vertcat(xs[n:], symbolic.aba(robot.model, xs[:n], xs[n:], tau, g))
    ode = ca.Function(f"mpc_ode{tag}", [xs, us], [xdot], {"cse": True})
    ode_jac = ca.Function(
        f"mpc_ode_jac{tag}",
        [xs, us],
        [ca.jacobian(xdot, xs), ca.jacobian(xdot, us)],
        {"cse": True},
    )
    x, u = ca.MX.sym("x", 2 * n), ca.MX.sym("u", n)
    hs = dt / rk4_steps
    xk, Dx, Du = x, ca.MX.eye(2 * n), ca.MX(2 * n, n)
    for _ in range(rk4_steps):
        ks: list[ca.MX] = []
        dks: list[tuple[ca.MX, ca.MX]] = []
        prev_x, prev_u = ca.MX(2 * n, 2 * n), ca.MX(2 * n, n)
        for c in (0.0, 0.5 * hs, 0.5 * hs, hs):
            xi = xk if not ks else xk + c * ks[-1]
            A, B = ode_jac(xi, u)
            ks.append(ode(xi, u))
            prev_x, prev_u = A @ (Dx + c * prev_x), A @ (Du + c * prev_u) + B
            dks.append((prev_x, prev_u))
        w = (hs / 6.0, hs / 3.0, hs / 3.0, hs / 6.0)
        xk = xk + sum((wi * ki for wi, ki in zip(w, ks, strict=True)), ca.MX(2 * n, 1))
        Dx = Dx + sum((wi * d[0] for wi, d in zip(w, dks, strict=True)), ca.MX(2 * n, 2 * n))
        Du = Du + sum((wi * d[1] for wi, d in zip(w, dks, strict=True)), ca.MX(2 * n, n))
    name = f"mpc_F{tag}"
    F = ca.Function(name, [x, u], [xk], ["x", "u"], ["xn"])
    out = ca.MX.sym("out_xn", ca.Sparsity(2 * n, 1))  # the unused nominal output
    jac = ca.Function(
        f"jac_{name}",
        [x, u, out],
        [Dx, Du],
        ["x", "u", "out_xn"],
        ["jac_xn_x", "jac_xn_u"],
    )
    return RK4Step(F, jac)


def rk4_linearisation(robot: Robot, dt: float, rk4_steps: int) -> ca.Function:
    """``ddp_lin: (x, u) -> (A, B)``, the Jacobians of the RK4 step on the ABA (gravity
    on), by the chain rule through RK4 (as `rk4_step`) with one SX call
    per RK4 stage giving the ODE's value and Jacobian together (no separate ODE call)."""
    n = robot.nv
    g = np.asarray(robot.gravity, dtype=np.float64)
    q, v, u_s, a_s = (ca.SX.sym(name, n) for name in ("q", "v", "u", "a"))
    acc = symbolic.aba(robot.model, q, v, damped_torque(robot, v, u_s), g)
    # d(ABA)/d(q, v) = -M^-1 d(RNEA + D v)/d(q, v) at a = ABA, d(ABA)/du = M^-1: 28 %
    # fewer operations than differentiating the ABA itself (panda: 14.1k against 19.5k).
    inverse = symbolic.rnea(robot.model, q, v, a_s, g)
    d = joint_damping(robot)
    if d is not None:
        inverse = inverse + ca.DM(d) * v
    d_rnea = ca.jacobian(inverse, ca.vertcat(q, v))
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
