"""The exported form of the torque-level box-DDP MPC (``GeodesicMPC(solver="ddp")``).

What goes into C, read through the MPC's public accessor (``GeodesicMPC.backend.graphs()``,
`geosyn.controllers.mpc.ddp.tracking.DDPGraphs`) and generated to C by CasADi: the
solver's own closed-loop rollout and rollout step (the shifted tail of a warm start), the
mass matrix (the gains of a cold solve's first rollout), RNEA plus the file's viscous
joint damping ``D v`` (the reference torques and the computed-torque fallback, as the
Python MPC adds it; the file's dry friction is fed forward as there), and the per-stage functions of the backward pass
(`geosyn.controllers.mpc.ddp.native.functions`), which the hand-written ``geosyn_ddp.c``
(`geosyn.controllers.mpc.ddp.native`, the same file the Python solver runs) chains into
the RK4 Jacobians and the Riccati recursion with the box QP (loops over small dense
matrices: several times less code, and faster, than CasADi's unrolled form of the whole
pass). The driver (``c/geosyn_mpc.c``) does what `GeodesicMPC` does around them, with the
constants of `geosyn.controllers.mpc.ddp.riccati` and
`geosyn.controllers.mpc.ocp.settings`.
"""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np

from geosyn.controllers import GeodesicMPC
from geosyn.controllers.mpc.ddp import riccati
from geosyn.controllers.mpc.ddp.box_qp import BOX_ITERATIONS
from geosyn.controllers.mpc.ddp.native.functions import (
    dynamics_function,
    inverse_jacobian_function,
    stage_box_function,
    terminal_function,
)
from geosyn.controllers.mpc.ddp.options import DDPOptions
from geosyn.controllers.mpc.ddp.parameters import DDPCosts, split_parameters
from geosyn.controllers.mpc.ddp.tracking import DDPTracking
from geosyn.controllers.mpc.ocp.dynamics import FRICTION_VELOCITY, joint_friction
from geosyn.controllers.mpc.ocp.plan import EPS_T
from geosyn.controllers.mpc.ocp.settings import STATE_MARGIN
from geosyn.export.errors import ExportError
from geosyn.export.law import LAW_FUNCTION, ControlLaw
from geosyn.robots.symbolic import crba, rnea

#: C files of the MPC driver (copied from ``c/`` and, the solver's,
#: `geosyn.controllers.mpc.ddp.native.C_DIR`) and of its generated functions.
MPC_TEMPLATES = ("geosyn_mpc.c", "geosyn_mpc.h", "geosyn_ddp.c", "geosyn_ddp.h")
MPC_FUNCTIONS = "geosyn_mpc_fun"
#: The solver code's second build for AVX2 CPUs (x86-64 compilers only; see
#: `geosyn.export.build.avx2_flags`).
MPC_AVX2_SOURCE = "geosyn_ddp_avx2.c"


class MPCFunctions(NamedTuple):
    """The MPC's solver pieces as CasADi functions (named as the C driver calls them).

    Attributes:
        rollout: ``(x0, X_bar, U_bar, k, K, alpha, XR, TR, P) -> (X, U, cost)``.
        step: ``(x, xb, ub, k, K, alpha, xr, tr, P) -> (u, xn, cost)``, one stage.
        crba: ``q -> M (n, n)``.
        dyn, drnea, stage, terminal: the backward pass's functions
            (`geosyn.controllers.mpc.ddp.native.functions`).
        P: the parameter vector the Python solver uses.
    """

    rollout: ca.Function
    step: ca.Function
    crba: ca.Function
    dyn: ca.Function
    drnea: ca.Function
    stage: ca.Function
    terminal: ca.Function
    P: np.ndarray


def _renamed(fun: ca.Function, name: str) -> ca.Function:
    args = fun.mx_in()
    return ca.Function(name, args, fun.call(args), fun.name_in(), fun.name_out())


def check_exportable(ctl: GeodesicMPC) -> tuple[DDPOptions, DDPTracking]:
    """The controller's `DDPOptions` and its DDP backend.

    Raises:
        ExportError: not ``solver="ddp"`` with ``control="torque"``, with a clearance
            margin (obstacles are not exported), or with the joint-limit guard on (the C
            driver has no guard: a different law).
    """
    options, backend = ctl.solver_options, ctl.backend
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
    if ctl.command.guard is not None:
        raise ExportError(
            "controller: GeodesicMPC with joint_limit_guard=True (its torques pass the"
            " joint-limit guard's QP) cannot be exported to C yet; build it with"
            " joint_limit_guard=False to export the MPC without the guard"
        )
    if not isinstance(backend, DDPTracking):
        raise ExportError(
            f"controller: the DDP MPC's backend is a {type(backend).__name__}, not the"
            " DDPTracking the export reads"
        )
    return options, backend


def mpc_functions(ctl: GeodesicMPC) -> MPCFunctions:
    """The CasADi functions of the controller's DDP solver that the export generates
    (builds graphs: about a second for 7 joints).

    Raises:
        ExportError: what `check_exportable` refuses.
    """
    _, backend = check_exportable(ctl)
    solver = backend.graphs()
    s, n = ctl.settings, ctl.nv
    costs = DDPCosts(ctl.robot, ctl.metric, s.effort, s.tracking, None)
    q = ca.SX.sym("q", n)
    P = np.asarray(solver.P, dtype=np.float64)
    return MPCFunctions(
        _renamed(solver.rollout, "geosyn_mpc_rollout"),
        _renamed(solver.parts.forward, "geosyn_mpc_step"),
        ca.Function("geosyn_mpc_crba", [q], [crba(ctl.robot.model, q)], ["q"], ["M"]),
        dynamics_function(ctl.robot),
        inverse_jacobian_function(ctl.robot),
        stage_box_function(n, costs, P.size),
        terminal_function(n, costs),
        P,
    )


def mpc_law(ctl: GeodesicMPC) -> ControlLaw:
    """`ControlLaw` of a ``GeodesicMPC(solver="ddp", control="torque")``.

    Raises:
        ExportError: what `check_exportable` refuses.
    """
    options, _ = check_exportable(ctl)
    robot, n = ctl.robot, ctl.nv
    graphs = mpc_functions(ctl)
    q, v, a = (ca.SX.sym(name, n) for name in ("q", "v", "a"))
    gravity = np.asarray(robot.model.gravity.linear, dtype=np.float64).copy()
    tau = rnea(robot.model, q, v, a, gravity)
    damping = np.asarray(robot.damping, dtype=np.float64)
    if np.any(damping):  # RNEA + D v, as the Python MPC's reference and fallback torques
        tau = tau + ca.DM(damping) * v
    law = ca.Function(LAW_FUNCTION, [q, v, a], [tau], ["q", "v", "a"], ["tau"])
    friction = joint_friction(robot)  # fed forward per stage, as the Python MPC does
    generated = tuple(f for f in graphs if isinstance(f, ca.Function))
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
        "geosyn_mpc_friction": np.zeros(n) if friction is None else friction,
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
        "GEOSYN_MPC_RK4_STEPS": ctl.settings.rk4_steps,
        "GEOSYN_MPC_FRICTION": int(friction is not None),
        "GEOSYN_MPC_FRICTION_VELOCITY": FRICTION_VELOCITY,
        "GEOSYN_MPC_BOX_ITERATIONS": BOX_ITERATIONS,
        "GEOSYN_MPC_REG_INDEX": int(split_parameters(np.arange(graphs.P.size), n).reg[0]),
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
        "joint damping D [N m s/rad] (in the dynamics and RNEA + D v)": damping.tolist(),
        "dry friction f_c [N m] (fed forward, f_c tanh(v_r / v_s))": (
            [] if friction is None else friction.tolist()
        ),
        "v_s [rad/s]": FRICTION_VELOCITY,
    }
    return ControlLaw(
        "ddp_mpc", law, arrays, scalars, settings, generated=generated, c_files=MPC_TEMPLATES
    )
