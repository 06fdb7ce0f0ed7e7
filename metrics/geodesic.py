"""Geodesics of any `Metric`: exponential map, log map, distance, energy, transport.

A geodesic of the metric G(q) solves

.. math:: G(q)\\,\\ddot q + \\Gamma(\\dot q, \\dot q) = 0, \\qquad
    \\Gamma(a, b)_i = \\sum_{jk} \\Gamma_{ijk} a_j b_k

(Christoffel symbols of the first kind), i.e. ``qdd = metric.geodesic_acceleration(q, qd)``.

- `exp` integrates it from (q0, v0) with a fixed-step RK4 whose whole loop runs in
  compiled code: one RK4 step of the state ``x = (q, v)`` is built as a CasADi SX function
  from ``metric.symbolic_geodesic_acceleration``, compiled to C with
  `geosyn.core.codegen.compile_function` (cached on disk) and repeated with
  ``mapaccum``. Metrics without a symbolic form fall back to a numpy RK4 loop.
  ``method="dop853"`` integrates with SciPy's DOP853 at rtol = atol = 1e-12 instead.
- `log` / `log_solve` solve the boundary-value problem exp(q0, v0)(1) = q1 by damped
  Newton shooting; the Jacobian dq(1)/dv0 comes from forward differences of the compiled
  shooting map, all n + 1 trajectories in one batched call, refreshed by Broyden updates.
  (An exact variational Jacobian by AD compiles ~13x more C code: ~80 s of gcc for panda,
  against ~1.5 s for the RK4 step, for no gain in speed.) If Newton fails from the
  initial guess, a continuation on the target (q1(s) = q0 + s (q1 - q0)) and optional
  seeded multistart follow.
- `path_energy`, `straight_line`, `distance` and `parallel_transport` complete the set.

Built functions are cached per metric instance (and per number of steps);
`clear_geodesic_cache` empties the cache.
"""

from __future__ import annotations

import math
import weakref
from typing import NamedTuple

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_positive
from geosyn.metrics.base import Metric, christoffel_from_dG, sx_cholesky_solve
from geosyn.metrics.errors import GeodesicNotFound, NoSymbolicForm

__all__ = [
    "Geodesic",
    "LogResult",
    "clear_geodesic_cache",
    "distance",
    "exp",
    "log",
    "log_solve",
    "parallel_transport",
    "path_energy",
    "straight_line",
]

_METHODS = ("rk4", "dop853", "adaptive")
_DOP853_TOL = 1e-12
# Forward-difference step of the shooting Jacobian, relative to max(1, |v0|_inf):
# ~sqrt(machine epsilon), so the Jacobian is exact to ~1e-8 relative.
_FD_STEP = 1e-7
_MAX_STAGES = 200  # continuation stages
_MIN_DS = 1.0 / 4096.0  # smallest continuation step
_STAGE_TOL = 1e-6  # residual tolerance of intermediate continuation stages [rad]


class Geodesic(NamedTuple):
    """A sampled path in configuration space (a geodesic, or a baseline path).

    Attributes:
        t: (T,) time stamps [s].
        q: (T, n) joint positions [rad].
        v: (T, n) joint velocities [rad/s].
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray


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
            the change of q(1) when the steps double, ~15/16 of the RK4 error; solutions above ``discretization_tol``
            are rejected (a solution of the discretised shooting map only, e.g. skimming
            a stiff obstacle barrier).
    """

    v0: np.ndarray
    residual: float
    iterations: int
    method: str
    discretization_error: float = 0.0


# --------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------
def _vector(x: object, name: str, n: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"{name} must be a float array, got {x!r}") from err
    want = f"({n},)" if n is not None else "(n,)"
    if arr.ndim != 1 or (n is not None and arr.shape[0] != n) or arr.size == 0:
        raise InvalidArgument(f"{name} must have shape {want}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidArgument(f"{name} must be finite, got {arr}")
    return arr


def _steps(steps: object, name: str = "steps") -> int:
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InvalidArgument(f"{name} must be an int >= 1, got {steps!r}")
    return int(steps)


def _metric(metric: object) -> Metric:
    if not isinstance(metric, Metric):
        raise InvalidArgument(f"metric must be a geosyn Metric, got {type(metric).__name__}")
    return metric


def _path(
    t: object, q: object, n: int | None, name_t: str = "t", name_q: str = "q"
) -> tuple[np.ndarray, np.ndarray]:
    tt = np.asarray(t, dtype=np.float64)
    qq = np.asarray(q, dtype=np.float64)
    if tt.ndim != 1 or tt.shape[0] < 2:
        raise InvalidArgument(f"{name_t} must have shape (T,) with T >= 2, got shape {tt.shape}")
    if qq.ndim != 2 or qq.shape[0] != tt.shape[0] or (n is not None and qq.shape[1] != n):
        want = f"({tt.shape[0]}, {n if n is not None else 'n'})"
        raise InvalidArgument(f"{name_q} must have shape {want}, got shape {qq.shape}")
    if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(qq))):
        raise InvalidArgument(f"{name_t} and {name_q} must be finite")
    dt = np.diff(tt)
    if not (np.all(dt > 0) or np.all(dt < 0)):
        raise InvalidArgument(f"{name_t} must be strictly monotonic, got {tt}")
    return tt, qq


# --------------------------------------------------------------------------------------
# Per-metric cache of built functions
# --------------------------------------------------------------------------------------
class _Functions:
    """Functions built for one metric: the RK4 step and, per steps, its repetitions."""

    def __init__(self, metric: Metric) -> None:
        self.n = metric.n
        self.symbolic = True
        self.step: ca.Function | None = None
        self.transport_A: ca.Function | None = None
        self.exp: dict[int, ca.Function] = {}
        self.shoot: dict[int, tuple[ca.Function, ca.Function]] = {}
        self.transport_map: dict[int, ca.Function] = {}
        try:
            self.step = _build_step(metric)
        except NoSymbolicForm:
            self.symbolic = False


_CACHE: dict[int, _Functions] = {}


def clear_geodesic_cache(metric: Metric | None = None) -> None:
    """Forget the functions built for ``metric`` (all metrics when None).

    The compiled C libraries stay in the codegen disk cache
    (`geosyn.core.codegen.clear_cache` removes them).
    """
    if metric is None:
        _CACHE.clear()
    else:
        _CACHE.pop(id(metric), None)


def _functions(metric: Metric) -> _Functions:
    key = id(metric)
    funcs = _CACHE.get(key)
    if funcs is None:
        funcs = _Functions(metric)
        try:
            # Entries die with their metric (ids are reused after garbage collection).
            weakref.finalize(metric, _CACHE.pop, key, None)
        except TypeError:
            return funcs  # not weak-referenceable: do not cache
        _CACHE[key] = funcs
    return funcs


def _compile(fun: ca.Function) -> ca.Function:
    from geosyn.core.codegen import compile_function

    return compile_function(fun, fallback=True)


def _theta(metric: Metric, dt: float) -> np.ndarray:
    """(1 + p,) step input: the time step [s] then the metric's parameter values.

    Parameterised metrics (obstacle poses in a shaped metric) are read here, at call time,
    so moving an obstacle changes an input and rebuilds nothing.
    """
    return np.concatenate([[dt], metric.parameter_values()])


def _build_step(metric: Metric) -> ca.Function:
    """One RK4 step of x = (q, v): (x (2n,), theta = [dt; p]) -> x', compiled to C."""
    n = metric.n
    q = ca.SX.sym("q", n)
    v = ca.SX.sym("v", n)
    p = metric.symbolic_parameters()
    acc = ca.Function(
        "geodesic_acceleration", [q, v, p], [metric.symbolic_geodesic_acceleration(q, v)]
    )
    x = ca.SX.sym("x", 2 * n)
    dt = ca.SX.sym("dt")
    theta = ca.vertcat(dt, p)

    def f(s: ca.SX) -> ca.SX:
        return ca.vertcat(s[n:], acc(s[:n], s[n:], p))

    k1 = f(x)
    k2 = f(x + 0.5 * dt * k1)
    k3 = f(x + 0.5 * dt * k2)
    k4 = f(x + dt * k3)
    x_next = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    step = ca.Function(
        "geodesic_rk4_step", [x, theta], [x_next], ["x", "theta"], ["x_next"], {"cse": True}
    )
    return _compile(step)


def _exp_function(funcs: _Functions, steps: int) -> ca.Function:
    """(x0 (2n,), thetas (1 + p, steps)) -> all states (2n, steps)."""
    fun = funcs.exp.get(steps)
    if fun is None:
        fun = funcs.step.mapaccum("geodesic_rk4", steps)  # type: ignore[union-attr]
        funcs.exp[steps] = fun
    return fun


def _shoot_functions(funcs: _Functions, steps: int) -> tuple[ca.Function, ca.Function]:
    """Shooting map x0 -> q(T) and its (n+1)-column batch, for a given number of steps."""
    pair = funcs.shoot.get(steps)
    if pair is None:
        n = funcs.n
        acc = _exp_function(funcs, steps)
        x0 = ca.MX.sym("x0", 2 * n)
        theta = ca.MX.sym("theta", acc.size1_in(1))
        states = acc(x0, ca.repmat(theta, 1, steps))
        shoot = ca.Function("geodesic_shoot", [x0, theta], [states[:n, steps - 1]])
        pair = (shoot, shoot.map(n + 1))
        funcs.shoot[steps] = pair
    return pair


# --------------------------------------------------------------------------------------
# Exponential map
# --------------------------------------------------------------------------------------
def _numpy_rk4(metric: Metric, q0: Vector, v0: Vector, dt: float, steps: int):
    n = metric.n
    X = np.empty((steps + 1, 2 * n))
    X[0, :n], X[0, n:] = q0, v0
    acc = metric.geodesic_acceleration

    def f(s: np.ndarray) -> np.ndarray:
        return np.concatenate([s[n:], acc(s[:n], s[n:])])

    x = X[0].copy()
    for k in range(steps):
        k1 = f(x)
        k2 = f(x + 0.5 * dt * k1)
        k3 = f(x + 0.5 * dt * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if not np.all(np.isfinite(x)):
            X[k + 1 :] = np.nan
            break
        X[k + 1] = x
    return X


def _rk4_states(metric: Metric, funcs: _Functions, q0, v0, duration: float, steps: int):
    """(steps+1, 2n) states of the fixed-step RK4 solution."""
    dt = duration / steps
    if not funcs.symbolic:
        return _numpy_rk4(metric, q0, v0, dt, steps)
    fun = _exp_function(funcs, steps)
    out = fun(np.concatenate([q0, v0]), np.tile(_theta(metric, dt)[:, None], (1, steps)))
    X = np.empty((steps + 1, 2 * metric.n))
    X[0, : metric.n], X[0, metric.n :] = q0, v0
    X[1:] = np.asarray(out).T
    return X


def exp(
    metric: Metric,
    q0: Vector,
    v0: Vector,
    duration: float = 1.0,
    steps: int = 100,
    method: str = "rk4",
) -> Geodesic:
    """Exponential map: the geodesic from q0 with initial velocity v0.

    Args:
        metric: the metric.
        q0: (n,) initial joint positions [rad].
        v0: (n,) initial joint velocities [rad/s].
        duration: integration time [s], > 0.
        steps: number of intervals, >= 1; the result has ``steps + 1`` samples,
            uniformly spaced, t = 0 included.
        method: ``"rk4"`` (fixed step, compiled loop; global error O(dt^4)) or
            ``"dop853"`` / ``"adaptive"`` (SciPy DOP853 with rtol = atol = 1e-12 on
            ``metric.geodesic_acceleration``, sampled at the same times).

    Returns:
        The sampled geodesic; ``q[-1]`` is exp_q0(duration * v0).

    The first call for a metric builds (and compiles, cached on disk) the RK4 step;
    later calls allocate only the result.

    Raises:
        InvalidArgument: bad shapes, non-finite values, steps < 1, duration <= 0, or an
            unknown method.
    """
    metric = _metric(metric)
    n = metric.n
    q0 = _vector(q0, "q0", n)
    v0 = _vector(v0, "v0", n)
    duration = check_positive(duration, "duration")
    steps = _steps(steps)
    if method not in _METHODS:
        raise InvalidArgument(f"method must be one of {', '.join(_METHODS)}, got {method!r}")
    t = np.linspace(0.0, duration, steps + 1)
    if method == "rk4":
        X = _rk4_states(metric, _functions(metric), q0, v0, duration, steps)
    else:
        from scipy.integrate import solve_ivp

        acc = metric.geodesic_acceleration

        def rhs(_t: float, x: np.ndarray) -> np.ndarray:
            return np.concatenate([x[n:], acc(x[:n], x[n:])])

        sol = solve_ivp(
            rhs,
            (0.0, duration),
            np.concatenate([q0, v0]),
            method="DOP853",
            t_eval=t,
            rtol=_DOP853_TOL,
            atol=_DOP853_TOL,
        )
        if not sol.success:
            raise GeodesicNotFound(
                f"exp: DOP853 failed: {sol.message}", residual=float("nan"), v0=v0
            )
        X = sol.y.T
    return Geodesic(t, X[:, :n].copy(), X[:, n:].copy())


# --------------------------------------------------------------------------------------
# Log map
# --------------------------------------------------------------------------------------
class _Shooter:
    """Shooting map v0 -> q(1) - target and its forward-difference Jacobian."""

    def __init__(self, metric: Metric, q0: np.ndarray, steps: int) -> None:
        self.metric = metric
        self.n = metric.n
        self.q0 = q0
        self.steps = steps
        self.dt = 1.0 / steps
        self.theta = _theta(metric, self.dt)
        self.funcs = _functions(metric)
        if self.funcs.symbolic:
            self._one, self._batch = _shoot_functions(self.funcs, steps)

    def set_parameters(self, values: np.ndarray) -> None:
        """Shoot with these metric parameter values (p,) instead of the metric's own."""
        self.theta = np.concatenate([[self.dt], values])

    def end(self, v0: np.ndarray) -> np.ndarray:
        """q(1) for initial velocity v0 (NaN if the integration blew up)."""
        if self.funcs.symbolic:
            return np.asarray(self._one(np.concatenate([self.q0, v0]), self.theta)).ravel()
        return _numpy_rk4(self.metric, self.q0, v0, self.dt, self.steps)[-1, : self.n]

    def end_fine(self, v0: np.ndarray) -> np.ndarray:
        """q(1) with twice the steps (for the discretisation check of a solution)."""
        if not self.funcs.symbolic:
            return _numpy_rk4(self.metric, self.q0, v0, 0.5 * self.dt, 2 * self.steps)[-1, : self.n]
        one, _ = _shoot_functions(self.funcs, 2 * self.steps)
        theta = self.theta.copy()
        theta[0] = 0.5 * self.dt
        return np.asarray(one(np.concatenate([self.q0, v0]), theta)).ravel()

    def end_and_jacobian(self, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """q(1) and d q(1) / d v0 (n, n) by forward differences."""
        n = self.n
        h = _FD_STEP * max(1.0, float(np.max(np.abs(v0))))
        V = np.repeat(v0[:, None], n + 1, axis=1)
        V[np.arange(n), np.arange(1, n + 1)] += h
        if self.funcs.symbolic:
            X0 = np.vstack([np.repeat(self.q0[:, None], n + 1, axis=1), V])
            Q = np.asarray(self._batch(X0, np.tile(self.theta[:, None], (1, n + 1))))
        else:
            Q = np.column_stack([self.end(V[:, j]) for j in range(n + 1)])
        return Q[:, 0], (Q[:, 1:] - Q[:, :1]) / h


class _Budget:
    def __init__(self, max_iter: int) -> None:
        self.left = max_iter
        self.used = 0


def _norm(r: np.ndarray) -> float:
    return float(np.linalg.norm(r)) if np.all(np.isfinite(r)) else math.inf


def _newton(
    shooter: _Shooter, target: np.ndarray, v: np.ndarray, tol: float, budget: _Budget
) -> tuple[np.ndarray, float, bool, np.ndarray | None]:
    """Damped Newton-Broyden on q(1; v) = target.

    A fresh (finite-difference) Jacobian is followed by cheap Broyden updates while they
    halve the residual at each step; otherwise the Jacobian is recomputed, and a step
    with a fresh Jacobian that does not decrease the residual is backtracked.

    Returns:
        (v, residual, converged, last Jacobian).
    """
    r = shooter.end(v) - target
    nr = _norm(r)
    J: np.ndarray | None = None
    fresh = False
    while nr > tol:
        if budget.left <= 0 or not math.isfinite(nr):
            return v, nr, False, J
        if J is None:
            _, J = shooter.end_and_jacobian(v)
            fresh = True
        budget.left -= 1
        budget.used += 1
        try:
            dv = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            dv = np.linalg.lstsq(J, -r, rcond=None)[0]
        r_try = shooter.end(v + dv) - target
        nr_try = _norm(r_try)
        if nr_try <= 0.5 * nr:
            # Good Broyden update: the secant condition J dv = r_try - r.
            J = J + np.outer(r_try - r - J @ dv, dv) / float(dv @ dv)
            v, r, nr, fresh = v + dv, r_try, nr_try, False
            continue
        if not fresh:
            J = None  # the secant model is off: recompute at the current v
            continue
        alpha = 1.0
        while nr_try >= (1.0 - 1e-4 * alpha) * nr:
            alpha *= 0.5
            if alpha < 1e-4:
                return v, nr, False, J  # line search stalled: a local minimum of |r|
            r_try = shooter.end(v + alpha * dv) - target
            nr_try = _norm(r_try)
        v, r, nr, J = v + alpha * dv, r_try, nr_try, None
    return v, nr, True, J


def _continuation(
    shooter: _Shooter, q1: np.ndarray, tol: float, budget: _Budget
) -> tuple[np.ndarray, float, bool]:
    """Homotopy on the target q1(s) = q0 + s (q1 - q0), s: 0 -> 1, with a tangent predictor."""
    q0 = shooter.q0
    delta = q1 - q0
    s, ds = 0.0, 0.125
    v = np.zeros_like(q0)
    tangent = delta.copy()  # dv/ds at s = 0 (the metric's exp is the identity to 1st order)
    for _ in range(_MAX_STAGES):
        s_new = min(1.0, s + ds)
        guess = v + (s_new - s) * tangent
        # Intermediate stages only need to be close enough to predict the next one.
        stage_tol = tol if s_new >= 1.0 else max(tol, _STAGE_TOL)
        v_new, nr_new, ok, J = _newton(shooter, q0 + s_new * delta, guess, stage_tol, budget)
        if ok:
            s, v = s_new, v_new
            if s >= 1.0:
                return v, nr_new, True
            if J is not None:
                try:
                    tangent = np.linalg.solve(J, delta)
                except np.linalg.LinAlgError:
                    pass
            ds = min(2.0 * ds, 1.0 - s)
        else:
            if budget.left <= 0:
                break
            ds *= 0.5
            if ds < _MIN_DS:
                break
    # Report the residual with respect to the final target, not the last stage's.
    return v, _norm(shooter.end(v) - q1), False


def _parameter_continuation(
    shooter: _Shooter,
    metric: Metric,
    q1: np.ndarray,
    guess: np.ndarray,
    tol: float,
    budget: _Budget,
) -> tuple[np.ndarray, float, bool]:
    """Homotopy on the metric parameters, ``metric.parameter_homotopy(s)``, s: 0 -> 1.

    Solves the easiest problem (s = 0) from ``guess``, then follows the solution with a
    secant predictor and adaptive stage length; s = 1 uses the metric's own parameters.
    The shooter is left with the metric's own parameters.
    """
    p_final = np.array(metric.parameter_values(), dtype=np.float64)

    def params(s: float) -> np.ndarray:
        if s >= 1.0:
            return p_final
        p = np.asarray(metric.parameter_homotopy(s), dtype=np.float64)
        if p.shape != p_final.shape or not np.all(np.isfinite(p)):
            raise InvalidArgument(
                f"{type(metric).__name__}.parameter_homotopy({s:g}) must return a finite "
                f"array of shape {p_final.shape}, got shape {p.shape}"
            )
        return p

    try:
        shooter.set_parameters(params(0.0))
        v, r, ok, _ = _newton(shooter, q1, guess.copy(), max(tol, _STAGE_TOL), budget)
        if not ok:
            return v, math.inf, False
        s, ds = 0.0, 0.25
        v_prev: np.ndarray | None = None
        s_prev = 0.0
        while budget.left > 0:
            s_new = min(1.0, s + ds)
            pred = v if v_prev is None else v + (v - v_prev) * (s_new - s) / (s - s_prev)
            shooter.set_parameters(params(s_new))
            stage_tol = tol if s_new >= 1.0 else max(tol, _STAGE_TOL)
            v_new, r, ok, _ = _newton(shooter, q1, pred, stage_tol, budget)
            if ok:
                v_prev, s_prev, v, s = v, s, v_new, s_new
                if s >= 1.0:
                    return v, r, True
                ds = min(1.5 * ds, 0.5)
            else:
                ds *= 0.5
                if ds < _MIN_DS:
                    break
        shooter.set_parameters(p_final)
        return v, _norm(shooter.end(v) - q1), False
    finally:
        shooter.set_parameters(p_final)


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
) -> LogResult:
    """Log map with diagnostics: the v0 whose geodesic reaches q1 at t = 1.

    Solves ``exp(metric, q0, v0, 1.0, steps).q[-1] = q1`` by damped Newton shooting
    (backtracking line search on the residual norm). The Jacobian ``dq(1)/dv0`` is the
    forward difference of the compiled shooting map (step ~1e-7, all n + 1 trajectories
    in one batched call), accurate to ~1e-8 relative; between fresh Jacobians, Broyden
    updates (one trajectory per step) are used while each step halves the residual.
    Strategy, in order, until one converges:

    1. Newton from ``v_init`` (default: the straight-line guess ``q1 - q0``);
    2. if ``v_init`` was given: Newton from the straight-line guess;
    3. (if ``continuation`` and the metric has a `Metric.parameter_homotopy`, e.g. a
       shaped metric with obstacles, which shrinks them about their centres) continuation
       on the metric parameters from the easiest problem (s = 0, solved from the first
       guess) to the metric's own (s = 1), secant predictor, adaptive stage length;
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
        steps: RK4 steps of the shooting integration (as in `exp`), >= 1.
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

    Returns:
        The solution and how it was found.

    Raises:
        InvalidArgument: bad shapes, non-finite values or bad options.
        GeodesicNotFound: no start converged within the budget; carries the smallest
            residual reached [rad] and its v0.
    """
    metric = _metric(metric)
    n = metric.n
    q0 = _vector(q0, "q0", n)
    q1 = _vector(q1, "q1", n)
    steps = _steps(steps)
    tol = check_positive(tol, "tol")
    discretization_tol = check_positive(discretization_tol, "discretization_tol")
    max_iter = _steps(max_iter, "max_iter")
    if (
        isinstance(multistart, bool)
        or not isinstance(multistart, (int, np.integer))
        or (multistart < 0)
    ):
        raise InvalidArgument(f"multistart must be an int >= 0, got {multistart!r}")
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise InvalidArgument(f"seed must be an int, got {seed!r}")
    straight = q1 - q0
    shooter = _Shooter(metric, q0, steps)
    best_v, best_r = straight, math.inf
    spent = 0  # Newton iterations of the finished strategies

    def keep(v: np.ndarray, r: float) -> None:
        nonlocal best_v, best_r
        if r < best_r:
            best_v, best_r = v, r

    coarse: list[float] = []  # discretisation errors of rejected solutions

    def accept(v: np.ndarray, r: float, method: str, budget: _Budget) -> LogResult | None:
        """The result if the converged v0 also solves the finer discretisation."""
        # |q_fine(1) - q1| differs from the RK4 change |q_fine(1) - q(1)| by at most the
        # residual r <= tol, and needs one integration fewer.
        err = _norm(shooter.end_fine(v) - q1)
        if err <= discretization_tol:
            return LogResult(v, r, spent + budget.used, method, err)
        coarse.append(err)
        return None

    # Each strategy has its own budget of max_iter Newton iterations, so a failing one
    # never starves the next.
    starts: list[tuple[np.ndarray, str]] = []
    if v_init is not None:
        starts.append((_vector(v_init, "v_init", n), "newton"))
        starts.append((straight, "newton(straight-line)"))
    else:
        starts.append((straight, "newton"))
    budget = _Budget(max_iter)
    for guess, label in starts:
        v, r, ok, _ = _newton(shooter, q1, guess.copy(), tol, budget)
        keep(v, r)
        if ok and (res := accept(v, r, label, budget)) is not None:
            return res
    spent += budget.used
    if continuation and metric.parameter_homotopy(0.0) is not None:
        budget = _Budget(max_iter)
        v, r, ok = _parameter_continuation(shooter, metric, q1, starts[0][0], tol, budget)
        if ok and (res := accept(v, r, "parameter continuation", budget)) is not None:
            return res
        if math.isfinite(r):
            keep(v, r)
        spent += budget.used
    if continuation:
        budget = _Budget(max_iter)
        v, r, ok = _continuation(shooter, q1, tol, budget)
        if ok and (res := accept(v, r, "continuation", budget)) is not None:
            return res
        if math.isfinite(r):
            keep(v, r)
        spent += budget.used
    rng = np.random.default_rng(seed)
    scale = 0.5 * max(float(np.linalg.norm(straight)), 1e-3)
    budget = _Budget(max_iter)
    for _ in range(int(multistart)):
        if budget.left <= 0:
            break
        guess = straight + scale * rng.standard_normal(n)
        v, r, ok, _ = _newton(shooter, q1, guess, tol, budget)
        keep(v, r)
        if ok and (res := accept(v, r, "multistart", budget)) is not None:
            return res
    spent += budget.used
    raise GeodesicNotFound(
        f"log: no geodesic from q0={q0.tolist()} to q1={q1.tolist()} found with "
        f"steps={steps}, tol={tol:g}, max_iter={max_iter}, multistart={multistart}: "
        f"best residual {best_r:.3e} rad after {spent} Newton iterations"
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


def log(
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
) -> Vector:
    """Log map: the (n,) initial velocity v0 [rad/s] with exp(q0, v0, 1.0, steps) = q1.

    Same arguments and errors as `log_solve`, which also reports the residual.
    """
    return log_solve(
        metric,
        q0,
        q1,
        v_init=v_init,
        steps=steps,
        tol=tol,
        max_iter=max_iter,
        multistart=multistart,
        seed=seed,
        continuation=continuation,
        discretization_tol=discretization_tol,
    ).v0


def distance(metric: Metric, q0: Vector, q1: Vector, **log_kwargs: object) -> float:
    """Riemannian distance along the geodesic found by `log` (unit duration).

    .. math:: d(q_0, q_1) = \\sqrt{v_0^T G(q_0) v_0}, \\quad v_0 = \\log_{q_0} q_1

    (the speed is constant along a geodesic). For the kinetic-energy metric the unit is
    sqrt(kg) m (sqrt(2 J s^2)). This is the length of the geodesic found, which is the
    minimal distance when that geodesic is minimizing.

    Args:
        metric: the metric.
        q0, q1: (n,) joint positions [rad].
        **log_kwargs: keyword arguments of `log_solve` (v_init, steps, tol, ...).
    """
    metric = _metric(metric)
    q0 = _vector(q0, "q0", metric.n)
    v0 = log(metric, q0, q1, **log_kwargs)  # type: ignore[arg-type]
    return float(math.sqrt(max(float(v0 @ metric.G(q0) @ v0), 0.0)))


# --------------------------------------------------------------------------------------
# Paths
# --------------------------------------------------------------------------------------
def path_energy(metric: Metric, t: np.ndarray, q: np.ndarray) -> float:
    """Energy of a sampled path, ``E = 1/2 integral qdot^T G(q) qdot dt``.

    ``qdot`` is the second-order finite difference of the samples (``np.gradient`` with
    the time stamps, second-order at the ends too) and the integral is Simpson's rule on
    the (possibly non-uniform) samples, so E converges to the energy of the underlying
    smooth path with error O(h^2) in the sample spacing h. For a geodesic of unit
    duration, ``E = 1/2 v0^T G(q0) v0``. Calls ``metric.G`` once per sample.

    Args:
        metric: the metric.
        t: (T,) strictly monotonic time stamps [s], T >= 2 (T >= 3 for second order).
        q: (T, n) joint positions [rad].

    Returns:
        The energy [J s for the kinetic-energy metric, i.e. (kg m^2)(rad/s)^2 s].
    """
    from scipy.integrate import simpson

    metric = _metric(metric)
    t, q = _path(t, q, metric.n)
    if t.shape[0] >= 3:
        qd = np.gradient(q, t, axis=0, edge_order=2)
    else:
        qd = np.repeat((q[1:] - q[:1]) / (t[1] - t[0]), 2, axis=0)
    integrand = np.array([qd[k] @ metric.G(q[k]) @ qd[k] for k in range(t.shape[0])])
    return float(0.5 * abs(simpson(integrand, x=t)))


def straight_line(q0: Vector, q1: Vector, duration: float = 1.0, steps: int = 100) -> Geodesic:
    """The Euclidean baseline: constant joint velocity from q0 to q1.

    Args:
        q0, q1: (n,) joint positions [rad].
        duration: time to go from q0 to q1 [s], > 0.
        steps: number of intervals, >= 1 (``steps + 1`` samples).

    Returns:
        t (T,), q (T, n) and the constant velocity v (T, n) = (q1 - q0) / duration.
    """
    q0 = _vector(q0, "q0")
    q1 = _vector(q1, "q1", q0.shape[0])
    duration = check_positive(duration, "duration")
    steps = _steps(steps)
    t = np.linspace(0.0, duration, steps + 1)
    s = (t / duration)[:, None]
    vel = (q1 - q0) / duration
    return Geodesic(t, q0 + s * (q1 - q0), np.repeat(vel[None, :], steps + 1, axis=0))


# --------------------------------------------------------------------------------------
# Parallel transport
# --------------------------------------------------------------------------------------
def _build_transport_A(metric: Metric) -> ca.Function:
    """A(q, qd) = -G(q)^-1 Gamma(qd, .) (n, n), the matrix of the transport ODE."""
    n = metric.n
    q = ca.SX.sym("q", n)
    qd = ca.SX.sym("qd", n)
    b = ca.SX.sym("b", n)
    p = metric.symbolic_parameters()
    Gq = metric.symbolic_G(q)
    # Gamma(a, b)_i = 1/2 (d(G a)/dq b + d(G b)/dq a - d(a^T G b)/dq)_i
    gam = 0.5 * (
        ca.jtimes(ca.mtimes(Gq, qd), q, b)
        + ca.jtimes(ca.mtimes(Gq, b), q, qd)
        - ca.gradient(ca.dot(qd, ca.mtimes(Gq, b)), q)
    )
    gam_mat = ca.jacobian(gam, b)  # linear in b: independent of b
    gam_mat = ca.substitute(gam_mat, b, ca.DM.zeros(n))
    A = -sx_cholesky_solve(Gq, gam_mat)
    fun = ca.Function(
        "geodesic_transport_A", [q, qd, p], [A], ["q", "qd", "p"], ["A"], {"cse": True}
    )
    return _compile(fun)


def _numeric_A(metric: Metric, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """A(q, qd) from central differences of the numeric G (metrics without symbolic form)."""
    n = metric.n
    h = 1e-6
    dG = np.empty((n, n, n))
    for k in range(n):
        e = np.zeros(n)
        e[k] = h
        dG[:, :, k] = (metric.G(q + e) - metric.G(q - e)) / (2.0 * h)
    gam = christoffel_from_dG(dG)  # [i, j, k]
    return -np.linalg.solve(metric.G(q), np.einsum("ijk,j->ik", gam, qd))


def _hermite(q0, d0, q1, d1, h, s):
    """Cubic Hermite position and derivative at fraction s of an interval of length h."""
    s2, s3 = s * s, s * s * s
    pos = (
        (2 * s3 - 3 * s2 + 1) * q0
        + (s3 - 2 * s2 + s) * h * d0
        + (-2 * s3 + 3 * s2) * q1
        + (s3 - s2) * h * d1
    )
    der = (
        (6 * s2 - 6 * s) / h * q0
        + (3 * s2 - 4 * s + 1) * d0
        + (-6 * s2 + 6 * s) / h * q1
        + (3 * s2 - 2 * s) * d1
    )
    return pos, der


def parallel_transport(
    metric: Metric,
    t: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    qdot: np.ndarray | None = None,
    substeps: int = 1,
) -> np.ndarray:
    """Parallel-transport tangent vector(s) from q[0] to q[-1] along a sampled curve.

    Solves the transport equation along the curve

    .. math:: G(q)\\,\\dot w + \\Gamma(\\dot q, w) = 0,

    which keeps ``<u, w>_G`` constant for any two transported vectors. The curve between
    samples is the cubic Hermite interpolant of (q, qdot) and the ODE is integrated with
    RK4 on that curve (``substeps`` RK4 steps per sample interval), so the transported
    vectors are exact for the interpolated curve up to the O(h^4) RK4 error; the
    interpolant itself deviates from the true curve by O(h^4) (O(h^2) when qdot comes
    from finite differences). The transport matrix ``A = -G^-1 Gamma(qdot, .)`` is
    evaluated in one batched compiled call; the propagation is a loop of n x n products.

    Args:
        metric: the metric.
        t: (T,) strictly monotonic time stamps [s], T >= 2 (reversed to transport back).
        q: (T, n) joint positions [rad].
        v: (n,) or (n, m) vector(s) at q[0] [rad/s].
        qdot: (T, n) joint velocities along the curve [rad/s], e.g. a geodesic's exact
            v; default the second-order finite difference of the samples.
        substeps: RK4 steps per sample interval, >= 1.

    Returns:
        The transported vector(s) at q[-1], with the shape of ``v``.
    """
    metric = _metric(metric)
    n = metric.n
    t, q = _path(t, q, n)
    substeps = _steps(substeps, "substeps")
    V = np.asarray(v, dtype=np.float64)
    if V.ndim not in (1, 2) or V.shape[0] != n or V.size == 0:
        raise InvalidArgument(f"v must have shape ({n},) or ({n}, m), got shape {V.shape}")
    if not np.all(np.isfinite(V)):
        raise InvalidArgument("v must be finite")
    if qdot is None:
        if t.shape[0] >= 3:
            qd = np.gradient(q, t, axis=0, edge_order=2)
        else:
            qd = np.repeat((q[1:] - q[:1]) / (t[1] - t[0]), 2, axis=0)
    else:
        qd = np.asarray(qdot, dtype=np.float64)
        if qd.shape != q.shape or not np.all(np.isfinite(qd)):
            raise InvalidArgument(
                f"qdot must be finite with shape {q.shape} (like q), got shape {qd.shape}"
            )
    # Evaluation points: for each RK4 (sub)step its start, midpoint and end; the end of
    # one is the start of the next, so 2 * K + 1 points for K substeps in total.
    K = (t.shape[0] - 1) * substeps
    fr = np.arange(2 * substeps) / (2 * substeps)  # fractions inside one interval
    h = np.diff(t)
    qa = np.repeat(q[:-1], 2 * substeps, axis=0)
    da = np.repeat(qd[:-1], 2 * substeps, axis=0)
    qb = np.repeat(q[1:], 2 * substeps, axis=0)
    db = np.repeat(qd[1:], 2 * substeps, axis=0)
    hh = np.repeat(h, 2 * substeps)[:, None]
    ss = np.tile(fr, t.shape[0] - 1)[:, None]
    pos, der = _hermite(qa, da, qb, db, hh, ss)
    pos = np.vstack([pos, q[-1:]])
    der = np.vstack([der, qd[-1:]])
    funcs = _functions(metric)
    if funcs.symbolic:
        if funcs.transport_A is None:
            funcs.transport_A = _build_transport_A(metric)
        npts = pos.shape[0]
        mapped = funcs.transport_map.get(npts)
        if mapped is None:
            mapped = funcs.transport_A.map(npts)
            funcs.transport_map[npts] = mapped
        # Output (n, n * npts): point p occupies columns p*n .. p*n + n - 1.
        params = np.tile(metric.parameter_values()[:, None], (1, npts))
        As = np.asarray(mapped(pos.T, der.T, params)).reshape(n, npts, n).transpose(1, 0, 2)
    else:
        As = np.array([_numeric_A(metric, pos[p], der[p]) for p in range(pos.shape[0])])
    hs = np.repeat(h / substeps, substeps)
    Phi = np.eye(n)
    for k in range(K):
        A0, Am, A1 = As[2 * k], As[2 * k + 1], As[2 * k + 2]
        dt = hs[k]
        k1 = A0 @ Phi
        k2 = Am @ (Phi + 0.5 * dt * k1)
        k3 = Am @ (Phi + 0.5 * dt * k2)
        k4 = A1 @ (Phi + dt * k3)
        Phi = Phi + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return Phi @ V
