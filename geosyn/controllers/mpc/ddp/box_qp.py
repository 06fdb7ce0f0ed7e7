"""The box-constrained QP of a DDP stage.

``min 0.5 k^T H k + g^T k`` subject to ``lo <= k <= hi``, written symbolically (its solves
by `geosyn.controllers.mpc.ocp.linalg.spd_solve`) so that it compiles into the Riccati
step of `geosyn.controllers.mpc.ddp.parts`.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from geosyn.controllers.mpc.ocp.linalg import spd_solve

__all__ = ["BOX_ITERATIONS", "box_qp"]

BOX_ITERATIONS = 5
"""Projected-Newton steps of the box QP per stage (from the clipped unconstrained step;
exact once the active set is found, which takes one step per newly active joint)."""

_Sym = Any  # a CasADi SX or MX expression (the QP and the solves are written for both)


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
