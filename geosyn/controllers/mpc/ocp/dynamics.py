"""The stage dynamics of the MPC: one shooting stage of the robot as CasADi functions.

State ``x = (q, v)`` of size 2 nv; control ``u`` of size nv, either the joint torques
(torque control: RK4 on the forward dynamics ``qdd = ABA(q, v, u - D v)``) or the joint
accelerations (acceleration control: the exact double integrator, with the torque
``RNEA(q, v, u) + D v`` as an output for the limits). Both are SX functions built once.
``D`` is the robot file's viscous joint damping (`joint_damping`; MuJoCo applies it as
``-D v``).

The file's dry joint friction ``f_c`` (`joint_friction`) is not a smooth function of the
state, so the OCP does not hold it as such: like `ComputedTorque`, the MPC feeds it
forward on the reference velocity, ``f_k = f_c tanh(v^r_k / v_s)`` (`dry_friction`,
``v_s`` = `FRICTION_VELOCITY`), a known torque of stage ``k``. The solvers' control is
then the torque net of it (what ``F`` and ``TAU`` above take), the commanded torque is
``u_k + f_k`` (`geosyn.controllers.mpc.ocp.plan.MPCPlan.friction`), and the torque
limits bound the commanded torque, ``-tau_max - f_k <= u_k <= tau_max - f_k``.
"""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np

from geosyn.controllers.base import FRICTION_VELOCITY
from geosyn.core.errors import InvalidArgument
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = [
    "FRICTION_VELOCITY",
    "StageDynamics",
    "dry_friction",
    "joint_damping",
    "joint_friction",
    "stage_dynamics",
    "stage_friction",
    "stage_step",
    "stage_torque",
]


def joint_damping(robot: Robot) -> np.ndarray | None:
    """(nv,) the robot file's viscous joint damping D [N m s/rad], or None when it has none
    (the dynamics' graphs, and so their compiled-code keys, are then those of an undamped
    robot)."""
    d = np.asarray(robot.damping, dtype=np.float64)
    return d.copy() if d.size and np.any(d) else None


def joint_friction(robot: Robot) -> np.ndarray | None:
    """(nv,) the robot file's dry joint friction ``f_c`` [N m or N], or None without any.

    Raises:
        InvalidArgument: a joint's friction is not below its torque limit (no torque
            within the limits would move it; the MPC's torque box would be empty).
    """
    f = np.asarray(robot.frictionloss, dtype=np.float64)
    if not (f.size and np.any(f)):
        return None
    tau_max = np.asarray(robot.tau_max, dtype=np.float64)
    bad = np.flatnonzero(f >= tau_max)
    if bad.size:
        i = int(bad[0])
        raise InvalidArgument(
            f"robot {robot.name!r}: joint {robot.joint_names[i]!r} has frictionloss {f[i]:g},"
            f" not below its torque limit {tau_max[i]:g}; the MPC needs frictionloss <"
            " tau_max on every joint"
        )
    return f.copy()


def dry_friction(
    friction: np.ndarray, v_ref: np.ndarray, velocity: float = FRICTION_VELOCITY
) -> np.ndarray:
    """The dry-friction feed-forward ``f_c tanh(v_r / v_s)`` (a new array).

    Args:
        friction: (nv,) dry friction ``f_c`` [N m].
        v_ref: (..., nv) reference velocities [rad/s].
        velocity: ``v_s`` [rad/s], > 0.

    Returns:
        (..., nv) torques [N m].
    """
    return friction * np.tanh(np.asarray(v_ref, dtype=np.float64) / velocity)


def stage_friction(robot: Robot, v_ref: np.ndarray, N: int) -> np.ndarray | None:
    """(N, nv) the known dry-friction torque of each stage [N m] (`dry_friction` of the
    reference velocities ``v_ref`` (>= N, nv) [rad/s] at the stage starts), or None for a
    robot without dry friction."""
    f = joint_friction(robot)
    return None if f is None else dry_friction(f, np.asarray(v_ref)[:N])


def damped_torque(robot: Robot, v: ca.SX, tau: ca.SX) -> ca.SX:
    """``tau - D v``: the torque left for the rigid body once the joint damping took its
    share (``tau`` itself for an undamped robot)."""
    d = joint_damping(robot)
    return tau if d is None else tau - ca.DM(d) * v


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
    compiled-code cache (see `geosyn.controllers.mpc.ocp.compiled`).

    Args:
        robot: the robot; its Pinocchio model gives the dynamics.
        dt: stage length [s].
        control: ``"torque"`` (RK4 on the ABA) or ``"acceleration"`` (double integrator).
        rk4_steps: RK4 steps per stage (torque control only).
        gravity: include ``robot.gravity`` (else zero gravity).

    Returns:
        The `StageDynamics`.
    """
    return StageDynamics(
        stage_step(robot, dt, control, rk4_steps, gravity), stage_torque(robot, control, gravity)
    )


def _symbols(n: int) -> tuple[ca.SX, ca.SX]:
    return ca.SX.sym("x", 2 * n), ca.SX.sym("u", n)


def stage_step(robot: Robot, dt: float, control: str, rk4_steps: int, gravity: bool) -> ca.Function:
    """``F = mpc_F<g|0>: (x, u) -> x_next``: RK4 on the ABA (torque control; an SX graph
    of O(nv^2) nodes per RK4 step) or the exact double integrator (acceleration control;
    linear, cheap). Arguments as for `stage_dynamics`."""
    n, h = robot.nv, dt
    x, u = _symbols(n)
    q, v = x[:n], x[n:]
    if control == "torque":
        acc = symbolic.aba(robot.model, q, v, damped_torque(robot, v, u), _gravity(robot, gravity))
        f = ca.Function("f", [x, u], [ca.vertcat(v, acc)])
        hs = h / rk4_steps
        xk = x
        for _ in range(rk4_steps):
            k1 = f(xk, u)
            k2 = f(xk + 0.5 * hs * k1, u)
            k3 = f(xk + 0.5 * hs * k2, u)
            k4 = f(xk + hs * k3, u)
            xk = xk + (hs / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
    else:
        xk = ca.vertcat(q + h * v + 0.5 * h * h * u, v + h * u)
    name = f"mpc_F{'g' if gravity else '0'}"
    return ca.Function(name, [x, u], [xk], ["x", "u"], ["xn"], {"cse": True})


def stage_torque(robot: Robot, control: str, gravity: bool) -> ca.Function:
    """``TAU = mpc_tau<g|0>: (x, u) -> tau``: ``u`` itself (torque control; cheap) or the
    RNEA ``tau = RNEA(q, v, u) + D v`` (acceleration control). Arguments as for
    `stage_dynamics`."""
    n = robot.nv
    x, u = _symbols(n)
    if control == "torque":
        tau = u
    else:
        tau = symbolic.rnea(robot.model, x[:n], x[n:], u, _gravity(robot, gravity))
        d = joint_damping(robot)
        if d is not None:
            tau = tau + ca.DM(d) * x[n:]
    name = f"mpc_tau{'g' if gravity else '0'}"
    return ca.Function(name, [x, u], [tau], ["x", "u"], ["tau"], {"cse": True})


def _gravity(robot: Robot, gravity: bool) -> np.ndarray:
    return np.asarray(robot.gravity, dtype=np.float64) if gravity else np.zeros(3)
