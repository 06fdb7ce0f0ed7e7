"""Parallel transport on a stance: the Levi-Civita connection of the induced metric.

On the floating base's group the velocity coordinates are a moving frame (base twist in
the base frame, joint rates), so the kinetic-energy connection has, besides the part
fixed by the geodesics, half the frame's bracket (torsion-free):

.. math:: \\nabla_v w = \\dot w + \\Gamma(v, w), \\qquad
    \\Gamma(v, w) = \\tfrac14 M^{-1} (c(v + w) - c(v - w)) + \\tfrac12 [v, w],

with ``c(q, v) = C(q, v) v`` (Pinocchio's RNEA without gravity) and ``[v, w]`` the se(3)
bracket of the base twists (zero on the joints). On a stance the induced connection is
the M-orthogonal projection of this one onto the tangent space (Gauss), so a vector
transported along a stance curve obeys

.. math:: \\dot w = -\\Gamma(v, w) + M^{-1} J^T \\mu, \\qquad
    \\mu = (J M^{-1} J^T)^{-1} (J \\Gamma(v, w) - \\dot J w),

which keeps ``J w = 0``. `transport_along_geodesic` integrates it together with the
stance's geodesic (RKMK4, returned to the stance each step; ``w`` re-projected onto the
tangent space against the drift).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin
import scipy.linalg

from geosyn.core.types import Vector
from geosyn.core.validation import check_int, check_positive, check_vector
from geosyn.metrics.errors import StanceError
from geosyn.metrics.geodesic.exp_map import MAX_STEPS
from geosyn.metrics.geodesic.group_rk4 import dexpinv
from geosyn.metrics.stance import Stance

__all__ = ["TransportedGeodesic", "connection", "transport_along_geodesic"]


class TransportedGeodesic(NamedTuple):
    """A stance geodesic and vectors transported along it."""

    t: np.ndarray  # (T,) time stamps [s]
    q: np.ndarray  # (T, nq) configurations
    v: np.ndarray  # (T, nv) velocities
    w: np.ndarray  # (T, m, nv) the transported vectors


def connection(stance: Stance, q: Vector, v: Vector, w: Vector) -> Vector:
    """(nv,) ``Gamma(v, w)`` of the floating base's kinetic-energy connection at ``q``.

    Args:
        stance: the stance whose (ambient) metric is used.
        q: (nq,) configuration.
        v: (nv,) velocity of the curve.
        w: (nv,) the vector transported.
    """
    metric = stance.metric
    c = metric.coriolis(q, v + w) - metric.coriolis(q, v - w)
    out = np.linalg.solve(metric.G(q), 0.25 * c)
    out[:6] += 0.5 * pin.Motion(v[:6]).cross(pin.Motion(w[:6])).vector
    return np.asarray(out)


def _rates(stance: Stance, q: Vector, v: Vector, W: np.ndarray) -> tuple[Vector, np.ndarray]:
    """(stance acceleration, dW/dt) at (q, v, W)."""
    M = stance.metric.G(q)
    J = stance.jacobian(q)
    dJ = stance.jacobian_time_variation(q, v)
    L = scipy.linalg.cho_factor(M)
    MiJt = scipy.linalg.cho_solve(L, J.T)
    S = J @ MiJt
    out = np.empty_like(W)
    for i, w in enumerate(W):
        g = connection(stance, q, v, w)
        out[i] = -g + MiJt @ np.linalg.solve(S, J @ g - dJ @ w)
    return stance.acceleration(q, v), out


def _tangent(stance: Stance, q: Vector, W: np.ndarray) -> np.ndarray:
    M, J = stance.metric.G(q), stance.jacobian(q)
    MiJt = np.linalg.solve(M, J.T)
    return np.asarray(W - (MiJt @ np.linalg.solve(J @ MiJt, J @ W.T)).T)


def transport_along_geodesic(
    stance: Stance,
    q0: Vector,
    v0: Vector,
    w0: np.ndarray,
    duration: float = 1.0,
    steps: int = 100,
) -> TransportedGeodesic:
    """Parallel transport of tangent vectors along the stance geodesic from ``(q0, v0)``.

    Args:
        stance: the stance.
        q0: (nq,) start on the stance.
        v0: (nv,) tangent initial velocity.
        w0: (nv,) or (m, nv) tangent vectors at ``q0`` (``J w0 = 0`` to 1e-9).
        duration: time [s], > 0.
        steps: RKMK4 steps, in [1, `MAX_STEPS`].

    Returns:
        The geodesic and the transported vectors; inner products ``w_i^T M w_j`` are
        conserved (to the integration error).

    Raises:
        StanceError: ``q0`` off the stance, ``v0`` or a ``w0`` not tangent.
    """
    robot = stance.robot
    q0 = robot.check_q(q0, "q0")
    v0 = check_vector(v0, robot.nv, "v0")
    W = np.atleast_2d(np.asarray(w0, dtype=np.float64))
    if W.ndim != 2 or W.shape[1] != robot.nv or not np.isfinite(W).all():
        raise StanceError(f"w0 must be finite of shape (nv,) or (m, nv), nv = {robot.nv}")
    duration = check_positive(duration, "duration", "s")
    steps = check_int(steps, "steps", low=1, high=MAX_STEPS)
    J = stance.jacobian(q0)
    off = float(np.abs(stance.residual(q0)).max())
    moving = float(np.abs(J @ np.vstack([v0, W]).T).max())
    if off > 1e-9 or moving > 1e-9:
        raise StanceError(
            f"q0 must be on {stance!r} and v0, w0 tangent to it: pose error {off:.3g},"
            f" held-frame velocity {moving:.3g} (each <= 1e-9); Stance.project makes them"
        )
    dt = duration / steps
    model = robot.model
    Q = np.empty((steps + 1, robot.nq))
    V = np.empty((steps + 1, robot.nv))
    Ws = np.empty((steps + 1, *W.shape))
    q, v = q0.copy(), v0.copy()
    Q[0], V[0], Ws[0] = q, v, W
    for k in range(steps):
        k1v, k1w = _rates(stance, q, v, W)
        k1x = v
        x2, v2, w2 = 0.5 * dt * k1x, v + 0.5 * dt * k1v, W + 0.5 * dt * k1w
        k2v, k2w = _rates(stance, pin.integrate(model, q, x2), v2, w2)
        k2x = dexpinv(x2, v2)
        x3, v3, w3 = 0.5 * dt * k2x, v + 0.5 * dt * k2v, W + 0.5 * dt * k2w
        k3v, k3w = _rates(stance, pin.integrate(model, q, x3), v3, w3)
        k3x = dexpinv(x3, v3)
        x4, v4, w4 = dt * k3x, v + dt * k3v, W + dt * k3w
        k4v, k4w = _rates(stance, pin.integrate(model, q, x4), v4, w4)
        k4x = dexpinv(x4, v4)
        q = pin.integrate(model, q, dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x))
        v = v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        W = W + dt / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
        q, v = stance.project(q, v)
        W = _tangent(stance, q, W)
        Q[k + 1], V[k + 1], Ws[k + 1] = q, v, W
    return TransportedGeodesic(np.linspace(0.0, duration, steps + 1), Q, V, Ws)
