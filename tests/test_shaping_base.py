"""ShapedMetric and MetricTerm: sums, symmetry, definiteness, Christoffel symbols, hooks."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import geosyn.metrics.shaping as shaping
from conftest import get_metric, get_robot
from geosyn.core import InvalidArgument
from geosyn.metrics.base import Metric
from geosyn.metrics.derived import christoffel_from_dG
from geosyn.metrics.shaping import (
    InvalidTermArgument,
    JointLimitTerm,
    LoadTerm,
    MetricTerm,
    ObstacleTerm,
    ShapedMetric,
    TermAlreadyBound,
    TermNotBound,
)
from geosyn.metrics.shaping.obstacle import PARAMS_PER_OBSTACLE, PROFILE_PARAMS
from geosyn.world import Box, Capsule, HalfSpace, Sphere


def _fd_dG(metric, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central finite differences ``[i, j, k] = d g_ij / d q_k`` of ``metric.G``."""
    n = q.size
    out = np.zeros((n, n, n))
    for k in range(n):
        e = np.zeros(n)
        e[k] = h
        out[:, :, k] = (metric.G(q + e) - metric.G(q - e)) / (2 * h)
    return out


def _panda_terms() -> list[MetricTerm]:
    obstacles = [
        Sphere((0.45, 0.15, 0.45), 0.08),
        Box((0.3, -0.35, 0.3), (0.05, 0.08, 0.1), _rotation_z(0.4)),
        Capsule((0.5, -0.2, 0.7), (0.5, 0.2, 0.75), 0.04),
        HalfSpace((0.0, 0.0, 1.0), 0.0),
    ]
    return [
        LoadTerm("panda_hand_tcp", 1.0, (0.0, 0.0, 0.05), np.diag([0.01, 0.012, 0.008])),
        ObstacleTerm(obstacles, capacity=4, gain=1e-3, cutoff=0.3),
        JointLimitTerm(margin=0.3, gain=1e-3),
    ]


def _rotation_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _shaped_panda() -> ShapedMetric:
    return ShapedMetric(get_metric("panda"), _panda_terms())


@pytest.fixture(scope="module")
def shaped_panda() -> ShapedMetric:
    return _shaped_panda()


def test_all_names_resolve() -> None:
    for name in shaping.__all__:
        assert getattr(shaping, name) is not None


def test_derived_quantities_come_from_metric() -> None:
    """ShapedMetric supplies G and its symbolic form; the derived quantities are Metric's."""
    for name in ("dG", "christoffel", "coriolis", "geodesic_acceleration", "inner", "norm"):
        assert getattr(ShapedMetric, name) is getattr(Metric, name), name


def test_no_terms_equals_base_metric() -> None:
    base = get_metric("panda")
    shaped = ShapedMetric(base, [])
    rng = np.random.default_rng(10)
    for _ in range(5):
        q = get_robot("panda").random_q(rng)
        v = rng.normal(size=7)
        np.testing.assert_array_equal(shaped.G(q), base.G(q))
        np.testing.assert_allclose(shaped.christoffel(q), base.christoffel(q), atol=1e-12)
        np.testing.assert_allclose(
            shaped.geodesic_acceleration(q, v), base.geodesic_acceleration(q, v), atol=1e-9
        )
    assert shaped.symbolic_parameters().shape == (0, 1)
    assert shaped.parameter_values().shape == (0,)


def test_terms_symmetric_psd_and_shaped_metric_spd(shaped_panda: ShapedMetric) -> None:
    robot = get_robot("panda")
    rng = np.random.default_rng(11)
    nonzero = [0] * len(shaped_panda.terms)
    for _ in range(30):
        q = robot.random_q(rng)
        for i, term in enumerate(shaped_panda.terms):
            g = term.G(q)
            scale = max(np.abs(g).max(), 1.0)
            assert np.abs(g - g.T).max() <= 1e-14 * scale
            assert np.linalg.eigvalsh(g)[0] >= -1e-12 * scale
            nonzero[i] += np.abs(g).max() > 1e-9
        G = shaped_panda.G(q)
        assert np.abs(G - G.T).max() <= 1e-12 * np.abs(G).max()
        eig = np.linalg.eigvalsh(G)
        assert eig[0] > 0.0
        # The sum is base + terms, term by term.
        total = get_metric("panda").G(q) + sum(t.G(q) for t in shaped_panda.terms)
        np.testing.assert_allclose(G, total, rtol=0, atol=1e-12 * np.abs(G).max())
    # Every term is active somewhere among the samples (the checks above are not vacuous).
    assert all(k > 0 for k in nonzero), nonzero


def _clear_configurations(shaped: ShapedMetric, count: int, seed: int) -> list[np.ndarray]:
    """Configurations with every sphere clear of every obstacle by 2 cm (no clamping)."""
    robot = shaped.robot
    obstacle_term = next(t for t in shaped.terms if isinstance(t, ObstacleTerm))
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        q = robot.random_q(rng, margin=0.05)
        if obstacle_term.min_clearance(q) > 0.02:
            out.append(q)
    return out


def test_christoffel_against_finite_differences(shaped_panda: ShapedMetric) -> None:
    for q in _clear_configurations(shaped_panda, 8, seed=12):
        dG_fd = _fd_dG(shaped_panda, q)
        gam = shaped_panda.christoffel(q)
        scale = max(1.0, np.abs(gam).max())
        assert np.abs(gam - christoffel_from_dG(dG_fd)).max() <= 1e-6 * scale
        assert np.abs(shaped_panda.dG(q) - dG_fd).max() <= 1e-6 * scale
        # Symmetric in the last two indices.
        assert np.abs(gam - gam.transpose(0, 2, 1)).max() <= 1e-12 * scale


def test_coriolis_and_geodesic_acceleration_consistent(shaped_panda: ShapedMetric) -> None:
    rng = np.random.default_rng(13)
    for q in _clear_configurations(shaped_panda, 5, seed=13):
        v = rng.normal(size=7)
        c = shaped_panda.coriolis(q, v)
        gam = shaped_panda.christoffel(q)
        np.testing.assert_allclose(
            c, np.einsum("ijk,j,k->i", gam, v, v), atol=1e-9 * max(1.0, np.abs(c).max())
        )
        a = shaped_panda.geodesic_acceleration(q, v)
        np.testing.assert_allclose(shaped_panda.G(q) @ a, -c, atol=1e-8 * max(1.0, np.abs(c).max()))


def test_planar2_christoffel_in_plane_of_obstacle() -> None:
    """A planar scene puts sphere centres exactly in the obstacle's plane (a tie case)."""
    robot = get_robot("planar2")
    term = ObstacleTerm([Sphere((1.2, 0.6, 0.0), 0.15)], capacity=2, gain=1e-2, cutoff=0.5)
    shaped = ShapedMetric(get_metric("planar2"), [term])
    for q in _clear_configurations(shaped, 10, seed=14):
        gam = shaped.christoffel(q)
        scale = max(1.0, np.abs(gam).max())
        assert np.abs(gam - christoffel_from_dG(_fd_dG(shaped, q))).max() <= 1e-6 * scale
    assert robot.nv == 2


def test_velocity_gated_coriolis_follows_frozen_velocity_definition() -> None:
    """c(q, v) = d(G(q, u) u)/dq u - 1/2 d(u^T G(q, u) u)/dq at u = v (u frozen)."""
    term = ObstacleTerm(
        [Sphere((1.2, 0.6, 0.0), 0.15)],
        capacity=1,
        gain=1e-2,
        cutoff=0.6,
        gate="approach",
        gate_speed=0.5,
    )
    shaped = ShapedMetric(get_metric("planar2"), [term])
    assert shaped.velocity_dependent
    rng = np.random.default_rng(15)
    checked = 0
    for q in _clear_configurations(shaped, 20, seed=15):
        v = rng.normal(size=2)
        gt = term.G(q, v)
        if np.abs(gt).max() < 1e-6:
            continue
        checked += 1
        h = 1e-6
        dG = np.zeros((2, 2, 2))
        for k in range(2):
            e = np.zeros(2)
            e[k] = h
            dG[:, :, k] = (shaped.G(q + e, v) - shaped.G(q - e, v)) / (2 * h)
        c_ref = np.einsum("ijk,j,k->i", christoffel_from_dG(dG), v, v)
        c = shaped.coriolis(q, v)
        assert np.abs(c - c_ref).max() <= 1e-6 * max(1.0, np.abs(c).max())
        a = shaped.geodesic_acceleration(q, v)
        np.testing.assert_allclose(shaped.G(q, v) @ a, -c, atol=1e-9 * max(1.0, np.abs(c).max()))
    assert checked >= 3


def test_parameter_hook_and_symbolic_functions(shaped_panda: ShapedMetric) -> None:
    obstacle_term = shaped_panda.terms[1]
    p = shaped_panda.symbolic_parameters()
    assert p.shape == (obstacle_term.capacity * PARAMS_PER_OBSTACLE + PROFILE_PARAMS, 1)
    assert np.array_equal(shaped_panda.parameter_values(), obstacle_term.parameter_values())
    # A geodesic integrator built from the symbolic form with the hook reproduces the
    # numeric geodesic acceleration.
    q = ca.SX.sym("q", 7)
    v = ca.SX.sym("v", 7)
    f = ca.Function("a", [q, v, p], [shaped_panda.symbolic_geodesic_acceleration(q, v)])
    rng = np.random.default_rng(16)
    q0 = get_robot("panda").random_q(rng)
    v0 = rng.normal(size=7)
    a_ref = shaped_panda.geodesic_acceleration(q0, v0)
    a = np.asarray(f(q0, v0, shaped_panda.parameter_values())).ravel()
    np.testing.assert_allclose(a, a_ref, atol=1e-9 * max(1.0, np.abs(a_ref).max()))


def test_compiled_functions_match_uncompiled() -> None:
    term = ObstacleTerm([Sphere((1.2, 0.6, 0.0), 0.15)], capacity=2, gain=1e-2, cutoff=0.5)
    plain = ShapedMetric(get_metric("planar2"), [term])
    compiled = ShapedMetric(get_metric("planar2"), [term], compile=True)
    for q in _clear_configurations(plain, 3, seed=17):
        v = np.array([0.3, -0.8])
        np.testing.assert_allclose(compiled.G(q), plain.G(q), atol=1e-12)
        np.testing.assert_allclose(compiled.christoffel(q), plain.christoffel(q), atol=1e-9)
        np.testing.assert_allclose(
            compiled.geodesic_acceleration(q, v), plain.geodesic_acceleration(q, v), atol=1e-9
        )


def test_bad_arguments_raise() -> None:
    with pytest.raises(InvalidTermArgument, match="base"):
        ShapedMetric("not a metric", [])  # type: ignore[arg-type]
    with pytest.raises(InvalidTermArgument, match=r"terms\[0\]"):
        ShapedMetric(get_metric("panda"), [object()])  # type: ignore[list-item]
    with pytest.raises(TermNotBound, match="bind"):
        JointLimitTerm().G(np.zeros(7))
    term = LoadTerm("tip", 1.0)
    ShapedMetric(get_metric("planar2"), [term])
    with pytest.raises(TermAlreadyBound, match="planar2"):
        term.bind(get_robot("planar3"))
    shaped = _shaped_panda()
    with pytest.raises(InvalidArgument, match=r"q must have shape \(7,\)"):
        shaped.G(np.zeros(6))
    with pytest.raises(InvalidArgument, match="finite"):
        shaped.christoffel(np.full(7, np.nan))
