"""Hermite interpolation of sampled trajectories: the one implementation geosyn uses.

Positions and velocities sampled at knots (and optionally accelerations) define a C1
cubic (or C2 quintic) Hermite interpolant. References, MPC plans and parallel transport
along sampled curves all evaluate their curves through these functions.
"""

from __future__ import annotations

import numpy as np


def hermite_point(
    q0: np.ndarray, d0: np.ndarray, q1: np.ndarray, d1: np.ndarray, h: float, s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Hermite value and time derivative at fraction ``s`` of one interval.

    Args:
        q0, q1: (..., n) values at the interval's ends (e.g. [rad]).
        d0, d1: (..., n) time derivatives at the ends (e.g. [rad/s]).
        h: interval length [s] (> 0).
        s: fraction of the interval in [0, 1] (also broadcastable array).

    Returns:
        (value, derivative): each (..., n); the derivative is with respect to time.
    """
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


def hermite_cubic_coefficients(t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Monomial coefficients of the C1 cubic Hermite interpolant through knots.

    Args:
        t: (T,) strictly increasing knot times [s].
        q: (T, n) values at the knots.
        v: (T, n) time derivatives at the knots.

    Returns:
        (T-1, 4, n) coefficients ``c`` with ``q(t) = sum_i c[k, i] (t - t_k)^i`` on
        ``[t_k, t_{k+1}]``.
    """
    h = np.diff(t)[:, None]
    dq = np.diff(q, axis=0)
    v0, v1 = v[:-1], v[1:]
    c2 = (3.0 * dq / h - 2.0 * v0 - v1) / h
    c3 = (-2.0 * dq / h + v0 + v1) / h**2
    return np.stack([q[:-1], v0, c2, c3], axis=1)


def hermite_quintic_coefficients(
    t: np.ndarray, q: np.ndarray, v: np.ndarray, a: np.ndarray
) -> np.ndarray:
    """Monomial coefficients of the C2 quintic Hermite interpolant through knots.

    Args:
        t: (T,) strictly increasing knot times [s].
        q: (T, n) values at the knots.
        v: (T, n) first time derivatives at the knots.
        a: (T, n) second time derivatives at the knots.

    Returns:
        (T-1, 6, n) coefficients, as in `hermite_cubic_coefficients`.
    """
    h = np.diff(t)
    q0, v0, a0 = q[:-1], v[:-1], a[:-1]
    c2 = 0.5 * a0
    # Remaining coefficients (c3, c4, c5) match position, velocity, acceleration at h.
    A = np.stack(
        [
            np.stack([h**3, h**4, h**5], axis=-1),
            np.stack([3 * h**2, 4 * h**3, 5 * h**4], axis=-1),
            np.stack([6 * h, 12 * h**2, 20 * h**3], axis=-1),
        ],
        axis=1,
    )  # (K, 3, 3)
    hh = h[:, None]
    rhs = np.stack(
        [q[1:] - (q0 + v0 * hh + c2 * hh**2), v[1:] - (v0 + 2 * c2 * hh), a[1:] - 2 * c2], axis=1
    )  # (K, 3, n)
    c345 = np.linalg.solve(A, rhs)
    return np.concatenate([np.stack([q0, v0, c2], axis=1), c345], axis=1)
