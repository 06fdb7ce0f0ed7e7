"""Synergies from demonstrations: principal geodesic analysis (PGA) and the PCA baseline.

PGA (Fletcher et al. 2004) is PCA on a Riemannian manifold: the Fréchet (Karcher) mean
replaces the average, the log map at the mean takes demonstrations to one tangent space,
and the principal directions are G(mean)-orthonormal. With a constant identity metric the
log map is the difference of configurations and PGA reduces to PCA.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import scipy.linalg

from geosyn.core.types import Matrix, Vector
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic import exp
from geosyn.synergies.basis import _fix_signs
from geosyn.synergies.errors import InvalidSynergyInput, SynergyNotConverged
from geosyn.synergies.synergy import check_count, check_metric, checked_log


class PGAResult(NamedTuple):
    """Principal geodesic analysis of demonstrations.

    Attributes:
        mean: (n,) Fréchet mean [rad].
        V: (n, k) principal directions at the mean, ``V.T @ G(mean) @ V = I`` [rad/s].
        variances: (k,) variance along each direction, ``mean_i <v_j, u_i>_G^2`` [rad^2]
            (G-norm units).
        explained_variance_ratio: (k,) variances over the total ``mean_i |u_i|_G^2``.
        reconstruction_error: (k,) for k' = 1..k, mean over demonstrations of the
            Riemannian distance between ``x_i`` and ``exp(mean, P_k' u_i)`` where
            ``P_k'`` is the G-orthogonal projection on the first k' directions [rad].
        log_vectors: (N, n) ``u_i = log(mean, x_i)`` [rad/s at unit duration].
        mean_iterations: fixed-point iterations of the mean.
        exact_cost: for ``exact=True``, (before, after): mean squared Riemannian distance
            [rad^2] from the demonstrations to the geodesic submanifold
            ``{exp(mean, V c)}`` at the tangent-PCA subspace and after refinement;
            None otherwise.
    """

    mean: Vector
    V: Matrix
    variances: Vector
    explained_variance_ratio: Vector
    reconstruction_error: Vector
    log_vectors: Matrix
    mean_iterations: int
    exact_cost: tuple[float, float] | None


class PCAResult(NamedTuple):
    """Euclidean PCA of configurations (the classical linear-synergy baseline).

    Attributes:
        mean: (n,) average configuration [rad].
        components: (n, k) orthonormal principal directions in R^n.
        explained_variance: (k,) variance along each component (1/N normalization)
            [rad^2].
        explained_variance_ratio: (k,) over the total variance.
        reconstruction_error: (k,) for k' = 1..k, mean Euclidean distance between
            ``x_i`` and its projection on the first k' components [rad].
    """

    mean: Vector
    components: Matrix
    explained_variance: Vector
    explained_variance_ratio: Vector
    reconstruction_error: Vector


def as_configurations(demos: object, n: int | None = None) -> Matrix:
    """Stack demonstrations into configurations.

    Args:
        demos: (N, n) array of configurations, or a sequence of trajectories each
            (T_i, n) (or objects with a ``.q`` attribute such as `Geodesic`) [rad].
        n: expected dimension, or None to accept any.

    Returns:
        (sum T_i, n) configurations (a copy).

    Raises:
        InvalidSynergyInput: no demonstrations or an empty trajectory, wrong or
            inconsistent dimensions, non-numeric or non-finite values.
    """
    parts: list[object]
    if isinstance(demos, np.ndarray):
        parts = [demos]
        if demos.ndim not in (2,):
            raise InvalidSynergyInput(
                f"demos as an array must be (N, n) configurations, got shape {demos.shape}",
                "demos",
            )
    else:
        if not isinstance(demos, Sequence) or isinstance(demos, (str, bytes)):
            raise InvalidSynergyInput(
                f"demos must be an (N, n) array or a list of (T_i, n) trajectories, "
                f"got {type(demos).__name__}",
                "demos",
            )
        parts = [getattr(d, "q", d) for d in demos]
    if len(parts) == 0:
        raise InvalidSynergyInput("demos is empty; at least one configuration is needed", "demos")
    arrays: list[np.ndarray] = []
    for i, p in enumerate(parts):
        try:
            a = np.array(p, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise InvalidSynergyInput(f"demos[{i}] is not a float array: {p!r}", "demos") from err
        if a.ndim != 2:
            raise InvalidSynergyInput(f"demos[{i}] must be (T, n), got shape {a.shape}", "demos")
        if a.shape[0] == 0:
            raise InvalidSynergyInput(f"demos[{i}] has zero samples, shape {a.shape}", "demos")
        if n is not None and a.shape[1] != n:
            raise InvalidSynergyInput(
                f"demos[{i}] has dimension {a.shape[1]}, the metric has n = {n}", "demos"
            )
        if arrays and a.shape[1] != arrays[0].shape[1]:
            raise InvalidSynergyInput(
                f"demos[{i}] has dimension {a.shape[1]}, demos[0] has {arrays[0].shape[1]}",
                "demos",
            )
        if not np.all(np.isfinite(a)):
            raise InvalidSynergyInput(f"demos[{i}] has non-finite values", "demos")
        arrays.append(a)
    return np.vstack(arrays)


def frechet_mean(
    metric: Metric,
    X: Matrix,
    *,
    steps: int = 100,
    tol: float = 1e-9,
    max_iter: int = 50,
) -> tuple[Vector, Matrix, int]:
    """Fréchet (Karcher) mean by the fixed point ``q <- exp(q, mean_i log(q, x_i))``.

    Starts from the arithmetic mean; each log is warm-started from the previous iterate
    shifted by the mean update.

    Args:
        metric: the metric.
        X: (N, n) configurations [rad].
        steps: integration steps of exp/log.
        tol: stop when the G-norm of the mean log vector is below this [rad].
        max_iter: iteration limit.

    Returns:
        mean (n,), log vectors (N, n) at the mean, iterations.

    Raises:
        SynergyNotConverged: ``max_iter`` reached (``residual`` is the G-norm of the last
            update, ``iterations`` is ``max_iter``), or a log map did not converge.
    """
    mean = X.mean(axis=0)
    U = X - mean
    step_norm = np.inf
    for it in range(1, max_iter + 1):
        U = np.array(
            [checked_log(metric, mean, x, v_init=u, steps=steps) for x, u in zip(X, U, strict=True)]
        )
        step = U.mean(axis=0)
        step_norm = float(np.sqrt(max(float(step @ metric.G(mean) @ step), 0.0)))
        if step_norm <= tol:
            return mean, U, it
        mean = exp(metric, mean, step, duration=1.0, steps=steps).q[-1].copy()
        U = U - step
    raise SynergyNotConverged(
        f"Fréchet mean did not converge in max_iter={max_iter} iterations "
        f"(last update G-norm {step_norm:.3g} > tol={tol:g}); demonstrations may be too "
        "spread out for a unique mean",
        step_norm,
        max_iter,
    )


def _reconstruction_errors(
    metric: Metric, mean: Vector, V: Matrix, G: Matrix, X: Matrix, U: Matrix, steps: int
) -> Vector:
    """Mean distance between x_i and exp(mean, P_k' u_i), k' = 1..k (see `PGAResult`)."""
    k = V.shape[1]
    errs = np.zeros(k)
    C = U @ G @ V  # (N, k) coordinates
    for kk in range(1, k + 1):
        total = 0.0
        for x, u, c in zip(X, U, C, strict=True):
            u_rec = V[:, :kk] @ c[:kk]
            x_rec = exp(metric, mean, u_rec, duration=1.0, steps=steps).q[-1]
            if np.max(np.abs(x_rec - x)) <= 1e-14:
                continue
            w = checked_log(metric, x_rec, x, v_init=u - u_rec, steps=steps)
            total += float(np.sqrt(max(float(w @ metric.G(x_rec) @ w), 0.0)))
        errs[kk - 1] = total / X.shape[0]
    return errs


def _geodesic_projection_sq(
    metric: Metric, mean: Vector, V: Matrix, x: Vector, c0: Vector, L_x: np.ndarray, steps: int
) -> tuple[float, Vector]:
    """Squared distance from x to the geodesic submanifold {exp(mean, V c)} and best c.

    Gauss-Newton (scipy least_squares, finite differences) on c with the residual
    ``L_x^T log(x, exp(mean, V c))``, whose norm is the Riemannian distance.
    """
    warm: dict[str, Vector | None] = {"v": None}

    def residual(c: np.ndarray) -> np.ndarray:
        y = exp(metric, mean, V @ c, duration=1.0, steps=steps).q[-1]
        w = checked_log(metric, x, y, v_init=warm["v"], steps=steps)
        warm["v"] = w
        return L_x.T @ w

    from scipy.optimize import least_squares  # heavy (~0.2 s): imported where used

    sol = least_squares(residual, c0, method="lm", xtol=1e-8, ftol=1e-10)
    return float(sol.fun @ sol.fun), sol.x


def _exact_refine(
    metric: Metric,
    mean: Vector,
    G: Matrix,
    V_full: Matrix,
    k: int,
    X: Matrix,
    U: Matrix,
    steps: int,
    max_evals: int,
) -> tuple[Matrix, float, float]:
    """Refine span(V[:, :k]) to minimize the mean squared distance to the submanifold.

    The subspace is charted around the tangent-PCA solution in whitened coordinates
    ``Y = L^T V`` (G = L L^T, so G-orthonormal V <-> orthonormal Y):
    ``Y(B) = orth(Y0 + Y0_perp B)`` with B of shape (n-k, k) (a Grassmann chart), and
    the cost ``mean_i min_c d(x_i, exp(mean, V(B) c))^2`` is minimized over B by
    Nelder-Mead with at most ``max_evals`` evaluations (each costs one inner Gauss-Newton
    projection per demonstration). Returns the refined V (columns rotated within the
    subspace to decreasing tangent variance), and the cost before and after.
    """
    n = G.shape[0]
    L = np.linalg.cholesky(G)
    Y0 = L.T @ V_full[:, :k]
    Yp = L.T @ V_full[:, k:]
    L_xs = [np.linalg.cholesky(metric.G(x)) for x in X]

    def V_of(b: np.ndarray) -> Matrix:
        Yb, _ = np.linalg.qr(Y0 + Yp @ b.reshape(n - k, k))
        return scipy.linalg.solve_triangular(L.T, Yb, lower=False)

    def cost(b: np.ndarray) -> float:
        Vb = V_of(b)
        C = U @ G @ Vb
        return float(
            np.mean(
                [
                    _geodesic_projection_sq(metric, mean, Vb, x, c, Lx, steps)[0]
                    for x, c, Lx in zip(X, C, L_xs, strict=True)
                ]
            )
        )

    b0 = np.zeros((n - k) * k)
    before = cost(b0)
    if n == k:
        return V_full[:, :k], before, before
    # Initial simplex: steps of 0.05 in the chart, i.e. tilts of about 3 degrees.
    simplex = np.vstack([b0, b0 + 0.05 * np.eye(b0.size)])
    from scipy.optimize import minimize  # heavy (~0.2 s): imported where used

    sol = minimize(
        cost,
        b0,
        method="Nelder-Mead",
        options={"maxfev": max_evals, "initial_simplex": simplex, "xatol": 1e-6, "fatol": 1e-12},
    )
    b_best, after = (sol.x, float(sol.fun)) if sol.fun < before else (b0, before)
    Vb = V_of(b_best)
    S = U.T @ U / X.shape[0]
    mu, W = np.linalg.eigh(Vb.T @ G @ S @ G @ Vb)
    return _fix_signs(Vb @ W[:, np.argsort(-mu)]), before, after


def pga(
    metric: Metric,
    demos: Matrix | Sequence[Matrix],
    k: int,
    exact: bool = False,
    *,
    steps: int = 100,
    mean_tol: float = 1e-9,
    max_iter: int = 50,
    exact_max_evals: int = 20,
) -> PGAResult:
    """Principal geodesic analysis of demonstrations.

    1. Fréchet mean by fixed-point iteration (`frechet_mean`).
    2. Tangent PCA at the mean under G = G(mean): with S the second moment of the log
       vectors u_i, solve :math:`G S G v = \\lambda G v` (variance of
       :math:`\\langle v, u\\rangle_G` subject to :math:`v^\\top G v = 1`); the
       eigenvectors, sorted by decreasing :math:`\\lambda`, are G-orthonormal.
    3. Optionally (``exact=True``) refine the k-dimensional subspace by minimizing the true
       distance to the principal geodesic submanifold (see `_exact_refine`; costly: use
       with few demonstrations and small n).

    Args:
        metric: the metric.
        demos: (N, n) configurations or a list of (T_i, n) trajectories [rad].
        k: number of principal directions, 1 <= k <= n.
        exact: refine by exact PGA.
        steps: integration steps of exp/log.
        mean_tol: convergence tolerance of the mean [rad, G-norm].
        max_iter: iteration limit of the mean.
        exact_max_evals: cost evaluations allowed to the exact refinement.

    Returns:
        The `PGAResult`. Signs: each direction's largest-magnitude entry is positive.

    Cost: N logs per mean iteration plus N k exp/log pairs for the reconstruction errors
    (N = number of configurations); ``exact=True`` adds up to ``exact_max_evals`` times N
    inner projections.

    Raises:
        InvalidSynergyInput: bad input.
        SynergyNotConverged: the mean iteration or a log map did not converge.
    """
    n = check_metric(metric).n
    X = as_configurations(demos, n)
    k = check_count(k, n)
    mean, U, iterations = frechet_mean(metric, X, steps=steps, tol=mean_tol, max_iter=max_iter)
    G = np.asarray(metric.G(mean), dtype=np.float64)
    S = U.T @ U / X.shape[0]
    lam, W = scipy.linalg.eigh(G @ S @ G, G)
    order = np.argsort(-lam, kind="stable")
    V_full = _fix_signs(W[:, order])
    exact_cost = None
    if exact:
        V, before, after = _exact_refine(
            metric, mean, G, V_full, k, X, U, steps, int(exact_max_evals)
        )
        exact_cost = (before, after)
    else:
        V = V_full[:, :k]
    variances = np.maximum(np.einsum("ij,jk,ki->i", V.T, G @ S @ G, V), 0.0)
    total = float(np.trace(G @ S))
    ratio = variances / total if total > 0 else np.zeros(k)
    errors = _reconstruction_errors(metric, mean, V, G, X, U, steps)
    return PGAResult(mean, V, variances, ratio, errors, U, iterations, exact_cost)


def pca_synergies(demos: Matrix | Sequence[Matrix], k: int) -> PCAResult:
    """Euclidean PCA of configurations (linear synergies, the baseline to PGA).

    Args:
        demos: (N, n) configurations or a list of (T_i, n) trajectories [rad].
        k: number of components, 1 <= k <= n.

    Returns:
        The `PCAResult` (1/N variance normalization, as in `pga`; same sign convention).

    Raises:
        InvalidSynergyInput: bad input.
    """
    X = as_configurations(demos)
    n = X.shape[1]
    k = check_count(k, n)
    mean = X.mean(axis=0)
    D = X - mean
    S = D.T @ D / X.shape[0]
    lam, W = np.linalg.eigh(S)
    order = np.argsort(-lam, kind="stable")
    lam = np.maximum(lam[order], 0.0)
    comps = _fix_signs(W[:, order])[:, :k]
    total = float(np.trace(S))
    ratio = lam[:k] / total if total > 0 else np.zeros(k)
    C = D @ comps
    errors = np.array(
        [np.mean(np.linalg.norm(D - C[:, :kk] @ comps[:, :kk].T, axis=1)) for kk in range(1, k + 1)]
    )
    return PCAResult(mean, comps, lam[:k], ratio, errors)
