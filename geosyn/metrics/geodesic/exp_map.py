"""The exponential map: the geodesic from an initial position and velocity.

A geodesic of the metric G(q) solves

.. math:: G(q)\\,\\ddot q + \\Gamma(\\dot q, \\dot q) = 0, \\qquad
    \\Gamma(a, b)_i = \\sum_{jk} \\Gamma_{ijk} a_j b_k

(Christoffel symbols of the first kind), i.e. ``qdd = metric.geodesic_acceleration(q, qd)``.

`exp` integrates it with a fixed-step RK4 whose whole loop runs in compiled code: one RK4
step of the state ``x = (q, v)`` is built as a CasADi SX function from
``metric.symbolic_geodesic_acceleration``, compiled to C with
`geosyn.core.codegen.compile_function` (cached on disk) and repeated with ``mapaccum``.
Metrics without a symbolic form fall back to a numpy RK4 loop. ``method="dop853"``
integrates with SciPy's DOP853 at rtol = atol = 1e-12 instead.

The step and its repetitions are kept in ``metric.functions`` (see
`geosyn.metrics.functions`), like every compiled function of a metric.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from geosyn.core.codegen import compile_function
from geosyn.core.types import Vector
from geosyn.core.validation import check_choice, check_int, check_positive, check_vector
from geosyn.metrics.base import Metric, check_metric
from geosyn.metrics.errors import GeodesicNotFound, NonFiniteResult, NoSymbolicForm
from geosyn.metrics.floating import FloatingKineticEnergyMetric
from geosyn.metrics.geodesic.group_rk4 import group_geodesic

__all__ = [
    "MAX_DOP853_EVALUATIONS",
    "MAX_STEPS",
    "METHODS",
    "Geodesic",
    "exp",
    "numpy_rk4",
    "rk4_map",
    "rk4_step",
    "step_input",
]

METHODS = ("rk4", "dop853", "adaptive")
"""Integration methods of `exp`."""
MAX_STEPS = 1_000_000
"""Largest number of integration steps of `exp` (the result holds steps + 1 samples)."""
_DOP853_TOL = 1e-12
MAX_DOP853_EVALUATIONS = 200_000
"""Most evaluations of the geodesic acceleration by one ``exp(..., method="dop853")``
(about 1.5 s at 7 us each): at rtol = 1e-12 DOP853 needs about 400 per radian travelled,
so |v0| * duration up to about 500 rad; beyond, `GeodesicNotFound` (|v0| = 1e5 once took
206 s, 1e8 never returned)."""


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


def step_input(metric: Metric, dt: float) -> np.ndarray:
    """(1 + p,) input ``theta`` of the RK4 step: the time step [s], then the parameters.

    Parameterised metrics (obstacle poses in a shaped metric) are read here, at call time,
    so moving an obstacle changes an input and rebuilds nothing.

    Args:
        metric: the metric.
        dt: time step [s].
    """
    return np.concatenate([[dt], metric.parameter_values()])


#: Largest geodesic acceleration [CasADi instructions] whose RK4 step calls it four times
#: instead of writing it out four times. The C is then ~3x shorter, compiles 4-5x faster
#: and gives the same bits (measured: Panda 3.2 -> 0.7 s, xArm7 3.9 -> 0.7 s, UR5 2.7 ->
#: 0.6 s at -O2). Above (the Panda with an obstacle term: 36,869 instructions) gcc takes
#: longer on the one long function than on the step written out (36 s against 17.5 s at
#: -O1), so that step stays written out.
STEP_CALL_MAX_INSTRUCTIONS = 20_000


def _build_step(metric: Metric) -> ca.Function:
    """One RK4 step of x = (q, v): (x (2n,), theta = [dt; p]) -> x', compiled to C.

    An acceleration of at most `STEP_CALL_MAX_INSTRUCTIONS` is generated once and called
    four times (an MX step); a longer one is written out in each stage (an SX step).
    """
    n = metric.n
    q = ca.SX.sym("q", n)
    v = ca.SX.sym("v", n)
    p = metric.symbolic_parameters()
    acc = ca.Function(
        "geodesic_acceleration", [q, v, p], [metric.symbolic_geodesic_acceleration(q, v)]
    )
    calls = acc.n_instructions() <= STEP_CALL_MAX_INSTRUCTIONS
    sym: Any = ca.MX if calls else ca.SX
    x = sym.sym("x", 2 * n)
    dt = sym.sym("dt")
    params = sym.sym("p", p.numel()) if calls else p
    theta = ca.vertcat(dt, params)

    def f(s: Any) -> Any:
        return ca.vertcat(s[n:], acc(s[:n], s[n:], params))

    k1 = f(x)
    k2 = f(x + 0.5 * dt * k1)
    k3 = f(x + 0.5 * dt * k2)
    k4 = f(x + dt * k3)
    x_next = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    step = ca.Function(
        "geodesic_rk4_step", [x, theta], [x_next], ["x", "theta"], ["x_next"], {"cse": True}
    )
    return compile_function(step, fallback=True)


def rk4_step(metric: Metric) -> ca.Function | None:
    """The compiled RK4 step ``(x (2n,), theta (1 + p,)) -> x'`` of ``metric``.

    Built (and compiled, cached on disk) on first use and kept in ``metric.functions``.

    Args:
        metric: the metric.

    Returns:
        The step, or None when the metric has no symbolic form.
    """
    try:
        return metric.functions.get("geodesic_rk4_step", lambda: _build_step(metric))
    except NoSymbolicForm:
        return None
    except ZeroDivisionError as err:  # constants folded while building: a singular G
        raise NonFiniteResult(
            f"exp: the geodesic acceleration of {metric!r} divides by zero (a singular"
            " metric, e.g. a joint that moves no mass)",
            "exp",
        ) from err


def rk4_map(metric: Metric, steps: int) -> ca.Function:
    """``(x0 (2n,), thetas (1 + p, steps)) -> states (2n, steps)``: ``steps`` RK4 steps.

    Built on first use (from `rk4_step`) and kept in ``metric.functions``.

    Args:
        metric: the metric.
        steps: number of steps, >= 1.

    Raises:
        NoSymbolicForm: the metric has no symbolic form.
    """
    step = rk4_step(metric)
    if step is None:
        raise NoSymbolicForm(f"{type(metric).__name__} has no symbolic form")
    return metric.functions.get(
        ("geodesic_rk4", steps), lambda: step.mapaccum("geodesic_rk4", steps)
    )


def numpy_rk4(metric: Metric, q0: Vector, v0: Vector, dt: float, steps: int) -> np.ndarray:
    """Fixed-step RK4 on ``metric.geodesic_acceleration`` in numpy (no symbolic form needed).

    Args:
        metric: the metric.
        q0: (n,) initial joint positions [rad].
        v0: (n,) initial joint velocities [rad/s].
        dt: time step [s].
        steps: number of steps.

    Returns:
        (steps + 1, 2n) states ``(q, v)``; NaN from the first non-finite state on.
    """
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


def _rk4_states(metric: Metric, q0: Vector, v0: Vector, duration: float, steps: int) -> np.ndarray:
    """(steps + 1, 2n) states of the fixed-step RK4 solution (compiled when possible)."""
    dt = duration / steps
    if rk4_step(metric) is None:
        return numpy_rk4(metric, q0, v0, dt, steps)
    fun = rk4_map(metric, steps)
    out = fun(np.concatenate([q0, v0]), np.tile(step_input(metric, dt)[:, None], (1, steps)))
    X = np.empty((steps + 1, 2 * metric.n))
    X[0, : metric.n], X[0, metric.n :] = q0, v0
    X[1:] = np.asarray(out).T
    return X


class _OverBudget(Exception):
    """Raised inside DOP853's right-hand side when the evaluation budget is spent."""


def _dop853_states(metric: Metric, q0: Vector, v0: Vector, t: np.ndarray) -> np.ndarray:
    """(T, 2n) states from SciPy's DOP853 sampled at ``t``, at most
    `MAX_DOP853_EVALUATIONS` evaluations of the geodesic acceleration."""
    from scipy.integrate import solve_ivp

    n = metric.n
    acc = metric.geodesic_acceleration
    calls = [0]

    def rhs(t_now: float, x: np.ndarray) -> np.ndarray:
        calls[0] += 1
        if calls[0] > MAX_DOP853_EVALUATIONS:
            raise _OverBudget
        if not np.isfinite(x).all():  # not the caller's q: the integration blew up
            when = f" at t={t_now:.6g} s" if np.isfinite(t_now) else ""
            raise NonFiniteResult(
                f"exp: the geodesic left the float64 range{when} with |v0| ="
                f" {np.linalg.norm(v0):.3g} rad/s; reduce |v0| or the duration",
                "exp",
            )
        return np.concatenate([x[n:], acc(x[:n], x[n:])])

    x0 = np.concatenate([q0, v0])
    try:
        sol = solve_ivp(
            rhs, (0.0, t[-1]), x0, method="DOP853", t_eval=t, rtol=_DOP853_TOL, atol=_DOP853_TOL
        )
    except _OverBudget:
        raise GeodesicNotFound(
            f"exp: DOP853 needed more than MAX_DOP853_EVALUATIONS = {MAX_DOP853_EVALUATIONS}"
            f" evaluations for |v0| = {np.linalg.norm(v0):.3g} rad/s over {t[-1]:.3g} s"
            " (about 400 per radian travelled); reduce |v0| or the duration, or use"
            " method='rk4' with more steps",
            residual=float("nan"),
            v0=v0,
        ) from None
    if not sol.success:
        raise GeodesicNotFound(f"exp: DOP853 failed: {sol.message}", residual=float("nan"), v0=v0)
    return np.asarray(sol.y.T)


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
        steps: number of intervals, in [1, `MAX_STEPS`]; the result has ``steps + 1``
            samples, uniformly spaced, t = 0 included.
        method: ``"rk4"`` (fixed step, compiled loop; global error O(dt^4)) or
            ``"dop853"`` / ``"adaptive"`` (SciPy DOP853 with rtol = atol = 1e-12 on
            ``metric.geodesic_acceleration``, sampled at the same times).

    Returns:
        The sampled geodesic; ``q[-1]`` is exp_q0(duration * v0).

    A floating-base metric (`geosyn.metrics.floating.FloatingKineticEnergyMetric`) takes
    ``q0`` (nq,) on SE(3) x R^n and ``v0`` (nv,); its geodesic is integrated on the group
    (`geosyn.metrics.geodesic.group_rk4`, ``method="rk4"`` only) and ``q`` is (T, nq).

    The first call for a metric builds (and compiles, cached on disk) the RK4 step;
    later calls allocate only the result.

    Raises:
        InvalidArgument: bad shapes, non-finite values, steps outside [1, MAX_STEPS],
            duration <= 0, or an unknown method.
        NonFiniteResult: the integration overflowed (e.g. a huge ``v0``).
        GeodesicNotFound: DOP853 failed, or needed more than `MAX_DOP853_EVALUATIONS`
            evaluations (a bounded call whatever |v0|).
    """
    # a floating base: configurations on SE(3) x R^n, integrated on the group
    floating = metric if isinstance(metric, FloatingKineticEnergyMetric) else None
    metric = check_metric(metric) if floating is None else floating
    n = metric.n
    q0 = check_vector(q0, n, "q0") if floating is None else floating.robot.check_q(q0, "q0")
    v0 = check_vector(v0, n, "v0")
    duration = check_positive(duration, "duration")
    steps = check_int(steps, "steps", low=1, high=MAX_STEPS)
    method = check_choice(method, METHODS, "method")
    t = np.linspace(0.0, duration, steps + 1)
    if floating is not None:
        return Geodesic(t, *group_geodesic(floating, q0, v0, duration, steps, method))
    if method == "rk4":
        X = _rk4_states(metric, q0, v0, duration, steps)
    else:
        X = _dop853_states(metric, q0, v0, t)
    if not np.isfinite(X).all():  # blew up (|v0| far beyond what the metric's scale allows)
        k = int(np.argmin(np.isfinite(X).all(axis=1)))
        raise NonFiniteResult(
            f"exp: the geodesic left the float64 range at t={t[k]:.6g} s (step {k} of"
            f" {steps}) with |v0| = {np.linalg.norm(v0):.3g} rad/s; reduce |v0| or"
            " duration, or increase steps",
            "exp",
        )
    return Geodesic(t, X[:, :n].copy(), X[:, n:].copy())
