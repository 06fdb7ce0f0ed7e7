"""The log map: the initial velocity whose geodesic reaches a goal at t = 1.

`log_solve` solves the boundary-value problem exp(q0, v0)(1) = q1 by damped Newton
shooting (`geosyn.metrics.geodesic.shooting`); when Newton fails from the initial guess,
the continuations of `geosyn.metrics.geodesic.continuation` and an optional seeded
multistart follow. `log` returns only the velocity.

Newton is damped (backtracking line search on the residual norm). The Jacobian ``dq(1)/dv0`` is the
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
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
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

    Solves ``exp(metric, q0, v0, 1.0, steps).q[-1] = q1``; the strategies, in order, are
    in the module docstring.

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
    search = _Search(
        Shooter(metric, q0, steps), q1, straight, tol, discretization_tol, max_iter, deadline
    )
    v_init = None if v_init is None else check_vector(v_init, n, "v_init")
    # Each strategy has its own budget of max_iter Newton iterations, so a failing one
    # never starves the next.
    result = search.from_guesses(v_init)
    if result is None and continuation and parameter_homotopy(metric, 0.0) is not None:
        first = straight if v_init is None else v_init
        result = search.by_parameter_continuation(metric, first)
    if result is None and continuation:
        result = search.by_target_continuation()
    if result is None:
        result = search.by_multistart(multistart, seed)
    if result is None:
        raise search.failure(q0, steps, multistart, max_time)
    return result


@dataclass
class _Search:
    """The state of one `log_solve`: the shooting map, the best point so far, the budget
    spent, and the converged solutions rejected for their discretisation error."""

    shooter: Shooter
    q1: np.ndarray  # (n,) goal [rad]
    straight: np.ndarray  # (n,) the straight-line guess q1 - q0 [rad/s]
    tol: float
    discretization_tol: float
    max_iter: int
    deadline: float  # time.monotonic() deadline [s]
    best_v: np.ndarray = field(init=False)  # (n,) v0 of the smallest residual so far
    best_r: float = math.inf
    spent: int = 0  # Newton iterations of the finished strategies
    coarse: list[float] = field(default_factory=list)  # rejected discretisation errors

    def __post_init__(self) -> None:
        self.best_v = self.straight

    def keep(self, v: np.ndarray, r: float) -> None:
        """Remember ``v`` if its residual ``r`` is the smallest so far."""
        if r < self.best_r:
            self.best_v, self.best_r = v, r

    def accept(self, v: np.ndarray, r: float, method: str, budget: Budget) -> LogResult | None:
        """The result if the converged v0 is finite and solves the finer discretisation."""
        if not np.all(np.isfinite(v)):
            return None
        # |q_fine(1) - q1| differs from the RK4 change |q_fine(1) - q(1)| by at most the
        # residual r <= tol, and needs one integration fewer.
        err = residual_norm(self.shooter.end_fine(v) - self.q1)
        if err <= self.discretization_tol:
            return LogResult(v, r, self.spent + budget.used, method, err)
        self.coarse.append(err)
        return None

    def from_guesses(self, v_init: np.ndarray | None) -> LogResult | None:
        """Newton from ``v_init`` then the straight-line guess (strategies 1 and 2)."""
        starts = [(self.straight, "newton")]
        if v_init is not None:
            starts = [(v_init, "newton"), (self.straight, "newton(straight-line)")]
        budget = Budget(self.max_iter, self.deadline)
        for guess, label in starts:
            v, r, ok, _ = newton(self.shooter, self.q1, guess.copy(), self.tol, budget)
            self.keep(v, r)
            if ok and (res := self.accept(v, r, label, budget)) is not None:
                return res
        self.spent += budget.used
        return None

    def _finish_stage(
        self, v: np.ndarray, r: float, ok: bool, method: str, budget: Budget
    ) -> LogResult | None:
        if ok and (res := self.accept(v, r, method, budget)) is not None:
            return res
        if math.isfinite(r):
            self.keep(v, r)
        self.spent += budget.used
        return None

    def by_parameter_continuation(self, metric: Metric, first: np.ndarray) -> LogResult | None:
        """Continuation on the metric's parameter homotopy (strategy 3)."""
        budget = Budget(self.max_iter, self.deadline)
        v, r, ok = parameter_continuation(self.shooter, metric, self.q1, first, self.tol, budget)
        return self._finish_stage(v, r, ok, "parameter continuation", budget)

    def by_target_continuation(self) -> LogResult | None:
        """Continuation on the target q1(s) = q0 + s (q1 - q0) (strategy 4)."""
        budget = Budget(self.max_iter, self.deadline)
        v, r, ok = target_continuation(self.shooter, self.q1, self.tol, budget)
        return self._finish_stage(v, r, ok, "continuation", budget)

    def by_multistart(self, multistart: int, seed: int) -> LogResult | None:
        """Newton from seeded perturbations of the straight-line guess (strategy 5)."""
        straight = self.straight
        rng = np.random.default_rng(seed)
        scale = 0.5 * max(float(np.linalg.norm(straight)), 1e-3)
        budget = Budget(self.max_iter, self.deadline)
        for _ in range(multistart):
            if budget.left <= 0:
                break
            guess = straight + scale * rng.standard_normal(straight.shape[0])
            v, r, ok, _ = newton(self.shooter, self.q1, guess, self.tol, budget)
            self.keep(v, r)
            if ok and (res := self.accept(v, r, "multistart", budget)) is not None:
                return res
        self.spent += budget.used
        return None

    def failure(
        self, q0: np.ndarray, steps: int, multistart: int, max_time: float | None
    ) -> GeodesicNotFound:
        """The error of a solve in which no strategy converged."""
        timed_out = time.monotonic() >= self.deadline
        return GeodesicNotFound(
            f"log: no geodesic from q0={q0.tolist()} to q1={self.q1.tolist()} found with "
            f"steps={steps}, tol={self.tol:g}, max_iter={self.max_iter}, multistart="
            f"{multistart}: best residual {self.best_r:.3e} rad after {self.spent} Newton"
            " iterations"
            + (f"; stopped by the time budget max_time={max_time:g} s" if timed_out else "")
            + (
                f"; {len(self.coarse)} converged solution(s) rejected: their end point moved"
                f" by {min(self.coarse):.1e} rad or more with 2 x steps (discretization_tol="
                f"{self.discretization_tol:g}): raise steps"
                if self.coarse
                else ""
            ),
            residual=self.best_r,
            v0=self.best_v,
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
