"""The stage dynamics of the MPC: one shooting stage of the robot as CasADi functions.

State ``x = (q, v)`` of size 2 nv; control ``u`` of size nv, either the joint torques
(torque control: RK4 on the forward dynamics ``qdd = ABA(q, v, u)``) or the joint
accelerations (acceleration control: the exact double integrator, with the torque
``RNEA(q, v, u)`` as an output for the limits). Both are SX functions built once.
"""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np

from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = ["StageDynamics", "stage_dynamics"]


class StageDynamics(NamedTuple):
    """One stage of length ``dt`` as two functions of ``(x (2 nv,), u (nv,))``.

    Attributes:
        F: ``(x, u) -> x_next (2 nv,)``, the state after the stage [rad, rad/s].
        TAU: ``(x, u) -> tau (nv,)``, the joint torques of the stage [N m].
    """

    F: ca.Function
    TAU: ca.Function


def stage_dynamics(
    robot: Robot, dt: float, control: str, rk4_steps: int, gravity: bool
) -> StageDynamics:
    """The SX functions ``F`` and ``TAU`` of one stage (allocates a graph).

    Their names (``mpc_F<g|0>``, ``mpc_tau<g|0>``) and graphs are part of the key of the
    compiled-code cache (see `geosyn.controllers.mpc.gauss_newton`).

    Args:
        robot: the robot; its Pinocchio model gives the dynamics.
        dt: stage length [s].
        control: ``"torque"`` (RK4 on the ABA) or ``"acceleration"`` (double integrator).
        rk4_steps: RK4 steps per stage (torque control only).
        gravity: include ``robot.gravity`` (else zero gravity).

    Returns:
        The `StageDynamics`.
    """
    model = robot.model
    n, h = robot.nv, dt
    g = np.asarray(robot.gravity, dtype=np.float64) if gravity else np.zeros(3)
    x = ca.SX.sym("x", 2 * n)
    u = ca.SX.sym("u", n)
    q, v = x[:n], x[n:]
    if control == "torque":
        acc = symbolic.aba(model, q, v, u, g)
        f = ca.Function("f", [x, u], [ca.vertcat(v, acc)])
        hs = h / rk4_steps
        xk = x
        for _ in range(rk4_steps):
            k1 = f(xk, u)
            k2 = f(xk + 0.5 * hs * k1, u)
            k3 = f(xk + 0.5 * hs * k2, u)
            k4 = f(xk + hs * k3, u)
            xk = xk + (hs / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        tau = u
    else:
        xk = ca.vertcat(q + h * v + 0.5 * h * h * u, v + h * u)
        tau = symbolic.rnea(model, q, v, u, g)
    tag = "g" if gravity else "0"
    F = ca.Function(f"mpc_F{tag}", [x, u], [xk], ["x", "u"], ["xn"], {"cse": True})
    TAU = ca.Function(f"mpc_tau{tag}", [x, u], [tau], ["x", "u"], ["tau"], {"cse": True})
    return StageDynamics(F, TAU)
