"""Solver front-ends of the MPC: option builders for fatrop and IPOPT, and the pair of
solvers (warm-started and cold) built for one NLP graph, each a `BoundedSolver` (a wall-time
budget whatever the iteration limit, interruptible by signals)."""

from __future__ import annotations

from typing import Any

import casadi as ca

from geosyn.controllers.mpc.nlp.bounded import FATROP_CHUNK, BoundedSolver
from geosyn.controllers.mpc.nlp.options import NLPOptions
from geosyn.controllers.mpc.nlp.problem import NLPGraph

__all__ = ["build_solvers", "fatrop_options", "ipopt_options", "iteration_limit"]

# No SX expansion step: an exact-Hessian graph is SX already, and a Gauss-Newton graph
# calls compiled code, which cannot be expanded.
_COMMON: dict[str, Any] = {"expand": False, "print_time": False, "error_on_fail": False}


def iteration_limit(settings: NLPOptions) -> int:
    """The iteration limit of one solve: ``max_iter``, or the plugin option that overrides it."""
    return int((settings.plugin_options or {}).get("max_iter", settings.max_iter))


def fatrop_options(settings: NLPOptions, equality: list[bool], mu: float) -> dict[str, Any]:
    """``casadi.nlpsol`` options for fatrop.

    fatrop ignores the multipliers passed as a warm start; only the primal guess and the
    initial barrier parameter ``mu`` make a warm start. Its ``max_iter`` is at most
    `FATROP_CHUNK` per call (`BoundedSolver` calls it again while the budget lasts).

    Args:
        settings: tolerances, iteration limit and plugin options (applied last).
        equality: per constraint row, whether it is an equality (structure detection).
        mu: initial barrier parameter.
    """
    plugin: dict[str, Any] = {
        "mu_init": mu,
        "print_level": 0,
        "tol": settings.tol,
        "max_iter": settings.max_iter,
    }
    plugin.update(settings.plugin_options or {})
    plugin["max_iter"] = min(iteration_limit(settings), FATROP_CHUNK)
    return {**_COMMON, "structure_detection": "auto", "equality": equality, "fatrop": plugin}


def ipopt_options(
    settings: NLPOptions, mu: float, warm: bool, max_solve_time: float
) -> dict[str, Any]:
    """``casadi.nlpsol`` options for IPOPT.

    Args:
        settings: tolerances, iteration limit and plugin options (applied last).
        mu: initial barrier parameter.
        warm: start from the given primal-dual point (``warm_start_init_point``), with a
            monotone barrier strategy.
        max_solve_time: wall-time budget of one solve [s].

    IPOPT stops after ``max_solve_time`` seconds (``max_wall_time``; status
    ``Maximum_WallTime_Exceeded``, an unsuccessful solve).
    """
    plugin: dict[str, Any] = {
        "print_level": 0,
        "sb": "yes",
        "tol": settings.tol,
        "max_iter": settings.max_iter,
        "mu_init": mu,
        "max_wall_time": max_solve_time,
    }
    if warm:
        plugin.update(
            warm_start_init_point="yes",
            warm_start_bound_push=1e-6,
            warm_start_mult_bound_push=1e-6,
            mu_strategy="monotone",
        )
    plugin.update(settings.plugin_options or {})
    return {**_COMMON, "ipopt": plugin}


def build_solvers(
    graph: NLPGraph, settings: NLPOptions, max_solve_time: float
) -> tuple[BoundedSolver, BoundedSolver]:
    """The warm-start and cold-start solvers of an NLP graph (allocates; seconds).

    Args:
        graph: the NLP graph (`geosyn.controllers.mpc.nlp.problem.transcribe`).
        settings: the solver options; warm solves start with ``mu_warm``, cold ones
            with ``mu_init``.
        max_solve_time: wall-time budget of one solve [s] (IPOPT's ``max_wall_time``;
            for fatrop checked between its calls of `FATROP_CHUNK` iterations).

    Returns:
        ``(warm, cold)``, each a `BoundedSolver` called like a ``casadi.nlpsol`` function.
    """
    name, nlp = settings.solver, graph.nlp
    if name == "fatrop":
        warm_opts = fatrop_options(settings, graph.equality, settings.mu_warm)
        cold_opts = fatrop_options(settings, graph.equality, settings.mu_init)
    else:
        warm_opts = ipopt_options(settings, settings.mu_warm, True, max_solve_time)
        cold_opts = ipopt_options(settings, settings.mu_init, False, max_solve_time)
    warm = ca.nlpsol("mpc_warm", name, nlp, warm_opts)
    cold = ca.nlpsol("mpc_cold", name, nlp, cold_opts)
    limit = iteration_limit(settings)
    then = warm if name == "fatrop" and limit > FATROP_CHUNK else None
    return (
        BoundedSolver(warm, then, limit, max_solve_time),
        BoundedSolver(cold, then, limit, max_solve_time),
    )
