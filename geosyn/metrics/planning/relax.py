"""`metric_relax`: a sampled path pulled taut in the metric, clear of the obstacles,
by Gauss-Newton steps on all its samples at once (no NLP solver).

For the samples ``x_0 .. x_N`` (ends fixed) of a piecewise-linear path the cost is the
discrete energy plus a clearance penalty on the samples,

.. math::
    J(x) = N \\sum_i d_i^T G(m_i) d_i
           + w \\sum_k \\max(0, \\delta - c(x_k))^2,
    \\qquad d_i = x_{i+1} - x_i,\\; m_i = (x_i + x_{i+1}) / 2,

with ``c`` the smallest sphere-obstacle clearance (the planner's `SphereCheck`) and
``delta`` [m] the clearance below which the penalty acts. Its gradient is exact in the
energy (`geosyn.metrics.base.Metric.quadratic_gradients`, the midpoint metrics by
`~geosyn.metrics.base.Metric.G_many`); in the clearance it is the caller's
(``gradients``: the nearest pair's, analytic) or central differences. The
Gauss-Newton Hessian is block tridiagonal (``2 N G(m_i)`` per segment, plus
``2 w g g^T`` per penalised sample, ``g`` the clearance gradient), solved as one banded
Cholesky system. A step is tried at twice the fraction the last one took and halved
until the cost falls (`SMALLEST_STEP`; trial iterates cost their energy and clearances
only; the gradients are taken once one is accepted). Every accepted iterate whose
segments all pass the segment check and whose energy is the lowest so far becomes the
returned path, so the result is valid wherever the input was checked and never of
higher energy than the input.

With ``bounds`` (the joint limits) the steps are projected (a projected Newton method,
Bertsekas 1982): a coordinate at its bound whose descent direction points outside is
held there in the system, and every trial iterate is clipped to the box, so no sample
(and no segment: the box is convex) leaves the limits.

It replaces a diffusion of the samples one at a time (an earlier `metric_smooth`:
preconditioned gradient steps, a sample held next to an invalid segment), which needs
O(N^2) sweeps to move the middle of a path: on the Panda it gained 1-2 % of length in
1 s, where these steps reach the geodesic of a free scene and the constrained optimum's
length on most benchmark scenes within 0.05-0.3 s (`benchmarks/RESULTS.md`).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable

import numpy as np
import scipy.linalg

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.base import Metric
from geosyn.metrics.planning.rrt import SegmentValidity

__all__ = ["RELAX_DELTA", "Clearances", "Gradients", "metric_relax"]

RELAX_DELTA = 0.03
"""Clearance [m] below which a sample is penalised (above the planner's sampling
margin: the samples keep clear of the obstacles, the segments between them too)."""

Clearances = Callable[[np.ndarray], np.ndarray]
"""``clearances(Q (K, n)) -> (K,)`` smallest sphere-obstacle signed distance [m]
(`geosyn.metrics.planning.sphere_check.SphereCheck.clearances`)."""

Gradients = Callable[[np.ndarray], np.ndarray]
"""``gradients(Q (K, n)) -> (K, n)`` the gradients [m/rad] of the `Clearances` at ``Q``
(e.g. `geosyn.metrics.planning.exact_path.configuration_gradients`)."""

SMALLEST_STEP = 0.5**7
"""Smallest fraction of a Gauss-Newton step tried before the relaxation stops. Each step
is tried first at twice the fraction the last accepted one took (at most the whole
step), then halved; a fraction below one that lowers the cost by less than ``tol`` has
the next step tried whole before the relaxation stops. On the 14 Panda benchmark scenes'
paths the clearance penalty's hinge had most steps accepted at 1/8-1/128 of the whole:
halving from the whole step each time spent 4.4 trial iterates per step, and this
memory took 21 % less CPU to the same or a lower energy (`benchmarks/RESULTS.md`)."""

BOUND_TOL = 1e-12
"""Distance [rad] to a bound within which a sample counts as at it (`metric_relax`'s
``bounds``)."""

OUTSIDE_TOL = 1e-9
"""Largest distance [rad] of a sample of ``path`` outside `metric_relax`'s ``bounds``
(e.g. an NLP's bound tolerance; such an interior sample is clipped onto the box first,
the ends are kept as given)."""


def _energy_value(metric: Metric, x: np.ndarray) -> tuple[float, np.ndarray]:
    """(discrete energy, (N, n, n) the metrics at the midpoints) of the samples ``x`` (T, n)."""
    N = len(x) - 1
    d, m = np.diff(x, axis=0), 0.5 * (x[1:] + x[:-1])
    Gs = metric.G_many(m)
    return N * float(np.einsum("ia,iab,ib->", d, Gs, d)), Gs


def _energy_gradient(metric: Metric, x: np.ndarray, Gs: np.ndarray) -> np.ndarray:
    """(T, n) gradient of the discrete energy at ``x`` (T, n), its midpoint metrics
    ``Gs`` given (`_energy_value`)."""
    N = len(x) - 1
    d, m = np.diff(x, axis=0), 0.5 * (x[1:] + x[:-1])
    Gd = np.einsum("iab,ib->ia", Gs, d)
    half = 0.5 * metric.quadratic_gradients(m, d)
    grad = np.zeros_like(x)
    grad[1:] += N * (2.0 * Gd + half)
    grad[:-1] += N * (-2.0 * Gd + half)
    return grad


def _penalty_value(clear: Clearances, x: np.ndarray, delta: float,
                   weight: float) -> tuple[float, np.ndarray]:  # fmt: skip
    """(penalty, (T - 2,) the clearances of the interior samples) of ``x`` (T, n)."""
    c = clear(x[1:-1])
    return float(weight * np.sum(np.maximum(delta - c, 0.0) ** 2)), c


def _penalty_gradient(clear: Clearances, x: np.ndarray, c: np.ndarray, delta: float,
                      weight: float, h: float = 1e-6, gradients: Gradients | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """((T, n) the penalty's gradient, (T, n) the clearance gradients of the penalised
    interior samples, zero elsewhere) of ``x`` with its interior clearances ``c``
    (`_penalty_value`): ``gradients``, or central differences of step ``h`` [rad]."""
    T, n = x.shape
    grad, g_all = np.zeros_like(x), np.zeros_like(x)
    hit = np.flatnonzero(c < delta)
    if not hit.size:
        return grad, g_all
    base = x[1:-1][hit]
    if gradients is not None:
        g = gradients(base)
    else:
        steps = h * np.eye(n)
        probes = np.concatenate([base[:, None] + steps, base[:, None] - steps], axis=1)
        values = clear(probes.reshape(-1, n)).reshape(len(hit), 2 * n)
        g = (values[:, :n] - values[:, n:]) / (2.0 * h)
    grad[hit + 1] = -2.0 * weight * (delta - c[hit])[:, None] * g
    g_all[hit + 1] = g
    return grad, g_all


def _block_tridiagonal_solve(diag: np.ndarray, off: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """(M, n) solution of the symmetric positive-definite block-tridiagonal system with
    diagonal blocks ``diag`` (M, n, n), blocks below the diagonal ``off`` (M - 1, n, n)
    and right-hand side ``rhs`` (M, n): one banded Cholesky solve (LAPACK ``pbsv``,
    bandwidth 2 n - 1; O(M n^3), no multithreaded BLAS call)."""
    M, n = rhs.shape
    u = 2 * n - 1  # superdiagonals of the banded (M n, M n) matrix
    upper = np.zeros((M, n, 2 * n))  # block row k: [block (k, k), block (k, k + 1)]
    upper[:, :, :n] = diag
    upper[:-1, :, n:] = np.swapaxes(off, 1, 2)
    rows, cols, take = _band_index(M, n)
    band = np.zeros((u + 1, M * n))
    band[rows, cols] = upper[take]  # upper form: band[u + r - c, c] = A[r, c], c >= r
    return scipy.linalg.solveh_banded(band, rhs.ravel()).reshape(M, n)


@functools.lru_cache(maxsize=32)
def _band_index(M: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, cols, take): where the upper-triangle entries of `_block_tridiagonal_solve`'s
    block rows (``upper[take]``, (M, n, 2 n) with ``take`` a boolean mask) go in LAPACK's
    upper band form of bandwidth ``2 n - 1``."""
    k, a, b = np.meshgrid(np.arange(M), np.arange(n), np.arange(2 * n), indexing="ij")
    take = (b >= a) & (k * n + b < M * n)
    r, c = k * n + a, k * n + b
    return (2 * n - 1 + r - c)[take], c[take], take


def _box(bounds: tuple[np.ndarray, np.ndarray] | None,
         x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """((n,), (n,)) the checked ``bounds`` [rad] of the samples ``x`` (T, n) (infinite
    when None)."""
    n = x.shape[1]
    if bounds is None:
        return np.full(n, -np.inf), np.full(n, np.inf)
    lo, hi = (np.asarray(b, dtype=float).reshape(-1) for b in bounds)
    if lo.shape != (n,) or hi.shape != (n,) or np.any(lo > hi):
        raise InvalidArgument(
            f"bounds: two ({n},) arrays with lower <= upper, got shapes {lo.shape}, {hi.shape}"
        )
    out = np.maximum(lo - x, x - hi).max()
    if out > OUTSIDE_TOL:
        raise InvalidArgument(
            f"path: a sample lies {out:.3g} rad outside bounds (the joint limits); "
            f"allowed: within them to {OUTSIDE_TOL:g} rad"
        )
    return lo, hi


def _hold_active(diag: np.ndarray, off: np.ndarray, rhs: np.ndarray, y: np.ndarray,
                 lo: np.ndarray, hi: np.ndarray) -> None:  # fmt: skip
    """Hold, in place in the block-tridiagonal system (``diag`` (M, n, n), ``off``
    (M - 1, n, n), ``rhs`` (M, n): `_block_tridiagonal_solve`'s), the coordinates of the
    interior samples ``y`` (M, n) that sit at a bound ``lo`` / ``hi`` (n,) with the
    descent direction ``rhs`` pointing outside: their rows and columns become the
    identity's, their right-hand side 0 (their step is 0)."""
    held = ((y <= lo + BOUND_TOL) & (rhs < 0.0)) | ((y >= hi - BOUND_TOL) & (rhs > 0.0))
    k, a = np.nonzero(held)
    diag[k, a, :] = 0.0
    diag[k, :, a] = 0.0
    diag[k, a, a] = 1.0
    rhs[k, a] = 0.0
    below, above = k >= 1, k + 1 < len(diag)
    off[k[below] - 1, a[below], :] = 0.0  # the block (k, k - 1): row a of sample k
    off[k[above], :, a[above]] = 0.0  # the block (k + 1, k): column a of sample k


def _path_check(segment: SegmentValidity | None, path_ok: Callable[[np.ndarray], bool] | None,
                resolution: float) -> Callable[[np.ndarray], bool]:  # fmt: skip
    """Whether a whole path (T, n) is valid: ``path_ok``, else ``segment`` on each of its
    segments at ``resolution`` [rad]."""
    if path_ok is not None:
        return path_ok
    if segment is None:
        raise InvalidArgument("metric_relax: a segment check or path_ok, got neither")
    check = segment

    def valid(y: np.ndarray) -> bool:
        return all(check(a, b, resolution) for a, b in zip(y[:-1], y[1:], strict=True))

    return valid


def metric_relax(
    segment: SegmentValidity | None,
    clearances: Clearances,
    metric: Metric,
    path: np.ndarray,
    *,
    budget: float = 0.1,
    delta: float = RELAX_DELTA,
    resolution: float = 0.02,
    tol: float = 1e-6,
    max_iter: int = 100,
    stay_valid: bool = False,
    path_ok: Callable[[np.ndarray], bool] | None = None,
    fd_step: float = 1e-6,
    gradients: Gradients | None = None,
    floor: float = -math.inf,
    seed_valid: bool = True,
    bounds: tuple[np.ndarray, np.ndarray] | None = None,
    first_valid: bool = False,
) -> np.ndarray:
    """A path of lower cost (module docstring) with the samples and ends of ``path``.

    Args:
        segment: the planner's segment check (`SegmentValidity`); None with ``path_ok``.
        clearances: its sphere clearances (`Clearances`), the query's obstacles set.
        metric: the planner's metric.
        path: (T, n) valid samples [rad] (T >= 3 to move anything), e.g. from
            `geosyn.metrics.planning.smoothing.even_in_metric`.
        budget: wall-time limit [s] (a step that would end past it, by the previous
            step's time, is not begun).
        delta: clearance below which a sample is penalised [m], > 0.
        resolution: check step of the segments of an iterate (2-norm) [rad].
        tol: stop when a step lowers the cost by less than this fraction.
        max_iter: most Gauss-Newton steps.
        stay_valid: halve a step also until the iterate's segments all pass
            ``segment`` (every iterate valid: the samples may then come as near as the
            check allows, with a small ``delta``), instead of only keeping the valid
            ones.
        path_ok: whether a whole iterate (T, n) is valid, in place of ``segment`` on
            each of its segments (e.g. an exact check of the path).
        fd_step: central-difference step of the clearance gradients [rad] (without
            ``gradients``).
        gradients: the clearances' gradients (`Gradients`); None: central differences.
        floor: clearance [m] below which an interior sample makes an iterate invalid
            without asking ``path_ok`` (whose checked configurations include the
            samples, at this floor: its answer would be no).
        seed_valid: whether ``path`` is valid. False (a seed through the obstacles,
            pushed out by the penalty): the first valid iterate is kept whatever its
            energy, then lower ones (never with ``stay_valid``).
        bounds: ((n,), (n,)) lower and upper joint limits [rad] (may be infinite) that
            every iterate keeps (module docstring); ``path`` within them. None: free.
        first_valid: stop at the first iterate kept (valid and of lower energy than
            ``path``, or, with ``seed_valid`` False, the first valid one): a push-out
            that a tightening follows needs no lower ones.

    Returns:
        (T, n) the accepted iterate of lowest energy whose segments all passed
        ``segment`` (``path`` itself when none did: with ``seed_valid`` False, the
        caller checks). O(T n) metric and O(T n) clearance evaluations per step,
        and one banded ((T - 2) n)^2 solve of bandwidth 2 n - 1.
    """
    x = np.array(path, dtype=float)
    T, n = x.shape
    if T < 3:
        return x
    lo, hi = _box(bounds, x)
    x[1:-1] = np.clip(x[1:-1], lo, hi)  # the ends stay as given (checked by the caller)

    valid = _path_check(segment, path_ok, resolution)

    def keeps(c: np.ndarray) -> bool:  # the interior samples' clearances keep ``floor``
        return bool(c.min() >= floor)

    t_end = time.perf_counter() + budget
    energy, Gs = _energy_value(metric, x)
    g_e = _energy_gradient(metric, x, Gs)
    weight = 100.0 * max(energy, 1e-9) / delta**2  # delta deep costs 100 times E
    pen, c = _penalty_value(clearances, x, delta, weight)
    g_p, g_c = _penalty_gradient(clearances, x, c, delta, weight, fd_step, gradients)
    if not seed_valid and stay_valid:
        raise InvalidArgument("metric_relax: stay_valid needs a valid path (seed_valid)")
    cost, best, N = energy + pen, x.copy(), T - 1
    lowest = energy if seed_valid else math.inf  # the energy to beat by a valid iterate
    last = 0.0  # the previous step's time: one that would end past the budget is not begun
    scale = 1.0  # of the Gauss-Newton step tried first: twice the last accepted one's
    for _ in range(max_iter):
        begun = time.perf_counter()
        if begun + last > t_end:
            break
        A = 2.0 * N * np.asarray(Gs)  # segment i joins samples i and i + 1 (interior: -1)
        diag, off = A[:-1] + A[1:], -A[1:-1]  # off: the blocks (i, i - 1) of the interior
        g = g_c[1:-1]
        diag += 2.0 * weight * np.einsum("ka,kb->kab", g, g)
        diag += (1e-9 * float(np.einsum("kaa->", diag)) / ((T - 2) * n)) * np.eye(n)
        rhs = -(g_e + g_p)[1:-1]
        _hold_active(diag, off, rhs, x[1:-1], lo, hi)
        step = _block_tridiagonal_solve(diag, off, rhs)
        while True:  # the Gauss-Newton step, halved until the cost falls
            trial = x.copy()
            trial[1:-1] = np.clip(x[1:-1] + scale * step, lo, hi)
            t_energy, t_Gs = _energy_value(metric, trial)  # the gradients once accepted
            t_pen, t_c = _penalty_value(clearances, trial, delta, weight)
            if t_energy + t_pen < cost and (not stay_valid or (keeps(t_c) and valid(trial))):
                break
            scale *= 0.5
            if scale < SMALLEST_STEP:
                break
        if scale < SMALLEST_STEP:
            break  # no descent along it: a local minimum of the sampled problem
        taken, scale = scale, min(1.0, 2.0 * scale)
        fall = (cost - t_energy - t_pen) / max(cost, 1e-12)
        x, cost, Gs = trial, t_energy + t_pen, t_Gs
        g_e = _energy_gradient(metric, x, Gs)
        g_p, g_c = _penalty_gradient(clearances, x, t_c, delta, weight, fd_step, gradients)
        if t_energy < lowest and (stay_valid or (keeps(t_c) and valid(x))):  # stay_valid: above
            best, lowest = x.copy(), t_energy
            if first_valid:
                break
        if fall < tol:
            if taken == 1.0:
                break
            scale = 1.0  # a small step fell little: the whole one decides
        last = time.perf_counter() - begun
    return best
