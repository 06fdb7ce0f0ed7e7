"""The hand-written C backward pass (``geosyn_ddp.c``) as a compiled CasADi function.

`native_backward` builds one C translation unit: the robot's generated per-stage functions
(`geosyn.controllers.mpc.ddp.native.functions`), the configuration (joints, horizon,
stage length, RK4 steps, box-QP iterations, where ``P`` holds the regularisation, the
generated functions' work sizes), ``geosyn_ddp.c`` and ``geosyn_ddp_casadi.c`` (its
entry point behind CasADi's external-function interface), compiles it through
`geosyn.core.codegen`'s disk cache (a key over the whole source, the compiler and the
flags; checked before loading) and loads it with ``casadi.external``. The function has
the inputs and outputs of `geosyn.controllers.mpc.ddp.riccati.backward_graph` and equals
it up to rounding (the sums run in another order): ``(X (2n, N+1), U (n, N),
XR (2n, N+1), TR (n, N), P) -> (k (n, N), K (n, 2n N), dV (2,))``.
"""

from __future__ import annotations

import functools
import platform
import re
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.ddp.box_qp import BOX_ITERATIONS
from geosyn.controllers.mpc.ddp.native.functions import (
    dynamics_function,
    inverse_jacobian_function,
    stage_box_function,
    terminal_function,
)
from geosyn.controllers.mpc.ddp.parameters import DDPCosts, split_parameters
from geosyn.core.codegen import CodegenError, compile_source, generate_source
from geosyn.robots.robot import Robot

__all__ = [
    "AVX2_FLAGS",
    "C_DIR",
    "FLAGS",
    "compile_flags",
    "NATIVE_FUNCTION",
    "native_backward",
    "native_source",
]

C_DIR = Path(__file__).resolve().parent
"""The folder of the hand-written C files (package data; `geosyn.export` copies them)."""
NATIVE_FUNCTION = "geosyn_ddp_native"
"""The name of the compiled backward pass (``geosyn_ddp_casadi.c``)."""
FLAGS = ("-O3", "-fvisibility=hidden")
"""Compiler flags: the library exports only the entry point and its metadata, so that
two robots' libraries in one process never bind each other's functions."""
AVX2_FLAGS = ("-mavx2", "-mfma", "-ffp-contract=fast")
"""Added on x86-64 CPUs with AVX2 and FMA (the library is compiled on the machine that
runs it; the flags are part of the cache key, so a cache shared with an older CPU never
hands it this build): 1.3x faster for the Panda, rounding differently (fused
multiply-adds)."""
_INCLUDE = re.compile(r'^#include "([^"]+)"\s*$', re.MULTILINE)


@functools.cache
def compile_flags() -> tuple[str, ...]:
    """`FLAGS`, plus `AVX2_FLAGS` when this CPU has AVX2 and FMA (x86-64 Linux: read from
    ``/proc/cpuinfo``; elsewhere never)."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return FLAGS
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return FLAGS
    cpu = set(
        next(
            (ln.split(":", 1)[1].split() for ln in text.splitlines() if ln.startswith("flags")), []
        )
    )
    return (*FLAGS, *AVX2_FLAGS) if {"avx2", "fma"} <= cpu else FLAGS


def _inlined(name: str, given: Mapping[str, str]) -> str:
    """The C file ``name`` of `C_DIR` with its local ``#include "..."`` lines replaced by
    the text ``given`` for that name, else by the file of `C_DIR` (inlined the same way)."""

    def include(match: re.Match[str]) -> str:
        target = match.group(1)
        return given[target] if target in given else _inlined(target, given)

    return _INCLUDE.sub(include, (C_DIR / name).read_text())


def native_source(
    robot: Robot, dt: float, rk4_steps: int, N: int, costs: DDPCosts, n_p: int
) -> str:
    """The C source of the native backward pass (builds the small CasADi functions and
    generates their C; allocates).

    Args:
        robot: the robot (its model, gravity and joint damping).
        dt: stage length [s]; rk4_steps: RK4 steps per stage; N: stages.
        costs: the stage and terminal costs (`DDPCosts`, with the clearance if any).
        n_p: the length of the parameter vector ``P``.
    """
    n = robot.nv
    funs = [
        dynamics_function(robot),
        inverse_jacobian_function(robot),
        stage_box_function(n, costs, n_p),
        terminal_function(n, costs),
    ]
    sizes = [(f.sz_arg(), f.sz_res(), f.sz_iw(), f.sz_w()) for f in funs]
    config = {
        "GEOSYN_NQ": n,
        "GEOSYN_MPC_N": N,
        "GEOSYN_MPC_NP": n_p,
        "GEOSYN_MPC_DT": repr(float(dt)),  # the shortest exact round trip
        "GEOSYN_MPC_RK4_STEPS": rk4_steps,
        "GEOSYN_MPC_BOX_ITERATIONS": BOX_ITERATIONS,
        "GEOSYN_MPC_REG_INDEX": int(split_parameters(np.arange(n_p), n).reg[0]),
        "GEOSYN_DDP_BACKWARD_ONLY": 1,
        **{
            f"GEOSYN_MPC_SZ_{what}": max(int(z[i]) for z in sizes) + 1
            for i, what in enumerate(("ARG", "RES", "IW", "W"))
        },
    }
    header = "\n".join(f"#define {key} {value}" for key, value in config.items()) + "\n"
    # The generated functions stay inside the library (hidden: no export macro).
    generated = "#define CASADI_SYMBOL_EXPORT\n" + generate_source("geosyn_mpc_fun", funs)
    given = {"geosyn_controller_config.h": header, "geosyn_mpc_fun.h": ""}
    return "\n".join(
        [generated, _inlined("geosyn_ddp.c", given), _inlined("geosyn_ddp_casadi.c", given)]
    )


def native_backward(
    robot: Robot,
    dt: float,
    rk4_steps: int,
    N: int,
    costs: DDPCosts,
    n_p: int,
    *,
    name: str,
    progress: Callable[[str], None] | None = None,
) -> ca.Function:
    """The compiled native backward pass (see the module docstring), from the disk cache
    when this source was compiled before (generating the source takes a fraction of a
    second for 7 joints; a first compile about a second).

    Args:
        robot, dt, rk4_steps, N, costs, n_p: as for `native_source`.
        name: the library's name in the cache (a C identifier).
        progress: receives a line after a first compile.

    Raises:
        CodegenError: no C compiler, or compiling or loading failed.
    """
    start = time.perf_counter()
    source = native_source(robot, dt, rk4_steps, N, costs, n_p)
    try:
        lib = compile_source(name, source, [NATIVE_FUNCTION], flags=compile_flags())
    except OSError as err:
        raise CodegenError(f"could not build the native DDP backward pass {name}: {err}") from err
    elapsed = time.perf_counter() - start
    if progress is not None and elapsed > 1.0:  # a first compile (a cache hit: ~0.1 s)
        progress(
            f"{name}: native DDP backward pass ({len(source) / 1e3:.0f} kB of C) in {elapsed:.1f} s"
        )
    return lib[NATIVE_FUNCTION]
