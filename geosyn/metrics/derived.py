"""Quantities derived from a metric's tensor G(q): the one place they are computed.

Symbolic (CasADi SX) forms, from an expression of G:

- `sx_metric_derivatives`: dG/dq and the Christoffel symbols of the first kind;
- `sx_coriolis`: the Coriolis and centrifugal term ``c(q, v) = C(q, v) v = Gamma(v, v)``;
- `sx_christoffel_contraction`: ``Gamma(a, b)``, the operator of parallel transport;
- `sx_cholesky_solve`: ``G^-1 b`` without a symbolic inverse.

Numeric: `christoffel_from_dG`, the same Christoffel formula on arrays (for metrics known
only numerically, and for tests against finite differences).

.. math::
    \\Gamma_{ijk} = \\tfrac12 (\\partial_k g_{ij} + \\partial_j g_{ik} - \\partial_i g_{jk}),
    \\qquad \\Gamma(a, b)_i = \\sum_{jk} \\Gamma_{ijk} a_j b_k
"""

from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = [
    "christoffel_from_dG",
    "sx_cholesky_solve",
    "sx_christoffel_contraction",
    "sx_coriolis",
    "sx_metric_derivatives",
]


def sx_cholesky_solve(A: ca.SX, b: ca.SX) -> ca.SX:
    """Solve ``A x = b`` for symmetric positive-definite SX ``A`` by an unrolled Cholesky.

    Keeps the graph O(n^3 / 6) instead of the much larger symbolic inverse.

    Args:
        A: (n, n) SPD matrix expression.
        b: (n, m) right-hand side.

    Returns:
        (n, m) solution expression.
    """
    n = A.shape[0]
    L = [[ca.SX(0.0) for _ in range(n)] for _ in range(n)]
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s = s - L[j][k] * L[j][k]
        L[j][j] = ca.sqrt(s)
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / L[j][j]
    cols = []
    for c in range(b.shape[1]):
        y = [ca.SX(0.0)] * n
        for i in range(n):
            s = b[i, c]
            for k in range(i):
                s = s - L[i][k] * y[k]
            y[i] = s / L[i][i]
        x = [ca.SX(0.0)] * n
        for i in reversed(range(n)):
            s = y[i]
            for k in range(i + 1, n):
                s = s - L[k][i] * x[k]
            x[i] = s / L[i][i]
        cols.append(ca.vertcat(*x))
    return ca.horzcat(*cols)


def christoffel_from_dG(dG: np.ndarray) -> np.ndarray:
    """Christoffel symbols of the first kind from metric derivatives.

    .. math:: \\Gamma_{ijk} = \\tfrac12 (\\partial_k g_{ij} + \\partial_j g_{ik} - \\partial_i g_{jk})

    Args:
        dG: (n, n, n) with ``dG[i, j, k] = d g_ij / d q_k``.

    Returns:
        (n, n, n) ``Gamma[i, j, k]``, symmetric in (j, k).
    """
    return 0.5 * (dG + dG.transpose(0, 2, 1) - dG.transpose(2, 0, 1))


def sx_metric_derivatives(G: ca.SX, q: ca.SX) -> tuple[ca.SX, ca.SX]:
    """dG/dq and the Christoffel symbols of the first kind, as flat SX matrices.

    Args:
        G: (n, n) SX expression of the metric in ``q``.
        q: (n, 1) SX symbol.

    Returns:
        ``(dG, Gamma)``, both (n, n*n): ``dG[i, j*n + k] = d g_ij / d q_k`` and
        ``Gamma[i, j*n + k] = Gamma_ijk`` (reshape a numeric value to (n, n, n)).
    """
    n = q.shape[0]
    d = ca.jacobian(ca.vec(G), q)  # (n*n, n), row i + j*n (column-major vec)
    dG = ca.vertcat(*[ca.horzcat(*[d[i + j * n, :] for j in range(n)]) for i in range(n)])
    rows = []
    for i in range(n):
        row = []
        for j in range(n):
            for k in range(n):
                row.append(0.5 * (d[i + j * n, k] + d[i + k * n, j] - d[j + k * n, i]))
        rows.append(ca.horzcat(*row))
    return dG, ca.vertcat(*rows)


def sx_coriolis(G: ca.SX, q: ca.SX, v: ca.SX, *, plus: ca.SX | None = None) -> ca.SX:
    """The Coriolis and centrifugal term ``c(q, v) = Gamma(v, v)``, without the tensor.

    .. math:: c = \\partial_q(G v)\\, v - \\tfrac12 \\nabla_q (v^T G v)

    Args:
        G: (n, n) SX expression of the metric in ``q``.
        q: (n, 1) SX symbol.
        v: (n, 1) SX velocity.
        plus: (n, 1) SX term to add ``c`` to (e.g. a base metric's Coriolis term, when
            ``G`` holds only the terms added to that metric); None adds nothing.

    Returns:
        (n, 1) SX expression [N m for the kinetic-energy metric].
    """
    Gv = ca.mtimes(G, v)
    jt = ca.jtimes(Gv, q, v)
    if plus is not None:
        jt = plus + jt
    return jt - 0.5 * ca.gradient(ca.dot(v, Gv), q)


def sx_christoffel_contraction(G: ca.SX, q: ca.SX, a: ca.SX, b: ca.SX) -> ca.SX:
    """``Gamma(a, b)_i = sum_jk Gamma_ijk a_j b_k`` without forming the (n, n, n) tensor.

    .. math::
        \\Gamma(a, b) = \\tfrac12 \\big(\\partial_q(G a)\\, b + \\partial_q(G b)\\, a
        - \\nabla_q (a^T G b)\\big)

    `sx_coriolis` is the case ``a = b``, by a shorter formula.

    Args:
        G: (n, n) SX expression of the metric in ``q``.
        q: (n, 1) SX symbol.
        a: (n, 1) SX tangent vector.
        b: (n, 1) SX tangent vector.

    Returns:
        (n, 1) SX expression.
    """
    return 0.5 * (
        ca.jtimes(ca.mtimes(G, a), q, b)
        + ca.jtimes(ca.mtimes(G, b), q, a)
        - ca.gradient(ca.dot(a, ca.mtimes(G, b)), q)
    )
