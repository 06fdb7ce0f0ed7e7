"""Tests of geosyn.synergies.synergy: GeodesicSynergy and combine (paper section 2.2)."""

from __future__ import annotations

import numpy as np
import pytest

import geosyn.synergies as synergies_pkg
import geosyn.synergies.synergy as synergy_mod
from conftest import get_metric
from geosyn.core import InvalidArgument
from geosyn.metrics.errors import GeodesicNotFound
from geosyn.metrics.geodesic import exp, log
from geosyn.synergies import (
    GeodesicSynergy,
    InvalidSynergyInput,
    SynergyError,
    SynergyNotConverged,
    combine,
    transported_velocities,
)
from geosyn.synergies.synergy import checked_log

RESIDUAL_STEPS = 5000  # h = 2e-4 s: central-difference truncation h^2/6 |d3 q|, |d4 q| < 1e-6


def geodesic_residuals(metric, traj) -> tuple[float, float, float, float]:
    """Check a sampled trajectory against the geodesic equation with independent parts.

    G(q) from Pinocchio's CRBA, c(q, v) from its RNEA (no gravity): independent of the
    compiled ABA-based RK4 that produced the samples.

    Returns:
        (r_v, b_v, r_a, b_a): max ||v - D_h q|| and its truncation budget, max
        ||G D_h v + c|| and its budget, where D_h is the central difference with step h
        and the budget is |D_h - D_2h| / 3 (the O(h^2) truncation of D_h, estimated
        from the step, since D_2h's truncation is four times D_h's).
    """
    h = traj.t[1] - traj.t[0]
    q, v = traj.q, traj.v
    i = np.arange(2, len(traj.t) - 2)
    dq_h = (q[i + 1] - q[i - 1]) / (2 * h)
    dq_2h = (q[i + 2] - q[i - 2]) / (4 * h)
    dv_h = (v[i + 1] - v[i - 1]) / (2 * h)
    dv_2h = (v[i + 2] - v[i - 2]) / (4 * h)
    r_v = np.max(np.linalg.norm(v[i] - dq_h, axis=1))
    b_v = np.max(np.linalg.norm(dq_h - dq_2h, axis=1)) / 3
    res, bud = [], []
    for j, k in enumerate(i):
        G = metric.G(q[k])
        c = metric.coriolis(q[k], v[k])
        res.append(np.linalg.norm(G @ dv_h[j] + c))
        bud.append(np.linalg.norm(G @ (dv_h[j] - dv_2h[j])) / 3)
    return r_v, b_v, max(res), max(bud)


def random_synergies(metric, rng, m, q0=None, spread=0.0):
    n = metric.n
    base = rng.uniform(-1.0, 1.0, n) if q0 is None else q0
    return [
        GeodesicSynergy(metric, base + spread * rng.uniform(-1, 1, n), rng.normal(0, 0.5, n))
        for _ in range(m)
    ]


def test_all_names_resolve():
    for name in synergies_pkg.__all__:
        assert getattr(synergies_pkg, name) is not None


def test_synergy_trajectory_is_exp_and_arrays_frozen():
    metric = get_metric("planar3")
    s = GeodesicSynergy(metric, [0.1, 0.2, 0.3], [0.5, -0.2, 0.1])
    ref = exp(metric, np.array([0.1, 0.2, 0.3]), np.array([0.5, -0.2, 0.1]), 0.7, 50)
    tr = s.trajectory(duration=0.7, steps=50)
    np.testing.assert_array_equal(tr.q, ref.q)
    np.testing.assert_array_equal(tr.v, ref.v)
    assert s.q0.dtype == np.float64 and not s.q0.flags.writeable
    with pytest.raises(ValueError):
        s.v0[0] = 1.0


@pytest.mark.parametrize("name", ["planar3", "panda"])
def test_common_base_combination_is_exp_of_weighted_sum(name):
    metric = get_metric(name)
    rng = np.random.default_rng(1)
    syns = random_synergies(metric, rng, 3)
    w = np.array([0.7, -1.3, 0.4])
    c = combine(syns, w)
    v_sum = w[0] * syns[0].v0 + w[1] * syns[1].v0 + w[2] * syns[2].v0
    ref = exp(metric, syns[0].q0.copy(), v_sum, 1.0, 100)
    got = c.trajectory()
    np.testing.assert_allclose(c.q0, syns[0].q0, rtol=0, atol=0)
    np.testing.assert_allclose(got.q, ref.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.v, ref.v, rtol=0, atol=1e-12)


def test_common_base_within_tolerance_skips_transport():
    metric = get_metric("planar3")
    rng = np.random.default_rng(2)
    a, b = random_synergies(metric, rng, 2)
    b_near = GeodesicSynergy(metric, a.q0 + 5e-13, b.v0)
    V = transported_velocities([a, b_near], a.q0)
    np.testing.assert_array_equal(V[:, 1], b.v0)


def test_combined_trajectory_satisfies_geodesic_equation():
    metric = get_metric("planar3")
    rng = np.random.default_rng(3)
    syns = random_synergies(metric, rng, 2, spread=0.3)
    q_start = syns[0].q0 + np.array([0.1, -0.2, 0.15])
    c = combine(syns, [0.8, -0.6], q_start)
    traj = c.trajectory(duration=1.0, steps=RESIDUAL_STEPS)
    r_v, b_v, r_a, b_a = geodesic_residuals(metric, traj)
    print(f"v residual {r_v:.2e} (budget {b_v:.2e}); G a + c residual {r_a:.2e} (budget {b_a:.2e})")
    assert r_a <= 1e-6 and r_v <= 1e-6
    # The residuals are the finite-difference truncation itself, nothing more.
    assert r_v <= 1.5 * b_v + 1e-10
    assert r_a <= 1.5 * b_a + 1e-9
    # Control: a perturbed (non-geodesic) path fails the same check by far.
    bent = traj._replace(
        q=traj.q + 1e-3 * np.sin(np.pi * traj.t)[:, None],
        v=traj.v + 1e-3 * np.pi * np.cos(np.pi * traj.t)[:, None],
    )
    assert geodesic_residuals(metric, bent)[2] > 1e-4


def test_transported_combination_is_geodesic_from_q_start_and_differs_from_naive():
    metric = get_metric("panda")
    rng = np.random.default_rng(4)
    q_base = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    syns = [
        GeodesicSynergy(metric, q_base + rng.uniform(-0.4, 0.4, 7), rng.normal(0, 0.4, 7))
        for _ in range(2)
    ]
    q_start = q_base.copy()
    w = np.array([1.0, 0.5])
    c = combine(syns, w, q_start)
    np.testing.assert_array_equal(c.q0, q_start)
    traj = c.trajectory(steps=RESIDUAL_STEPS)
    np.testing.assert_allclose(traj.q[0], q_start, atol=0)
    r_v, _, r_a, _ = geodesic_residuals(metric, traj)
    assert r_v <= 1e-6 and r_a <= 1e-6
    naive = w[0] * syns[0].v0 + w[1] * syns[1].v0
    G = metric.G(q_start)
    diff = np.sqrt((c.v0 - naive) @ G @ (c.v0 - naive)) / np.sqrt(c.v0 @ G @ c.v0)
    end_gap = np.linalg.norm(traj.q[-1] - exp(metric, q_start, naive).q[-1])
    print(
        f"transport vs naive sum: relative G-norm difference of v0 {diff:.3%}, "
        f"endpoint gap {end_gap:.4f} rad"
    )
    assert diff > 1e-3 and end_gap > 1e-4


def test_transport_preserves_inner_products_and_moves_geodesic_velocity():
    """Transport is an isometry, and a geodesic's own velocity transports to its end velocity."""
    metric = get_metric("planar3")
    rng = np.random.default_rng(5)
    q_a = np.array([0.2, 0.9, -0.4])
    q_b = np.array([-0.3, 1.4, 0.2])
    u = log(metric, q_a, q_b)
    end_velocity = exp(metric, q_a, u, 1.0, 100).v[-1]
    syns = [GeodesicSynergy(metric, q_a, u)] + [
        GeodesicSynergy(metric, q_a, rng.normal(0, 1, 3)) for _ in range(2)
    ]
    V0 = np.column_stack([s.v0 for s in syns])
    Vt = transported_velocities(syns, q_b)
    np.testing.assert_allclose(Vt[:, 0], end_velocity, rtol=0, atol=1e-7)
    gram0 = V0.T @ metric.G(q_a) @ V0
    gram1 = Vt.T @ metric.G(q_b) @ Vt
    np.testing.assert_allclose(gram1, gram0, rtol=0, atol=1e-7 * np.abs(gram0).max())


def test_bad_input_errors():
    metric = get_metric("planar2")
    other = get_metric("planar3")
    s = GeodesicSynergy(metric, [0.0, 1.0], [1.0, 0.0])
    with pytest.raises(InvalidSynergyInput, match="one weight per synergy") as info:
        combine([s, s], [1.0])
    assert info.value.argument == "weights"
    with pytest.raises(InvalidSynergyInput, match=r"q_start must have shape \(2,\)") as info:
        combine([s], [1.0], q_start=[0.0, 0.0, 0.0])
    assert info.value.argument == "q_start"
    with pytest.raises(InvalidSynergyInput, match=r"v0 must have shape \(2,\)"):
        GeodesicSynergy(metric, [0.0, 1.0], [1.0, 0.0, 0.0])
    with pytest.raises(InvalidSynergyInput, match="share one metric"):
        combine([s, GeodesicSynergy(other, [0.0] * 3, [1.0] * 3)], [1.0, 1.0])
    with pytest.raises(InvalidSynergyInput, match="at least one"):
        combine([], [])
    with pytest.raises(InvalidSynergyInput, match="finite"):
        combine([s], [np.nan])
    with pytest.raises(InvalidSynergyInput, match="Metric"):
        GeodesicSynergy("planar2", [0.0, 1.0], [1.0, 0.0])
    for exc in (InvalidSynergyInput, SynergyNotConverged):
        assert issubclass(exc, SynergyError)
    assert issubclass(InvalidSynergyInput, InvalidArgument)


def test_non_converging_log_is_a_clear_error(monkeypatch):
    metric = get_metric("planar2")
    q_a, q_b = np.array([0.0, 0.5]), np.array([2.0, -1.0])
    with pytest.raises(SynergyNotConverged, match="no geodesic found") as info:
        checked_log(metric, q_a, q_b, max_iter=1, tol=1e-300)
    err = info.value
    assert isinstance(err.__cause__, GeodesicNotFound)
    assert err.residual == err.__cause__.residual
    assert err.residual > 0 and "residual" in str(err)
    np.testing.assert_array_equal(err.q_from, q_a)
    np.testing.assert_array_equal(err.q_to, q_b)

    def failing_log(metric, q0, q1, **kw):
        kw.update(max_iter=1, tol=1e-300)
        return log(metric, q0, q1, **kw)

    monkeypatch.setattr(synergy_mod, "log", failing_log)
    s = GeodesicSynergy(metric, q_a, [1.0, 0.0])
    with pytest.raises(SynergyNotConverged, match="no geodesic found"):
        combine([s], [1.0], q_start=q_b)
