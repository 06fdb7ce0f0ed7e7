"""The log map: the initial velocity whose geodesic reaches a goal at t = 1.

`log_solve` solves the boundary-value problem exp(q0, v0)(1) = q1 by damped Newton
shooting (`geosyn.metrics.geodesic.shooting`); when Newton fails from the initial guess,
the continuations of `geosyn.metrics.geodesic.continuation` and an optional seeded
multistart follow. `log` returns only the velocity.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple, TypedDict

import numpy as np
from typing_extensions import Unpack

from geosyn.core.types import Vector
from geosyn.core.validation import check_int, check_positive, check_vector
from geosyn.metrics.base import Metric, check_metric
from geosyn.metrics.errors import GeodesicNotFound
from geosyn.metrics.geodesic.continuation import (
    parameter_continuation,
    parameter_homotopy,
    target_continuation,
)
from geosyn.metrics.geodesic.shooting import Budget, Shooter, newton, residual_norm

__all__ = ["LogOptions", "LogResult", "log", "log_solve"]


MAX_SHOOTING_STEPS = 10_000
"""Largest number of RK4 steps of the shooting map of `log_solve` (its CasADi graph and
compiled code grow with it; 10^9 steps ran out of memory after 13 s)."""


class LogResult(NamedTuple):
    """Result of the log map (boundary-value solve).

    Attributes:
        v0: (n,) initial velocity [rad/s] such that exp(q0, v0, 1.0)(1) = q1.
        residual: ||q(1) - q1|| [rad] of the returned v0 (same number of RK4 steps).
        iterations: Newton iterations spent in total (all starts and stages).
        method: how the solution was found: ``"newton"`` (from the initial guess),
            ``"newton(straight-line)"`` (v_init failed, the straight-line guess worked),
            ``"parameter continuation"``, ``"continuation"`` or ``"multistart"``.
        discretization_error: ||q(1) with 2 x steps - q1|| [rad]: within ``residual`` of
            the change of q(1) when the steps double, ~15/16 of the RK4 error; solutions
            above ``discretization_tol`` are rejected (a solution of the discretised
            shooting map only, e.g. skimming a stiff obstacle barrier).
    """

    v0: np.ndarray
    residual: float
    iterations: int
    method: str
    discretization_error: float = 0.0


class LogOptions(TypedDict, total=False):
    """Keyword options of `log_solve`, as accepted by `log` and `distance`."""

    v_init: Vector | None
    steps: int
    tol: float
    max_iter: int
    multistart: int
    seed: int
    continuation: bool
    discretization_tol: float
    max_time: float | None


def log_solve(
    metric: Metric,
    q0: Vector,
    q1: Vector,
    *,
    v_init: Vector | None = None,
    steps: int = 100,
    tol: float = 1e-10,
    max_iter: int = 50,
    multistart: int = 0,
    seed: int = 0,
    continuation: bool = True,
    discretization_tol: float = 1e-4,
    max_time: float | None = None,
) -> LogResult:
    """Log map with diagnostics: the v0 whose geodesic reaches q1 at t = 1.

    Solves ``exp(metric, q0, v0, 1.0, steps).q[-1] = q1`` by damped Newton shooting
    (backtracking line search on the residual norm). The Jacobian ``dq(1)/dv0`` is the
    forward difference of the compiled shooting map (all n + 1 trajectories in one
    batched call); between fresh Jacobians, Broyden updates (one trajectory per step) are
    used while each step halves the residual. Strategy, in order, until one converges:

    1. Newton from ``v_init`` (default: the straight-line guess ``q1 - q0``);
    2. if ``v_init`` was given: Newton from the straight-line guess;
    3. (if ``continuation`` and the metric has a parameter homotopy, e.g. a shaped metric
       with obstacles, which shrinks them about their centres; see
       `geosyn.metrics.geodesic.continuation.parameter_homotopy`) continuation on the
       metric parameters from the easiest problem (s = 0, solved from the first guess)
       to the metric's own (s = 1), secant predictor, adaptive stage length;
    4. (if ``continuation``) continuation on the target ``q1(s) = q0 + s (q1 - q0)``
       from s = 0 to 1, each stage warm-started by a tangent predictor, the stage length
       adapted;
    5. ``multistart`` Newton runs from seeded random perturbations of the straight-line
       guess (normal, standard deviation 0.5 |q1 - q0| per component).

    Args:
        metric: the metric.
        q0: (n,) start joint positions [rad].
        q1: (n,) goal joint positions [rad].
        v_init: (n,) initial guess of v0 [rad/s], e.g. the solution of a nearby pair.
        steps: RK4 steps of the shooting integration (as in `exp`), in [1, `MAX_SHOOTING_STEPS`].
        tol: residual tolerance ||q(1) - q1|| [rad], > 0.
        max_iter: budget of Newton iterations (Jacobian evaluations) of each strategy
            (the initial guesses together, each continuation over all its stages, the
            restarts together), >= 1; `LogResult.iterations` reports the total.
        multistart: number of random restarts, >= 0.
        seed: seed of the restarts' random generator.
        continuation: try the continuations (steps 3 and 4) when Newton fails.
        discretization_tol: largest accepted change of q(1) [rad] when the converged v0
            is integrated with twice the steps; a solution above it is rejected and the
            next strategy tried (raise ``steps`` for stiff metrics).
        max_time: wall-time budget of the whole solve [s], > 0, or None (iterations
            only); a strategy running when it expires stops at its next Newton iteration
            and the solve raises `GeodesicNotFound` saying so.

    Returns:
        The solution and how it was found.

    Raises:
        InvalidArgument: bad shapes, non-finite values or bad options.
        GeodesicNotFound: no start converged within the budget; carries the smallest
            residual reached [rad] and its v0.
    """
    metric = check_metric(metric)
    n = metric.n
    q0 = check_vector(q0, n, "q0")
    q1 = check_vector(q1, n, "q1")
    steps = check_int(steps, "steps", low=1, high=MAX_SHOOTING_STEPS)
    tol = check_positive(tol, "tol")
    discretization_tol = check_positive(discretization_tol, "discretization_tol")
    max_iter = check_int(max_iter, "max_iter", low=1)
    deadline = math.inf
    if max_time is not None:
        deadline = time.monotonic() + check_positive(max_time, "max_time", "s")
    multistart = check_int(multistart, "multistart", low=0)
    seed = check_int(seed, "seed")
    straight = q1 - q0
    shooter = Shooter(metric, q0, steps)
    best_v, best_r = straight, math.inf
    spent = 0  # Newton iterations of the finished strategies

    def keep(v: np.ndarray, r: float) -> None:
        nonlocal best_v, best_r
        if r < best_r:
            best_v, best_r = v, r

    coarse: list[float] = []  # discretisation errors of rejected solutions

    def accept(v: np.ndarray, r: float, method: str, budget: Budget) -> LogResult | None:
        """The result if the converged v0 also solves the finer discretisation."""
        # |q_fine(1) - q1| differs from the RK4 change |q_fine(1) - q(1)| by at most the
        # residual r <= tol, and needs one integration fewer.
        err = residual_norm(shooter.end_fine(v) - q1)
        if err <= discretization_tol:
            return LogResult(v, r, spent + budget.used, method, err)
        coarse.append(err)
        return None

    # Each strategy has its own budget of max_iter Newton iterations, so a failing one
    # never starves the next.
    starts: list[tuple[np.ndarray, str]] = []
    if v_init is not None:
        starts.append((check_vector(v_init, n, "v_init"), "newton"))
        starts.append((straight, "newton(straight-line)"))
    else:
        starts.append((straight, "newton"))
    budget = Budget(max_iter, deadline)
    for guess, label in starts:
        v, r, ok, _ = newton(shooter, q1, guess.copy(), tol, budget)
        keep(v, r)
        if ok and (res := accept(v, r, label, budget)) is not None:
            return res
    spent += budget.used
    if continuation and parameter_homotopy(metric, 0.0) is not None:
        budget = Budget(max_iter, deadline)
        v, r, ok = parameter_continuation(shooter, metric, q1, starts[0][0], tol, budget)
        if ok and (res := accept(v, r, "parameter continuation", budget)) is not None:
            return res
        if math.isfinite(r):
            keep(v, r)
        spent += budget.used
    if continuation:
        budget = Budget(max_iter, deadline)
        v, r, ok = target_continuation(shooter, q1, tol, budget)
        if ok and (res := accept(v, r, "continuation", budget)) is not None:
            return res
        if math.isfinite(r):
            keep(v, r)
        spent += budget.used
    rng = np.random.default_rng(seed)
    scale = 0.5 * max(float(np.linalg.norm(straight)), 1e-3)
    budget = Budget(max_iter, deadline)
    for _ in range(multistart):
        if budget.left <= 0:
            break
        guess = straight + scale * rng.standard_normal(n)
        v, r, ok, _ = newton(shooter, q1, guess, tol, budget)
        keep(v, r)
        if ok and (res := accept(v, r, "multistart", budget)) is not None:
            return res
    spent += budget.used
    raise GeodesicNotFound(
        f"log: no geodesic from q0={q0.tolist()} to q1={q1.tolist()} found with "
        f"steps={steps}, tol={tol:g}, max_iter={max_iter}, multistart={multistart}: "
        f"best residual {best_r:.3e} rad after {spent} Newton iterations"
        + (
            f"; stopped by the time budget max_time={max_time:g} s"
            if time.monotonic() >= deadline
            else ""
        )
        + (
            f"; {len(coarse)} converged solution(s) rejected: their end point moved by "
            f"{min(coarse):.1e} rad or more with 2 x steps (discretization_tol="
            f"{discretization_tol:g}): raise steps"
            if coarse
            else ""
        ),
        residual=best_r,
        v0=best_v,
    )


def log(metric: Metric, q0: Vector, q1: Vector, **options: Unpack[LogOptions]) -> Vector:
    """Log map: the (n,) initial velocity v0 [rad/s] with exp(q0, v0, 1.0, steps) = q1.

    Args:
        metric: the metric.
        q0: (n,) start joint positions [rad].
        q1: (n,) goal joint positions [rad].
        **options: the keyword options of `log_solve` (v_init, steps, tol, ...), with its
            defaults; an unknown name raises TypeError.

    Raises:
        InvalidArgument, GeodesicNotFound: as `log_solve`, which also reports the residual.
    """
    return log_solve(metric, q0, q1, **options).v0
