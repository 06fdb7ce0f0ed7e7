"""Parallel transport of tangent vectors along a sampled curve.

Solves the transport equation

.. math:: G(q)\\,\\dot w + \\Gamma(\\dot q, w) = 0,

which keeps ``<u, w>_G`` constant for any two transported vectors, on the cubic Hermite
interpolant of the samples (`geosyn.core.interpolation.hermite_point`).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from geosyn.core.codegen import compile_function
from geosyn.core.errors import InvalidArgument
from geosyn.core.interpolation import hermite_point
from geosyn.core.validation import check_int, check_real_array
from geosyn.metrics.base import Metric, check_metric
from geosyn.metrics.derived import (
    christoffel_from_dG,
    sx_cholesky_solve,
    sx_christoffel_contraction,
)
from geosyn.metrics.errors import NoSymbolicForm
from geosyn.metrics.geodesic.energy import check_path, path_velocity, real_array
from geosyn.metrics.geodesic.exp_map import MAX_STEPS

__all__ = ["parallel_transport"]


def _build_transport_A(metric: Metric) -> ca.Function:
    """A(q, qd) = -G(q)^-1 Gamma(qd, .) (n, n), the matrix of the transport ODE."""
    n = metric.n
    q = ca.SX.sym("q", n)
    qd = ca.SX.sym("qd", n)
    b = ca.SX.sym("b", n)
    p = metric.symbolic_parameters()
    Gq = metric.symbolic_G(q)
    gam = sx_christoffel_contraction(Gq, q, qd, b)
    gam_mat = ca.jacobian(gam, b)  # linear in b: independent of b
    gam_mat = ca.substitute(gam_mat, b, ca.DM.zeros(n))
    A = -sx_cholesky_solve(Gq, gam_mat)
    fun = ca.Function(
        "geodesic_transport_A", [q, qd, p], [A], ["q", "qd", "p"], ["A"], {"cse": True}
    )
    return compile_function(fun, fallback=True)


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


def _transport_matrices(metric: Metric, pos: np.ndarray, der: np.ndarray) -> np.ndarray:
    """(P, n, n) transport matrices A at P points (one batched compiled call if possible)."""
    try:
        fun = metric.functions.get("geodesic_transport_A", lambda: _build_transport_A(metric))
    except NoSymbolicForm:
        return np.array([_numeric_A(metric, pos[k], der[k]) for k in range(pos.shape[0])])
    n, npts = metric.n, pos.shape[0]
    mapped = metric.functions.get(("geodesic_transport_A", npts), lambda: fun.map(npts))
    # Output (n, n * npts): point k occupies columns k*n .. k*n + n - 1.
    params = np.tile(metric.parameter_values()[:, None], (1, npts))
    return np.asarray(mapped(pos.T, der.T, params)).reshape(n, npts, n).transpose(1, 0, 2)


def _check_velocity_matches(t: np.ndarray, q: np.ndarray, qd: np.ndarray) -> None:
    """Refuse ``qd`` that is not dq/dt of the samples (a reversed time axis flips it).

    The trapezoid rule ``h (qd_k + qd_k+1) / 2`` predicts each step ``q_k+1 - q_k`` to
    O(h^3); a mismatch above half the path's length is not rounding but a velocity of the
    other direction (or of another curve). O(T n).
    """
    dq = np.diff(q, axis=0)
    predicted = np.diff(t)[:, None] * 0.5 * (qd[:-1] + qd[1:])
    length = float(np.sum(np.linalg.norm(dq, axis=1)))
    mismatch = float(np.sum(np.linalg.norm(dq - predicted, axis=1)))
    if length > 0.0 and mismatch > 0.5 * length:
        raise InvalidArgument(
            f"qdot is not the derivative of q along t: integrating it over t misses the"
            f" samples by {mismatch:.3g} rad on a path of {length:.3g} rad (a reversed"
            " time axis? to transport back, reverse t, q and qdot together)"
        )


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

    Raises:
        InvalidArgument: bad shapes, non-finite, complex or boolean values, substeps < 1,
            or ``qdot`` that is not the derivative of ``q`` along ``t`` (e.g. a reversed
            time axis with the samples in their original order).
    """
    metric = check_metric(metric)
    n = metric.n
    for value, name in ((t, "t"), (q, "q"), (v, "v"), (qdot, "qdot")):
        if value is not None:
            check_real_array(value, name)  # booleans and complex refused, not cast
    t, q = check_path(t, q, n)
    substeps = check_int(substeps, "substeps", low=1)
    if (t.shape[0] - 1) * substeps > MAX_STEPS:  # the evaluation points are allocated at once
        raise InvalidArgument(
            f"substeps={substeps} over {t.shape[0] - 1} intervals is more than MAX_STEPS ="
            f" {MAX_STEPS} RK4 steps; use fewer substeps or samples"
        )
    V = real_array(v, "v")
    if V.ndim not in (1, 2) or V.shape[0] != n or V.size == 0:
        raise InvalidArgument(f"v must have shape ({n},) or ({n}, m), got shape {V.shape}")
    if not np.all(np.isfinite(V)):
        raise InvalidArgument("v must be finite")
    if qdot is None:
        qd = path_velocity(t, q)
    else:
        qd = real_array(qdot, "qdot")
        if qd.shape != q.shape or not np.all(np.isfinite(qd)):
            raise InvalidArgument(
                f"qdot must be finite with shape {q.shape} (like q), got shape {qd.shape}"
            )
        _check_velocity_matches(t, q, qd)
    # Evaluation points: for each RK4 (sub)step its start, midpoint and end; the end of
    # one is the start of the next, so 2 * K + 1 points for K substeps in total.
    K = (t.shape[0] - 1) * substeps
    fr = np.arange(2 * substeps) / (2 * substeps)  # fractions inside one interval
    h = np.diff(t)
    pos, der = hermite_point(
        np.repeat(q[:-1], 2 * substeps, axis=0),
        np.repeat(qd[:-1], 2 * substeps, axis=0),
        np.repeat(q[1:], 2 * substeps, axis=0),
        np.repeat(qd[1:], 2 * substeps, axis=0),
        np.repeat(h, 2 * substeps)[:, None],  # type: ignore[arg-type]
        np.tile(fr, t.shape[0] - 1)[:, None],  # type: ignore[arg-type]
    )
    As = _transport_matrices(metric, np.vstack([pos, q[-1:]]), np.vstack([der, qd[-1:]]))
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
