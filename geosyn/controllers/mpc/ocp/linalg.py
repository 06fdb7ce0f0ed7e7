"""Small symmetric positive-definite solves written symbolically (SX: an unrolled
Cholesky factorisation, straight-line code; MX: CasADi's LDL^T solver), for the cost
derivatives and the RK4 linearisation of the shared OCP description and the DDP's
Riccati step."""

from __future__ import annotations

from typing import Any

import casadi as ca

__all__ = ["spd_solve"]

_Sym = Any  # a CasADi SX or MX expression (the solves are written for both)


def _cholesky(H: ca.SX) -> ca.SX:
    """Lower Cholesky factor of a symmetric positive-definite SX matrix (unrolled)."""
    n = H.shape[0]
    L = ca.SX.zeros(n, n)
    for j in range(n):
        s = H[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        L[j, j] = ca.sqrt(s)
        for i in range(j + 1, n):
            s = H[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    return L


def _cholesky_solve(L: ca.SX, b: ca.SX) -> ca.SX:
    """``(L L^T)^{-1} b`` for an (n, m) right-hand side, by two triangular sweeps."""
    n = L.shape[0]
    y = ca.SX.zeros(b.shape)
    for i in range(n):
        s = b[i, :]
        for k in range(i):
            s -= L[i, k] * y[k, :]
        y[i, :] = s / L[i, i]
    z = ca.SX.zeros(b.shape)
    for i in reversed(range(n)):
        s = y[i, :]
        for k in range(i + 1, n):
            s -= L[k, i] * z[k, :]
        z[i, :] = s / L[i, i]
    return z


def spd_solve(H: _Sym, b: _Sym) -> _Sym:
    """``H^{-1} b`` for a symmetric positive-definite ``H``: an unrolled Cholesky
    factorisation in SX (small, fastest), CasADi's LDL^T solver in MX (compact code for
    many joints)."""
    if isinstance(H, ca.MX):
        return ca.solve(H, b, "ldl")
    return _cholesky_solve(_cholesky(H), b)
