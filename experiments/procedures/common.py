"""Numerical helpers shared by the geometric procedures."""

from __future__ import annotations

import numpy as np

from geosyn.metrics import Metric


def fd_derivatives(t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity and acceleration of uniformly sampled positions, 4th-order central differences.

    Args:
        t: (T,) uniform time stamps [s], T >= 5.
        q: (T, n) positions [rad].

    Returns:
        (interior indices (T-4,), qd (T-4, n) [rad/s], qdd (T-4, n) [rad/s^2]); the
        truncation error is O(h^4) in the sample spacing h.
    """
    h = float(t[1] - t[0])
    qm2, qm1, q0, qp1, qp2 = q[:-4], q[1:-3], q[2:-2], q[3:-1], q[4:]
    qd = (-qp2 + 8.0 * qp1 - 8.0 * qm1 + qm2) / (12.0 * h)
    qdd = (-qp2 + 16.0 * qp1 - 30.0 * q0 + 16.0 * qm1 - qm2) / (12.0 * h * h)
    return np.arange(2, len(t) - 2), qd, qdd


def geodesic_residual(metric: Metric, t: np.ndarray, q: np.ndarray) -> float:
    """Largest violation of the geodesic equation along a sampled path.

    .. math:: r = \\max_k \\| G(q_k) \\ddot q_k + C(q_k, \\dot q_k) \\dot q_k \\|_2

    with ``qd``, ``qdd`` from 4th-order finite differences of the positions only (so a
    path is judged by its shape, not by the velocities an integrator reports). For the
    kinetic-energy metric ``r`` is a torque [N m]: the force needed, gravity aside, to
    keep the robot on the path. Along an RK4 geodesic with h = 1/400 s, r ~ 1e-8.
    """
    idx, qd, qdd = fd_derivatives(t, q)
    r = 0.0
    for i, k in enumerate(idx):
        res = metric.G(q[k]) @ qdd[i] + metric.coriolis(q[k], qd[i])
        r = max(r, float(np.linalg.norm(res)))
    return r
