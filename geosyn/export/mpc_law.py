"""The exported form of the torque-level box-DDP MPC (``GeodesicMPC(solver="ddp")``).

What goes into C: the MPC's own CasADi graphs, built uncompiled
(`geosyn.controllers.mpc.ddp.parts.ddp_parts` with ``compiled=False``) and generated to
C by CasADi: one backward pass over the horizon (stage Jacobians and the Riccati
recursion, the box QP inside), one closed-loop rollout, one rollout step (the shifted
tail of a warm start), the mass matrix (the gains of a cold solve's first rollout), and
RNEA (the reference torques, the computed-torque fallback). The driver
(``c/geosyn_mpc.c``) does what `GeodesicMPC` does around them, with the constants of
`geosyn.controllers.mpc.ddp.riccati` and `geosyn.controllers.mpc.ocp.settings`.

The MPC package exposes no public accessor for its parameter vector and horizon graphs
yet: `ddp_graphs` reads them (``GeodesicMPC._tracker.solver.P`` and
``riccati._backward_graph`` / ``_forward_graph``); the MPC should expose them (e.g.
``DDPTracking.parameters`` and ``RiccatiSolver.graphs()``).
"""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np

from geosyn.controllers import GeodesicMPC
from geosyn.controllers.mpc.ddp import riccati
from geosyn.controllers.mpc.ddp.options import DDPOptions
from geosyn.controllers.mpc.ddp.parameters import DDPCosts
from geosyn.controllers.mpc.ddp.parts import ddp_parts
from geosyn.controllers.mpc.ocp.plan import EPS_T
from geosyn.controllers.mpc.ocp.settings import STATE_MARGIN
from geosyn.export.errors import ExportError
from geosyn.export.law import LAW_FUNCTION, ControlLaw
from geosyn.robots.symbolic import crba, rnea

#: C files of the MPC driver (copied from ``c/``) and of its generated functions.
MPC_TEMPLATES = ("geosyn_mpc.c", "geosyn_mpc.h")
MPC_FUNCTIONS = "geosyn_mpc_fun"


class DDPGraphs(NamedTuple):
    """The MPC's solver pieces as CasADi functions (named as the C driver calls them).

    Attributes:
        backward: ``(X, U, XR, TR, P) -> (k (n, N), K (n, 2n N), dV (2,))``.
        rollout: ``(x0, X_bar, U_bar, k, K, alpha, XR, TR, P) -> (X, U, cost)``.
        step: ``(x, xb, ub, k, K, alpha, xr, tr, P) -> (u, xn, cost)``, one stage.
        crba: ``q -> M (n, n)``.
        P: the parameter vector the Python solver uses.
    """

    backward: ca.Function
    rollout: ca.Function
    step: ca.Function
    crba: ca.Function
    P: np.ndarray


def _renamed(fun: ca.Function, name: str) -> ca.Function:
    args = fun.mx_in()
    return ca.Function(name, args, fun.call(args), fun.name_in(), fun.name_out())


def check_exportable(ctl: GeodesicMPC) -> DDPOptions:
    """The controller's `DDPOptions`.

    Raises:
        ExportError: not ``solver="ddp"`` with ``control="torque"``, with a clearance
            margin (obstacles are not exported), or for a robot with joint damping (the
            C driver's reference and fallback torques are RNEA alone, while the Python
            MPC adds the file's ``D v``).
    """
    options = ctl.solver_options
    if not isinstance(options, DDPOptions) or ctl.control != "torque":
        raise ExportError(
            "controller: only GeodesicMPC(solver='ddp', control='torque') is exported to C, "
            f"got solver={options.name!r}, control={ctl.control!r}"
        )
    if ctl.settings.clearance_margin is not None:
        raise ExportError(
            "controller: GeodesicMPC with clearance_margin (obstacles) cannot be exported "
            "to C yet; export it without obstacles"
        )
    if np.any(ctl.robot.damping):
        raise ExportError(
            f"controller: robot {ctl.robot.name!r} has joint damping"
            f" {np.asarray(ctl.robot.damping).tolist()}, which the exported MPC driver does"
            " not model yet (the Python MPC does); export computed torque or the PD instead"
        )
    return options


def ddp_graphs(ctl: GeodesicMPC) -> DDPGraphs:
    """The CasADi graphs of the controller's DDP solver, uncompiled (builds graphs:
    about a second for 7 joints).

    Raises:
        ExportError: what `check_exportable` refuses.
    """
    check_exportable(ctl)
    s, robot, n = ctl.settings, ctl.robot, ctl.nv
    costs = DDPCosts(robot, ctl.metric, s.effort, s.tracking, None)
    parts = ddp_parts(robot, s.dt, s.rk4_steps, costs, compiled=False)
    q = ca.SX.sym("q", n)
    P = np.asarray(ctl._tracker.solver.P, dtype=np.float64).copy()  # type: ignore[attr-defined]
    return DDPGraphs(
        _renamed(riccati._backward_graph(parts, s.N, n), "geosyn_mpc_backward"),
        _renamed(riccati._forward_graph(parts, s.N, n), "geosyn_mpc_rollout"),
        _renamed(parts.forward, "geosyn_mpc_step"),
        ca.Function("geosyn_mpc_crba", [q], [crba(robot.model, q)], ["q"], ["M"]),
        P,
    )


def mpc_law(ctl: GeodesicMPC) -> ControlLaw:
    """`ControlLaw` of a ``GeodesicMPC(solver="ddp", control="torque")``.

    Raises:
        ExportError: what `check_exportable` refuses.
    """
    options = check_exportable(ctl)
    robot, n = ctl.robot, ctl.nv
    graphs = ddp_graphs(ctl)
    q, v, a = (ca.SX.sym(name, n) for name in ("q", "v", "a"))
    gravity = np.asarray(robot.model.gravity.linear, dtype=np.float64).copy()
    law = ca.Function(
        LAW_FUNCTION, [q, v, a], [rnea(robot.model, q, v, a, gravity)], ["q", "v", "a"], ["tau"]
    )
    generated = (graphs.backward, graphs.rollout, graphs.step, graphs.crba)
    sizes = [(f.sz_arg(), f.sz_res(), f.sz_iw(), f.sz_w()) for f in (*generated, law)]
    arrays = {
        "geosyn_tau_max": np.asarray(robot.tau_max, dtype=np.float64),
        "geosyn_kp": ctl.kp,
        "geosyn_kd": ctl.kd,
        "geosyn_q_min": np.asarray(robot.q_min, dtype=np.float64),
        "geosyn_q_max": np.asarray(robot.q_max, dtype=np.float64),
        "geosyn_v_max": np.asarray(robot.v_max, dtype=np.float64),
        "geosyn_mpc_P": graphs.P,
        "geosyn_mpc_line_search": np.asarray(riccati.LINE_SEARCH_STEPS),
    }
    scalars: dict[str, float | int] = {
        "GEOSYN_MPC_N": ctl.N,
        "GEOSYN_MPC_DT": ctl.dt,
        "GEOSYN_MPC_NP": int(graphs.P.size),
        "GEOSYN_MPC_TOL": options.tol,
        "GEOSYN_MPC_MAX_ITER": options.max_iter,
        "GEOSYN_MPC_WARM_ITERATIONS": options.warm_iterations,
        "GEOSYN_MPC_PLAN_TOLERANCE": ctl.plan_tolerance,
        "GEOSYN_MPC_EPS_T": EPS_T,
        "GEOSYN_MPC_MAX_REG": riccati.MAX_REGULARISATION,
        "GEOSYN_MPC_ROUNDING": riccati.ROUNDING,
        "GEOSYN_MPC_N_LINE_SEARCH": len(riccati.LINE_SEARCH_STEPS),
        "GEOSYN_MPC_MARGIN_Q": STATE_MARGIN[0],
        "GEOSYN_MPC_MARGIN_V": STATE_MARGIN[1],
        **{
            f"GEOSYN_MPC_SZ_{name}": max(int(z[i]) for z in sizes) + 1
            for i, name in enumerate(("ARG", "RES", "IW", "W"))
        },
    }
    s = ctl.settings
    settings: dict[str, object] = {
        "solver": "box-DDP, one real-time iteration per solve (warm_iterations "
        f"{options.warm_iterations}), Riccati feedback between solves",
        "horizon N": ctl.N,
        "dt [s]": ctl.dt,
        "effort": s.effort,
        "tracking": s.tracking,
        "rk4_steps": s.rk4_steps,
        "kp [1/s^2]": ctl.kp.tolist(),
        "kd [1/s]": ctl.kd.tolist(),
        "plan_tolerance [rad]": ctl.plan_tolerance,
        "tol, max_iter (cold solves)": [options.tol, options.max_iter],
        "solve time budget": "none (Python: max_solve_time)",
        "tau_max [N m]": robot.tau_max.tolist(),
    }
    return ControlLaw(
        "ddp_mpc", law, arrays, scalars, settings, generated=generated, c_files=MPC_TEMPLATES
    )
