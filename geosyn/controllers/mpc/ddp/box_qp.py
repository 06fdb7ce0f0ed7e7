"""The box-constrained QP of a DDP stage and the small symmetric solves it needs.

``min 0.5 k^T H k + g^T k`` subject to ``lo <= k <= hi``, written symbolically (SX: an
unrolled Cholesky factorisation, straight-line code; MX: CasADi's LDL^T solver) so that
it compiles into the Riccati step of `geosyn.controllers.mpc.ddp`.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

__all__ = ["BOX_ITERATIONS", "box_qp", "spd_solve"]

BOX_ITERATIONS = 5
"""Projected-Newton steps of the box QP per stage (from the clipped unconstrained step;
exact once the active set is found, which takes one step per newly active joint)."""

_Sym = Any  # a CasADi SX or MX expression (the QP and the solves are written for both)


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


def _free_mask(k: _Sym, grad: _Sym, lo: _Sym, hi: _Sym) -> _Sym:
    """1 for a free control, 0 for one at a bound with the gradient pushing outwards."""
    clamped = ca.logic_or(ca.logic_and(k <= lo, grad > 0), ca.logic_and(k >= hi, grad < 0))
    return 1 - clamped


def _masked(H: _Sym, free: _Sym) -> _Sym:
    """The Hessian of the free controls, with the identity on the clamped ones."""
    return H * (free @ free.T) + ca.diag(1 - free)


def box_qp(H: _Sym, g: _Sym, lo: _Sym, hi: _Sym, iterations: int) -> tuple[_Sym, _Sym, _Sym]:
    """``min 0.5 k^T H k + g^T k`` s.t. ``lo <= k <= hi``: projected Newton, unrolled.

    Starts from the clipped unconstrained minimiser; each step solves the free block
    and keeps the best of four projected step lengths (never worse than the current k).

    Returns:
        ``(k, free, H_free)``: the solution (n,), the free-control mask (n,) and the
        Hessian of the free controls (identity on the clamped ones).
    """

    def clip(z: ca.SX) -> ca.SX:
        return ca.fmin(ca.fmax(z, lo), hi)

    def value(z: ca.SX) -> ca.SX:
        return ca.dot(z, 0.5 * (H @ z) + g)

    k = clip(-spd_solve(H, g))
    for _ in range(iterations):
        grad = g + H @ k
        free = _free_mask(k, grad, lo, hi)
        d = -spd_solve(_masked(H, free), free * grad)
        best, best_value = k, value(k)
        # Projected Newton steps, and a projected gradient step of length 1 / trace(H)
        # (<= 1 / lambda_max: it never increases the value), so a bent Newton
        # direction cannot stall the iteration.
        candidates = [clip(k + step * d) for step in (1.0, 0.5, 0.25, 0.1)]
        candidates.append(clip(k - grad / ca.trace(H)))
        for cand in candidates:
            cand_value = value(cand)
            better = cand_value < best_value
            best = ca.if_else(better, cand, best)
            best_value = ca.if_else(better, cand_value, best_value)
        k = best
    free = _free_mask(k, g + H @ k, lo, hi)
    return k, free, _masked(H, free)
