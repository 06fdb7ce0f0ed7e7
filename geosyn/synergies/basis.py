"""Metric-orthonormal synergy bases at a configuration.

``n`` geodesic synergies whose initial velocities are G-orthonormal span every initial
velocity, hence (through exp) every geodesic from ``q0`` (paper section 2.2).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg

from geosyn.core.types import Matrix, Vector
from geosyn.metrics.base import Metric
from geosyn.robots.kinematics import frame_position_jacobian
from geosyn.robots.robot import Robot
from geosyn.synergies.errors import InvalidSynergyInput
from geosyn.synergies.synergy import (
    GeodesicSynergy,
    as_vector,
    check_count,
    check_metric,
    check_robot,
)

DEPENDENCE_TOL = 1e-10
"""A direction whose G-norm drops below this fraction of its own G-norm after removing
its components along the previous ones is declared linearly dependent."""

NULL_TOL = 1e-10
"""Generalized eigenvalues below this fraction of the largest count as null directions."""


class SynergyBasis(NamedTuple):
    """G-orthonormal synergies at one configuration.

    Attributes:
        V: (n, k) initial velocities [rad/s] with ``V.T @ G(q0) @ V = I``.
        synergies: the k synergies ``GeodesicSynergy(metric, q0, V[:, i])``.
        scores: (k,) ordering criterion of each column: ``|J v_i|^2`` [m^2/s^2], the
            squared end-effector speed per unit G-norm (when a robot is known), else
            ``|v_i|^2`` [rad^2/s^2], the squared joint speed per unit G-norm.
    """

    V: Matrix
    synergies: list[GeodesicSynergy]
    scores: Vector


def g_orthonormalize(G: Matrix, D: Matrix) -> Matrix:
    """Gram-Schmidt (done twice per column for stability) under the inner product G.

    Args:
        G: (n, n) SPD matrix.
        D: (n, m) directions, orthonormalized in column order.

    Returns:
        (n, m) columns ``u_i`` with ``U.T @ G @ U = I`` and
        ``span(u_1..u_j) = span(d_1..d_j)`` for every j, ``<u_j, d_j>_G > 0``.

    Raises:
        InvalidSynergyInput: a column lies (to `DEPENDENCE_TOL`) in the span of the
            previous ones (or is zero); its ``index`` is that column.
    """
    n, m = D.shape
    U = np.zeros((n, m))
    for j in range(m):
        d = D[:, j].astype(np.float64)
        norm0 = np.sqrt(max(float(d @ G @ d), 0.0))
        u = d.copy()
        for _ in range(2):
            u = u - U[:, :j] @ (U[:, :j].T @ (G @ u))
        norm = np.sqrt(max(float(u @ G @ u), 0.0))
        if norm0 == 0.0 or norm <= DEPENDENCE_TOL * norm0:
            raise InvalidSynergyInput(
                f"directions[:, {j}] = {np.round(d, 6).tolist()} is linearly dependent on "
                f"directions[:, :{j}] under G (relative residual {norm / max(norm0, 1e-300):.2e}"
                f" <= {DEPENDENCE_TOL:g}); directions must be linearly independent",
                "directions",
                index=j,
            )
        U[:, j] = u / norm
    return U


def _fix_signs(V: Matrix) -> Matrix:
    """Make the largest-magnitude entry of each column positive (deterministic signs)."""
    V = V.copy()
    for j in range(V.shape[1]):
        i = int(np.argmax(np.abs(V[:, j])))
        if V[i, j] < 0:
            V[:, j] = -V[:, j]
    return V


def orthonormal_synergies(
    metric: Metric,
    q0: Vector,
    k: int,
    directions: Matrix | None = None,
    frame: str | None = None,
    robot: Robot | None = None,
) -> SynergyBasis:
    """k synergies at ``q0`` with G(q0)-orthonormal initial velocities.

    Without ``directions`` the columns are ordered by end-effector displacement per unit
    energy: the generalized eigenproblem

    .. math:: J^\\top J\\, u = \\lambda\\, G(q_0)\\, u, \\qquad u^\\top G u = 1

    with J the (3, n) position Jacobian of ``frame`` at ``q0``, sorted by decreasing
    :math:`\\lambda = |J u|^2 / u^\\top G u`. The remaining (null) directions, which do
    not move the frame to first order, are ordered within their span by decreasing joint
    speed per unit energy (eigenvectors of :math:`N^\\top N` for a G-orthonormal basis N
    of that span). Without a robot (a metric that has none and ``robot=None``) all
    columns use that joint-speed criterion (``eigh(I, G)``). Each column's sign makes its
    largest-magnitude entry positive.

    With ``directions`` the first k columns are G-orthonormalized in order (Gram-Schmidt).

    Args:
        metric: the metric.
        q0: (n,) base configuration [rad].
        k: number of synergies, 1 <= k <= n.
        directions: optional (n, m) directions, m >= k, [rad/s].
        frame: end-effector frame name; defaults to ``robot.ee_frame``.
        robot: the robot for the Jacobian; defaults to ``metric.robot`` if present.

    Returns:
        The basis, its synergies and their scores (see `SynergyBasis`).

    Raises:
        InvalidSynergyInput: k out of range, q0 or directions of the wrong shape,
            dependent directions (``index`` names the column), or a robot whose nv is
            not the metric's n.
        UnknownFrame: ``frame`` is not in the robot.
    """
    check_metric(metric)
    n = metric.n
    q = as_vector(q0, n, "q0")
    k = check_count(k, n)
    if robot is None:
        robot = getattr(metric, "robot", None)
    if robot is not None:
        check_robot(robot, n)
    G = np.asarray(metric.G(q), dtype=np.float64)
    J = None
    if robot is not None:
        J = frame_position_jacobian(robot, q, frame if frame is not None else robot.ee_frame)

    if directions is not None:
        D = np.array(directions, dtype=np.float64)
        if D.ndim == 1:
            D = D[:, None]
        if D.ndim != 2 or D.shape[0] != n or D.shape[1] < k:
            raise InvalidSynergyInput(
                f"directions must have shape ({n}, m) with m >= k = {k}, got {D.shape}",
                "directions",
            )
        if not np.all(np.isfinite(D)):
            raise InvalidSynergyInput("directions must be finite", "directions")
        V = g_orthonormalize(G, D[:, :k])
    else:
        V = _ordered_basis(G, J)[:, :k]

    scores = np.sum((J @ V) ** 2, axis=0) if J is not None else np.sum(V**2, axis=0)
    synergies = [GeodesicSynergy(metric, q, V[:, i]) for i in range(k)]
    return SynergyBasis(V, synergies, scores)


def _ordered_basis(G: Matrix, J: Matrix | None) -> Matrix:
    """Full (n, n) G-orthonormal basis in the order described in `orthonormal_synergies`."""
    n = G.shape[0]
    if J is None:
        lam, U = scipy.linalg.eigh(np.eye(n), G)
        return _fix_signs(U[:, np.argsort(-lam, kind="stable")])
    lam, U = scipy.linalg.eigh(J.T @ J, G)
    order = np.argsort(-lam, kind="stable")
    lam, U = lam[order], U[:, order]
    lmax = max(lam[0], 0.0)
    r = int(np.sum(lam > NULL_TOL * lmax)) if lmax > 0 else 0
    N = U[:, r:]
    if N.shape[1] > 1:
        # Any rotation W of a G-orthonormal N keeps it G-orthonormal; pick the one
        # ordering the null span by joint speed, which is unique (unlike eigh's choice).
        mu, W = np.linalg.eigh(N.T @ N)
        N = N @ W[:, np.argsort(-mu, kind="stable")]
    return _fix_signs(np.hstack([U[:, :r], N]))
