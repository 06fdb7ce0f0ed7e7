"""Control laws that can be exported: what of a Python controller goes into C.

Each exportable controller class maps to a `ControlLaw`: the CasADi function of its
rigid-body terms (generated to C) and the numbers the hand-written C driver needs
(gains, torque limits, friction). The C driver (``c/geosyn_controller.c``) applies the
same operations, in the same order, as the Python ``_compute`` of the controller.
"""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from geosyn.controllers import ComputedTorque, Controller, GeodesicMPC, RiemannianPD
from geosyn.export.errors import ExportError
from geosyn.export.law import LAW_FUNCTION, ControlLaw
from geosyn.export.mpc_law import mpc_law
from geosyn.robots.robot import Robot
from geosyn.robots.symbolic import rnea


def _symbols(n: int, names: str) -> list[ca.SX]:
    return [ca.SX.sym(name, n) for name in names.split()]


def _gravity(robot: Robot) -> np.ndarray:
    return np.asarray(robot.model.gravity.linear, dtype=np.float64).copy()


def computed_torque_law(ctl: ComputedTorque) -> ControlLaw:
    """`ControlLaw` of a `ComputedTorque`: ``RNEA(q, v, a_des)`` in C, PD and friction
    in the driver."""
    robot, n = ctl.robot, ctl.nv
    q, v, a = _symbols(n, "q v a_des")
    fun = ca.Function(
        LAW_FUNCTION, [q, v, a], [rnea(robot.model, q, v, a, _gravity(robot))],
        ["q", "v", "a_des"], ["tau"],
    )  # fmt: skip
    arrays = {
        "geosyn_tau_max": np.asarray(robot.tau_max, dtype=np.float64),
        "geosyn_kp": ctl.kp,
        "geosyn_kd": ctl.kd,
        "geosyn_damping": np.asarray(robot.damping, dtype=np.float64),
        "geosyn_frictionloss": np.asarray(robot.frictionloss, dtype=np.float64),
    }
    settings = {
        "kp [1/s^2]": ctl.kp.tolist(),
        "kd [1/s]": ctl.kd.tolist(),
        "compensate_friction": ctl.compensate_friction,
        "tau_max [N m]": robot.tau_max.tolist(),
    }
    scalars = {
        "GEOSYN_FRICTION": int(ctl.compensate_friction),
        "GEOSYN_FRICTION_VELOCITY": ctl.friction_velocity,
    }
    return ControlLaw("computed_torque", fun, arrays, scalars, settings)


def riemannian_pd_law(ctl: RiemannianPD) -> ControlLaw:
    """`ControlLaw` of a `RiemannianPD`: ``M a_x + C(q, v) v_x + g + D v_x`` in C (``D``
    the robot file's viscous joint damping), the dry friction ``f_c tanh(v_x / v_s)`` in
    the driver, as the Python controller compensates them.

    ``C(q, v) w`` with the Christoffel-symbol Coriolis matrix is the symmetric bilinear
    form of the velocity terms, so by polarization
    ``C(q, v) w = (c(q, v + w) - c(q, v - w)) / 4`` with ``c(q, v) = RNEA(q, v, 0) - g``;
    ``M a_x + g = RNEA(q, 0, a_x)``. Three RNEA passes, no mass matrix.
    """
    robot, n = ctl.robot, ctl.nv
    q, v, vx, ax = _symbols(n, "q v v_x a_x")
    model, g, zero = robot.model, _gravity(robot), np.zeros(n)
    coriolis = (
        rnea(model, q, v + vx, zero, np.zeros(3)) - rnea(model, q, v - vx, zero, np.zeros(3))
    ) / 4
    out = rnea(model, q, zero, ax, g) + coriolis
    damping = np.asarray(robot.damping, dtype=np.float64)
    if np.any(damping):  # the file's viscous damping compensated along v_r (= v_x)
        out = out + ca.DM(damping) * vx
    fun = ca.Function(LAW_FUNCTION, [q, v, vx, ax], [out], ["q", "v", "v_x", "a_x"], ["tau"])
    friction = np.asarray(robot.frictionloss, dtype=np.float64)
    compensated = bool(friction.size and np.any(friction))  # as RiemannianPD decides
    arrays = {
        "geosyn_tau_max": np.asarray(robot.tau_max, dtype=np.float64),
        "geosyn_lam": ctl.lam,
        "geosyn_k": ctl.k,
        "geosyn_frictionloss": friction,
    }
    scalars = {
        "GEOSYN_FRICTION": int(compensated),
        "GEOSYN_FRICTION_VELOCITY": ctl.friction_velocity,
    }
    settings = {
        "joint damping D [N m s/rad] (compensated along v_r)": damping.tolist(),
        "dry friction f_c [N m] (compensated along v_r, f_c tanh(v_r / v_s))": friction.tolist(),
        "v_s [rad/s]": ctl.friction_velocity,
        "lam [1/s]": ctl.lam.tolist(),
        "k [N m s/rad]": ctl.k.tolist(),
        "tau_max [N m]": robot.tau_max.tolist(),
    }
    return ControlLaw("riemannian_pd", fun, arrays, scalars, settings)


#: Exportable controller classes and the function that reads their law.
LAWS: dict[type, Callable[..., ControlLaw]] = {
    ComputedTorque: computed_torque_law,
    RiemannianPD: riemannian_pd_law,
    GeodesicMPC: mpc_law,
}


def control_law(controller: Controller) -> ControlLaw:
    """The `ControlLaw` of a controller instance.

    Raises:
        ExportError: the controller's class cannot be exported (the message lists those
            that can).
    """
    for cls, read in LAWS.items():
        if type(controller) is cls:
            return read(controller)
    names = ", ".join(cls.__name__ for cls in LAWS)
    raise ExportError(
        f"controller: {type(controller).__name__} cannot be exported to C; exportable: {names}"
    )
