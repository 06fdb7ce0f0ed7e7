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

import re

import casadi as ca

from geosyn.controllers.mpc.dynamics import StageDynamics
from geosyn.core.codegen import compile_library

__all__ = ["compiled_dynamics", "zero_curvature_library"]


def _sx_copy(fun: ca.Function, name: str) -> ca.Function:
    """An SX function evaluating ``fun`` under a new name (for code generation)."""
    ins = [ca.SX.sym(fun.name_in(i), fun.sparsity_in(i)) for i in range(fun.n_in())]
    return ca.Function(name, ins, fun.call(ins), fun.name_in(), fun.name_out(), {"cse": True})


def _first_order_jacobian(fun: ca.Function, name: str) -> ca.Function:
    """The Jacobian of a derivative function ``fun`` with its second-order part dropped.

    Blocks with respect to the seed inputs (named ``adj_*``/``fwd_*``; the derivative is
    linear in them) are kept exactly; blocks with respect to the nominal inputs (second
    derivatives of the original function) are structurally zero.
    """
    jj = fun.jacobian()
    ins = [ca.SX.sym(jj.name_in(i), jj.sparsity_in(i)) for i in range(jj.n_in())]
    full = jj.call(ins)
    seeds = {
        fun.name_in(i) for i in range(fun.n_in()) if fun.name_in(i).startswith(("adj_", "fwd_"))
    }
    outs = []
    for i in range(jj.n_out()):
        name_out = jj.name_out(i)  # "jac_<out>_<in>"
        keep = any(name_out.endswith("_" + s_) for s_ in seeds)
        sp = jj.sparsity_out(i)
        outs.append(full[i] if keep else ca.SX(sp.size1(), sp.size2()))
    return ca.Function(name, ins, outs, jj.name_in(), jj.name_out())


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
    parts: list[ca.Function] = []
    for f in funs:
        jac = _sx_copy(f.jacobian(), f"jac_{f.name()}")
        # Also adding adj1_<name> with a first-order-only Jacobian would remove the
        # dynamics from the Hessian graph; it was not worth its larger compile.
        parts += [f, jac, _first_order_jacobian(jac, f"jac_jac_{f.name()}")]
    return compile_library(name, parts, load=[f.name() for f in funs])


def compiled_dynamics(dynamics: StageDynamics, control: str, robot_name: str) -> StageDynamics:
    """The stage dynamics with their nonlinear part compiled without curvature.

    Torque control: the RK4 step on the ABA is the nonlinear part. Acceleration control:
    the double integrator is linear, only the RNEA torque is compiled.

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
    tag = re.sub(r"\W", "_", f"geosyn_mpc_{robot_name}_{control}_{len(funs)}")
    lib = zero_curvature_library(funs, tag)
    return StageDynamics(
        lib.get(dynamics.F.name(), dynamics.F), lib.get(dynamics.TAU.name(), dynamics.TAU)
    )
