"""Geodesics on a floating base's group SE(3) x R^n: Runge-Kutta-Munthe-Kaas of order 4.

The state is ``(q, v)``: ``q`` on the group (nq), ``v`` the velocity coordinates (nv,
base twist in the base frame, joint rates), with

.. math:: q^{-1}\\dot q = v, \\qquad \\dot v = a(q, v) = -M(q)^{-1} C(q, v) v.

Each step writes the configuration in the exponential chart at the step's start,
``q = q_k exp(xi)``, where ``dxi/dt = dexp^{-1}_{-xi}(v)`` with, on the se(3) block,

.. math:: \\mathrm{dexp}^{-1}_{-\\xi}(v) = v + \\tfrac12 [\\xi, v]
    + \\tfrac1{12} [\\xi, [\\xi, v]] + O(|\\xi|^4 |v|)

(the joints' block is the identity), takes one classical RK4 step of ``(xi, v)`` from
``(0, v_k)`` and returns to the group with ``q_{k+1} = q_k exp(xi)``
(``pinocchio.integrate``). The series truncation keeps the method of order 4 (global
error O(dt^4)); every configuration stays on the group (unit quaternion) to round-off.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.metrics.errors import NonFiniteResult
from geosyn.metrics.floating import FloatingKineticEnergyMetric

__all__ = ["dexpinv", "group_geodesic", "group_rk4"]


def _ad(xi: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(6,) se(3) bracket ``[xi, w]`` of twists with the linear part first."""
    return np.asarray(pin.Motion(xi).cross(pin.Motion(w)).vector)


def dexpinv(xi: Vector, v: Vector) -> Vector:
    """``dxi/dt`` of ``q = q_k exp(xi)`` moving with velocity ``v`` (series to 2nd order).

    Args:
        xi: (nv,) chart coordinates (base twist first, joints after).
        v: (nv,) velocity (base twist in the base frame, joint rates).

    Returns:
        (nv,) chart velocity; equal to ``v`` on the joints.
    """
    out = np.array(v, dtype=np.float64)
    b1 = _ad(xi[:6], v[:6])
    out[:6] += 0.5 * b1 + _ad(xi[:6], b1) / 12.0
    return out


def group_rk4(
    metric: FloatingKineticEnergyMetric,
    q0: Vector,
    v0: Vector,
    dt: float,
    steps: int,
    acceleration: Callable[[Vector, Vector], Vector] | None = None,
    project: Callable[[Vector, Vector], tuple[Vector, Vector]] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` RKMK4 steps of the geodesic from ``(q0, v0)`` (see the module docstring).

    Args:
        metric: the floating-base metric.
        q0: (nq,) initial configuration (checked by the caller).
        v0: (nv,) initial velocity.
        dt: time step [s].
        steps: number of steps.
        acceleration: ``(q, v) -> (nv,)`` the velocity coordinates' time derivative;
            None: the metric's geodesic acceleration (a stance passes its constrained one).
        project: ``(q, v) -> (q, v)`` applied after each step (a stance's return to its
            submanifold); None: nothing.

    Returns:
        ``(Q, V)``: (steps + 1, nq) configurations and (steps + 1, nv) velocities; NaN
        from the first non-finite state on.
    """
    acc, integrate = metric.unchecked()
    if acceleration is not None:
        acc = acceleration
    Q = np.empty((steps + 1, metric.nq))
    V = np.empty((steps + 1, metric.n))
    Q[0], V[0] = q0, v0
    q, v = Q[0].copy(), V[0].copy()
    half = 0.5 * dt
    for k in range(steps):
        if not math.isfinite(v.dot(v)):  # an overflow: stop here
            Q[k:], V[k:] = np.nan, np.nan
            break
        k1x, k1v = v, acc(q, v).copy()
        x2, v2 = half * k1x, v + half * k1v
        k2x, k2v = dexpinv(x2, v2), acc(integrate(q, x2), v2).copy()
        x3, v3 = half * k2x, v + half * k2v
        k3x, k3v = dexpinv(x3, v3), acc(integrate(q, x3), v3).copy()
        x4, v4 = dt * k3x, v + dt * k3v
        k4x, k4v = dexpinv(x4, v4), acc(integrate(q, x4), v4)
        v = v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        q = integrate(q, dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x))
        if project is not None and math.isfinite(v.dot(v)):
            q, v = project(q, v)
        Q[k + 1], V[k + 1] = q, v
    if not math.isfinite(V[-1].dot(V[-1])):
        Q[-1], V[-1] = np.nan, np.nan
    return Q, V


def group_geodesic(
    metric: FloatingKineticEnergyMetric,
    q0: Vector,
    v0: Vector,
    duration: float,
    steps: int,
    method: str = "rk4",
) -> tuple[np.ndarray, np.ndarray]:
    """The samples of `geosyn.metrics.geodesic.exp` on a floating base (checked inputs).

    Args:
        metric: the floating-base metric.
        q0: (nq,) initial configuration.
        v0: (nv,) initial velocity.
        duration: integration time [s].
        steps: number of RK4 steps.
        method: ``"rk4"``; the coordinate integrators (DOP853) are refused.

    Returns:
        ``(Q, V)`` as in `group_rk4`.

    Raises:
        InvalidArgument: another method.
        NonFiniteResult: the integration overflowed.
    """
    if method != "rk4":
        raise InvalidArgument(
            f"method {method!r} integrates in coordinates; a floating base's geodesics are"
            " integrated on SE(3) x R^n by method='rk4' (Runge-Kutta-Munthe-Kaas) only"
        )
    Q, V = group_rk4(metric, q0, v0, duration / steps, steps)
    if not np.isfinite(V[-1]).all():
        k = int(np.argmin(np.isfinite(V).all(axis=1)))
        raise NonFiniteResult(
            f"exp: the floating-base geodesic left the float64 range at step {k} of {steps}"
            f" with |v0| = {np.linalg.norm(v0):.3g}; reduce |v0| or duration, or increase"
            " steps",
            "exp",
        )
    return Q, V
