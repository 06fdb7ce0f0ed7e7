"""Compiled stage dynamics without curvature: Gauss-Newton Hessians for the MPC.

The per-stage dynamics (RK4 on the ABA, or the RNEA in acceleration mode) dominate an
interior-point iteration when their exact second derivatives are used. Here they are
compiled to C together with their Jacobian and a *structurally zero* second derivative:
CasADi's ``external`` takes ``jac_<f>`` and ``jac_jac_<f>`` from the same library, so
the Lagrangian Hessian keeps only the costs' own curvature, a generalised Gauss-Newton
Hessian (exact for quadratic tracking costs). The library goes through the one
compiled-code cache, `geosyn.core.codegen.compile_library`.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable
from pathlib import Path

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.ocp import dynamics as dynamics_module
from geosyn.controllers.mpc.ocp import rk4 as rk4_module
from geosyn.controllers.mpc.ocp.dynamics import (
    StageDynamics,
    joint_damping,
    stage_step,
    stage_torque,
)
from geosyn.controllers.mpc.ocp.rk4 import rk4_step
from geosyn.core.codegen import compile_library, compile_recipe
from geosyn.robots import symbolic
from geosyn.robots.robot import Robot

__all__ = [
    "cached_stage_dynamics",
    "compiled_dynamics",
    "rk4_parts",
    "stage_recipe",
    "zero_curvature_library",
    "zero_curvature_parts",
]


def _sx_copy(fun: ca.Function, name: str) -> ca.Function:
    """An SX function evaluating ``fun`` under a new name (for code generation)."""
    ins = [ca.SX.sym(fun.name_in(i), fun.sparsity_in(i)) for i in range(fun.n_in())]
    return ca.Function(name, ins, fun.call(ins), fun.name_in(), fun.name_out(), {"cse": True})


def _first_order_jacobian(fun: ca.Function, name: str) -> ca.Function:
    """The Jacobian of a derivative function ``fun`` with its second-order part dropped.

    Blocks with respect to the seed inputs (named ``adj_*``/``fwd_*``; the derivative is
    linear in them) are kept exactly; blocks with respect to the nominal inputs (second
    derivatives of the original function) are structurally zero. Without seed inputs
    (a plain Jacobian ``jac_<f>``) every block is zero, and the second derivative is never
    formed: the inputs and outputs follow CasADi's naming of ``fun.jacobian()``.
    """
    seeds = {
        fun.name_in(i) for i in range(fun.n_in()) if fun.name_in(i).startswith(("adj_", "fwd_"))
    }
    if not seeds:
        return _zero_jacobian(fun, name)
    jj = fun.jacobian()
    ins = [ca.SX.sym(jj.name_in(i), jj.sparsity_in(i)) for i in range(jj.n_in())]
    full = jj.call(ins)
    outs = []
    for i in range(jj.n_out()):
        name_out = jj.name_out(i)  # "jac_<out>_<in>"
        keep = any(name_out.endswith("_" + s_) for s_ in seeds)
        sp = jj.sparsity_out(i)
        outs.append(full[i] if keep else ca.SX(sp.size1(), sp.size2()))
    return ca.Function(name, ins, outs, jj.name_in(), jj.name_out())


def zero_curvature_parts(funs: list[ca.Function]) -> list[ca.Function]:
    """Each of ``funs`` with its Jacobian ``jac_<f>`` and a structurally zero
    ``jac_jac_<f>``: the functions of a `zero_curvature_library` (builds SX graphs)."""
    parts: list[ca.Function] = []
    for f in funs:
        jac = _sx_copy(f.jacobian(), f"jac_{f.name()}")
        # Also adding adj1_<name> with a first-order-only Jacobian would remove the
        # dynamics from the Hessian graph; it was not worth its larger compile.
        parts += [f, jac, _first_order_jacobian(jac, f"jac_jac_{f.name()}")]
    return parts


def rk4_parts(robot: Robot, dt: float, rk4_steps: int, gravity: bool) -> list[ca.Function]:
    """The torque-control stage ``mpc_F<g|0>`` (RK4 on the ABA) and its Jacobian by the
    chain rule through RK4 (`geosyn.controllers.mpc.ocp.rk4.rk4_step`), a structurally
    zero ``jac_jac_*``, and its reverse derivative ``adj1_*`` (with a zero Jacobian): a
    `zero_curvature_parts` equivalent whose C code is about ten times smaller.

    Args:
        robot: the robot.
        dt: stage length [s].
        rk4_steps: RK4 steps per stage.
        gravity: include the robot's gravity.
    """
    step = rk4_step(robot, dt, rk4_steps, gravity)
    F, jac, name = step.F, step.jacobian, step.F.name()
    n = robot.nv
    x, u = ca.MX.sym("x", 2 * n), ca.MX.sym("u", n)
    out = ca.MX.sym("out_xn", ca.Sparsity(2 * n, 1))  # the unused nominal output
    # The reverse derivative (exact) with a structurally zero Jacobian: the Lagrangian
    # Hessian (forward over reverse, in x only) then skips a second pass through the
    # dynamics. Zero is the Gauss-Newton value in x and u; the block in the seed (J^T)
    # is declared zero too, which only a derivative with respect to the multipliers would
    # see, and no solver asks for one (-40 % Hessian time at N = 10).
    seed = ca.MX.sym("adj_xn", 2 * n)
    Jx, Ju = jac(x, u, out)
    adj = ca.Function(
        f"adj1_{name}",
        [x, u, out, seed],
        [Jx.T @ seed, Ju.T @ seed],
        ["x", "u", "out_xn", "adj_xn"],
        ["adj_x", "adj_u"],
    )
    return [
        F,
        jac,
        _first_order_jacobian(jac, f"jac_jac_{name}"),
        adj,
        _zero_jacobian(adj, f"jac_adj1_{name}"),
    ]


def _zero_jacobian(fun: ca.Function, name: str) -> ca.Function:
    """The Jacobian of ``fun`` (CasADi's naming and shapes of ``fun.jacobian()``: inputs
    ``fun``'s and its nominal outputs, outputs ``jac_<out>_<in>``), every block
    structurally zero, named ``name``; the second derivative is never formed."""
    sp_in = [fun.sparsity_in(i) for i in range(fun.n_in())]
    sp_out = [fun.sparsity_out(i) for i in range(fun.n_out())]
    in_names = list(fun.name_in()) + [f"out_{o}" for o in fun.name_out()]
    empty = [ca.Sparsity(sp.size1(), sp.size2()) for sp in sp_out]
    ins = [ca.SX.sym(n, sp) for n, sp in zip(in_names, sp_in + empty, strict=True)]
    outs, out_names = [], []
    for out_name, so in zip(fun.name_out(), sp_out, strict=True):
        for in_name, si in zip(fun.name_in(), sp_in, strict=True):
            out_names.append(f"jac_{out_name}_{in_name}")
            outs.append(ca.SX(so.numel(), si.numel()))
    return ca.Function(name, ins, outs, in_names, out_names)


def zero_curvature_library(funs: list[ca.Function], name: str) -> dict[str, ca.Function]:
    """Compile SX functions with their Jacobians and a structurally zero ``jac_jac_*``.

    Declaring the derivative of the Jacobian empty removes each function's curvature from
    every Hessian built from it. One shared library per set of functions, cached on disk
    by a hash of the generated C code. Allocates; a cache miss runs the C compiler.

    Args:
        funs: SX functions of dense inputs and outputs, named by C identifiers.
        name: library name, a C identifier.

    Returns:
        ``{f.name(): compiled f}`` for each of ``funs``.

    Raises:
        CodegenError: no compiler, or compiling/loading failed.
    """
    return compile_library(name, zero_curvature_parts(funs), load=[f.name() for f in funs])


def compiled_dynamics(dynamics: StageDynamics, control: str, robot_name: str) -> StageDynamics:
    """The stage dynamics with their nonlinear part compiled without curvature.

    Torque control: the RK4 step on the ABA is the nonlinear part. Acceleration control:
    the double integrator is linear, only the RNEA torque is compiled. The C source is
    generated to find the library (seconds for a 7-DoF RK4 step); `cached_stage_dynamics`
    finds it from a recipe instead.

    Args:
        dynamics: the SX stage functions (`stage_dynamics`).
        control: ``"torque"`` or ``"acceleration"``.
        robot_name: part of the library's name.

    Returns:
        `StageDynamics` with the compiled function(s) in place of the SX ones.

    Raises:
        CodegenError: no compiler, or compiling/loading failed.
    """
    funs = [dynamics.F] if control == "torque" else [dynamics.TAU]
    lib = zero_curvature_library(funs, _library_name(robot_name, control))
    return StageDynamics(
        lib.get(dynamics.F.name(), dynamics.F), lib.get(dynamics.TAU.name(), dynamics.TAU)
    )


def _library_name(robot_name: str, control: str) -> str:
    return re.sub(r"\W", "_", f"geosyn_mpc_{robot_name}_{control}_1")


def _code_digest() -> str:
    """sha256 of the code that builds the stage functions (symbolic dynamics, the
    description's dynamics and RK4 step, and this module): a code change is a new recipe."""
    files = sorted(Path(symbolic.__file__).parent.glob("*.py"))
    files += [Path(dynamics_module.__file__), Path(rk4_module.__file__), Path(__file__)]
    digest = hashlib.sha256()
    for path in files:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def stage_recipe(robot: Robot, dt: float, control: str, rk4_steps: int, gravity: bool) -> str:
    """Everything the compiled stage function depends on, as text (the cache's recipe):
    the Pinocchio model (serialised), gravity, ``dt``, control mode, RK4 steps, the joint
    damping (when there is any), CasADi's version and a digest of the code that builds
    the graph."""
    g = np.asarray(robot.gravity, dtype=np.float64) if gravity else np.zeros(3)
    damping = joint_damping(robot)
    return "\0".join(
        [
            "geosyn-mpc-stage-v1",
            ca.CasadiMeta.version(),
            _code_digest(),
            robot.model.saveToString(),
            g.tobytes().hex(),
            float(dt).hex(),
            control,
            str(int(rk4_steps)),
        ]
        + ([] if damping is None else ["damping", damping.tobytes().hex()])
    )


def cached_stage_dynamics(
    robot: Robot,
    dt: float,
    control: str,
    rk4_steps: int,
    gravity: bool,
    progress: Callable[[str], None] | None = None,
) -> StageDynamics:
    """The stage dynamics with the nonlinear part compiled without curvature, found
    through a recipe (`stage_recipe`): a robot and settings seen before load in
    milliseconds, without building the symbolic graph (`geosyn.core.codegen.compile_recipe`).

    The same functions as ``compiled_dynamics(stage_dynamics(...), control, robot.name)``
    to rounding; torque control compiles `rk4_parts` (the Jacobian by the chain rule
    through RK4: about ten times less C than the expanded Jacobian, and faster), so a
    first build compiles in seconds, not minutes. The linear part (the double integrator,
    or ``tau = u``) is built as SX, which is cheap.

    Args:
        robot: the robot.
        dt: stage length [s].
        control: ``"torque"`` or ``"acceleration"``.
        rk4_steps: RK4 steps per stage.
        gravity: include the robot's gravity.
        progress: receives a line before and after each slow step of a first build.

    Raises:
        CodegenError: no compiler, or compiling/loading failed.
    """
    torque = control == "torque"

    def make() -> list[ca.Function]:
        if torque:
            return rk4_parts(robot, dt, rk4_steps, gravity)
        return zero_curvature_parts([stage_torque(robot, control, gravity)])

    tag = "g" if gravity else "0"
    wanted = f"mpc_F{tag}" if torque else f"mpc_tau{tag}"
    recipe = stage_recipe(robot, dt, control, rk4_steps, gravity)
    lib = compile_recipe(
        _library_name(robot.name, control), recipe, make, load=[wanted], progress=progress
    )
    if torque:
        return StageDynamics(lib[wanted], stage_torque(robot, control, gravity))
    return StageDynamics(stage_step(robot, dt, control, rk4_steps, gravity), lib[wanted])
