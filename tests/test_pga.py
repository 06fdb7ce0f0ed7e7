"""Tests of geosyn.synergies.pga: principal geodesic analysis and the PCA baseline."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import scipy.linalg

from conftest import get_metric
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic import distance, exp
from geosyn.synergies import (
    InvalidSynergyInput,
    SynergyNotConverged,
    orthonormal_synergies,
    pca_synergies,
    pga,
)


class IdentityMetric(Metric):
    """The Euclidean metric G = I: geodesics are straight lines, log is a difference."""

    def __init__(self, n: int) -> None:
        self.n = n

    def G(self, q):
        return np.eye(self.n)

    def symbolic_G(self, q):
        return ca.SX.eye(self.n)


Q0 = np.array([0.3, 1.2, -0.8])


def planted_demos(metric, seed=0, pairs=6, samples=4, noise=1e-4, scale=0.1):
    """Geodesics from Q0 along combinations of two planted G-orthonormal synergies.

    Weights come in antithetic pairs (w, -w), so the Fréchet mean of noise-free data is
    Q0 itself; each demonstration is a trajectory subsampled at ``samples`` instants.
    """
    rng = np.random.default_rng(seed)
    V = orthonormal_synergies(metric, Q0, 3).V[:, :2]
    demos = []
    for _ in range(pairs):
        w = rng.normal(0, scale, 2)  # G-unit synergies move up to ~6 rad/s here
        for sign in (1.0, -1.0):
            tr = exp(metric, Q0, sign * (V @ w), 1.0, 60)
            q = tr.q[np.linspace(15, 60, samples).round().astype(int)]
            demos.append(q + noise * rng.normal(size=q.shape))
    return V, demos


def g_angles_deg(G, A, B):
    Gh = np.real(scipy.linalg.sqrtm(G))
    return np.degrees(scipy.linalg.subspace_angles(Gh @ A, Gh @ B))


def test_recovers_planted_geodesic_subspace():
    metric = get_metric("planar3")
    V_true, demos = planted_demos(metric)
    res = pga(metric, demos, 2)
    G = metric.G(res.mean)
    angles = g_angles_deg(G, res.V, V_true)
    print(
        f"principal angles to the planted span: {angles} deg; mean offset "
        f"{np.linalg.norm(res.mean - Q0):.2e} rad"
    )
    assert angles.max() < 2.0
    np.testing.assert_allclose(res.V.T @ G @ res.V, np.eye(2), atol=1e-10)
    assert np.linalg.norm(res.mean - Q0) < 1e-2
    assert res.log_vectors.shape == (len(demos) * 4, 3)
    # Log vectors really are logs: exp(mean, u_i)(1) returns the demonstrations.
    X = np.vstack(demos)
    for u, x in zip(res.log_vectors[::7], X[::7], strict=True):
        np.testing.assert_allclose(exp(metric, res.mean, u).q[-1], x, atol=1e-9)


def test_mean_is_a_frechet_mean():
    """Moving the mean in any direction increases the sum of squared distances."""
    metric = get_metric("planar3")
    _, demos = planted_demos(metric, seed=1, pairs=3, samples=2, noise=0.05)
    X = np.vstack(demos)
    res = pga(metric, X, 2)
    assert np.linalg.norm(res.log_vectors.mean(axis=0)) < 1e-8

    def cost(m):
        return sum(distance(metric, m, x) ** 2 for x in X)

    c0 = cost(res.mean)
    rng = np.random.default_rng(7)
    for _ in range(3):
        d = rng.normal(size=3)
        d *= 0.02 / np.linalg.norm(d)
        assert cost(res.mean + d) > c0


def test_euclidean_metric_pga_equals_pca():
    metric = IdentityMetric(3)
    rng = np.random.default_rng(3)
    X = rng.normal(size=(15, 3)) @ np.array([[1.0, 0.4, 0.1], [0.0, 0.5, 0.2], [0, 0, 0.1]])
    X += np.array([0.2, -0.4, 1.0])
    res = pga(metric, X, 3)
    pca = pca_synergies(X, 3)
    np.testing.assert_allclose(res.mean, pca.mean, atol=1e-8)
    signs = np.sign(np.sum(res.V * pca.components, axis=0))
    np.testing.assert_allclose(res.V * signs, pca.components, atol=1e-8)
    np.testing.assert_allclose(res.variances, pca.explained_variance, atol=1e-8)
    np.testing.assert_allclose(
        res.explained_variance_ratio, pca.explained_variance_ratio, atol=1e-8
    )
    np.testing.assert_allclose(res.reconstruction_error, pca.reconstruction_error, atol=1e-8)
    # PCA itself against an SVD of the centred data (1/N variances).
    _, s, Wt = np.linalg.svd(X - X.mean(axis=0), full_matrices=False)
    np.testing.assert_allclose(pca.explained_variance, s**2 / len(X), rtol=1e-12)
    np.testing.assert_allclose(np.abs(pca.components.T @ Wt.T), np.eye(3), atol=1e-8)
    np.testing.assert_allclose(pca.reconstruction_error[-1], 0.0, atol=1e-12)


def test_curved_data_explained_variance_pga_and_pca():
    metric = get_metric("planar3")
    _, demos = planted_demos(metric, seed=2, noise=1e-4, scale=0.25)
    res = pga(metric, demos, 3)
    pca = pca_synergies(demos, 3)
    ev_pga = res.explained_variance_ratio[:2].sum()
    ev_pca = pca.explained_variance_ratio[:2].sum()
    print(
        f"explained variance at k=2: PGA {ev_pga:.7f}, PCA {ev_pca:.7f}; reconstruction "
        f"error at k=2: PGA {res.reconstruction_error[1]:.2e} (Riemannian), "
        f"PCA {pca.reconstruction_error[1]:.2e} rad (Euclidean)"
    )
    assert 0 < ev_pga <= 1 and 0 < ev_pca <= 1
    # The data lie (up to 1e-4 noise) on a 2-D geodesic submanifold, curved in joint
    # coordinates: two principal geodesics explain it, two straight components do not.
    assert 1 - ev_pga < 1e-5 < 1 - ev_pca
    np.testing.assert_allclose(res.explained_variance_ratio.sum(), 1.0, atol=1e-10)
    np.testing.assert_allclose(pca.explained_variance_ratio.sum(), 1.0, atol=1e-12)
    assert np.all(np.diff(res.variances) <= 0)
    assert np.all(np.diff(res.reconstruction_error) <= 1e-12)
    assert res.reconstruction_error[-1] < 1e-8  # k = n reconstructs exactly


def test_exact_pga_does_not_increase_projection_cost():
    metric = get_metric("planar3")
    _, demos = planted_demos(metric, seed=4, pairs=3, samples=1, noise=0.05)
    res = pga(metric, demos, 1, exact=True, exact_max_evals=12)
    before, after = res.exact_cost
    print(
        f"exact PGA: mean squared distance to the geodesic submanifold {before:.9f} -> {after:.9f}"
    )
    assert after <= before
    # The geodesic projection is optimal over c; the tangent projection is one candidate.
    G = metric.G(res.mean)
    tangent = pga(metric, demos, 1)
    X = np.vstack(demos)
    C = tangent.log_vectors @ G @ tangent.V
    d2 = [
        distance(metric, exp(metric, tangent.mean, tangent.V @ c).q[-1], x) ** 2
        for c, x in zip(C, X, strict=True)
    ]
    assert before <= np.mean(d2) + 1e-12
    np.testing.assert_allclose(res.V.T @ G @ res.V, np.eye(1), atol=1e-10)
    assert tangent.exact_cost is None
    # The refinement starts from, and stays close to, the tangent-PCA direction.
    assert g_angles_deg(G, res.V, tangent.V).max() < 30.0


def test_bad_input():
    metric = get_metric("planar2")
    with pytest.raises(InvalidSynergyInput, match="empty"):
        pga(metric, [], 1)
    with pytest.raises(InvalidSynergyInput, match=r"demos\[1\] has zero samples"):
        pga(metric, [np.zeros((3, 2)), np.zeros((0, 2))], 1)
    with pytest.raises(InvalidSynergyInput, match="zero samples"):
        pca_synergies(np.zeros((0, 2)), 1)
    with pytest.raises(InvalidSynergyInput, match="the metric has n = 2"):
        pga(metric, np.zeros((4, 3)), 1)
    with pytest.raises(InvalidSynergyInput, match=r"demos\[1\] has dimension 3, demos\[0\] has 2"):
        pca_synergies([np.zeros((2, 2)), np.zeros((2, 3))], 1)
    with pytest.raises(InvalidSynergyInput, match="k must"):
        pga(metric, np.zeros((4, 2)), 3)
    with pytest.raises(InvalidSynergyInput, match="non-finite"):
        pca_synergies(np.array([[0.0, np.inf]]), 1)
    X = np.array([[0.0, 0.5], [2.5, -2.0], [-2.0, 2.5], [1.0, 1.0]])
    with pytest.raises(SynergyNotConverged, match="max_iter=1") as info:
        pga(metric, X, 1, max_iter=1)
    assert info.value.iterations == 1 and info.value.residual > 0


def test_exact_refinement_recovers_from_a_tilted_start():
    """The subspace optimizer works: started 15 deg off the tangent-PCA direction, it
    lowers the projection cost to within 1 % of the tangent-PCA cost and returns close
    to that direction (tangent PCA is near-optimal for data this concentrated)."""
    from geosyn.synergies.pga import _exact_refine

    metric = get_metric("planar3")
    _, demos = planted_demos(metric, seed=4, pairs=3, samples=1, noise=0.05)
    X = np.vstack(demos)
    res = pga(metric, X, 3)
    G = metric.G(res.mean)
    L = np.linalg.cholesky(G)
    th = np.radians(15.0)
    R = np.eye(3)
    R[:2, :2] = [[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]]
    V_tilted = scipy.linalg.solve_triangular(L.T, L.T @ res.V @ R, lower=False)
    _, tangent_cost, _ = _exact_refine(metric, res.mean, G, res.V, 1, X, res.log_vectors, 100, 1)
    V, before, after = _exact_refine(metric, res.mean, G, V_tilted, 1, X, res.log_vectors, 100, 15)
    print(f"tilted start: cost {before:.6f} -> {after:.6f} (tangent PCA {tangent_cost:.6f})")
    assert before > 1.1 * tangent_cost
    assert after < 1.01 * tangent_cost
    np.testing.assert_allclose(V.T @ G @ V, np.eye(1), atol=1e-10)
    assert g_angles_deg(G, V, res.V[:, :1]).max() < 5.0
