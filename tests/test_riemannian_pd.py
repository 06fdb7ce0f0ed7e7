"""Tests of geosyn.controllers.riemannian_pd: tracking, the Lyapunov function, inputs."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers import GeodesicReference, JointTrajectoryReference
from geosyn.controllers.plant import PinocchioPlant
from geosyn.controllers.riemannian_pd import RiemannianPD
from geosyn.core import InvalidArgument
from geosyn.synergies import GeodesicSynergy

Q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
V0 = 0.5 * np.array([1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
LAM, K = 20.0, 50.0


@pytest.fixture(scope="module")
def synergy_reference():
    synergy = GeodesicSynergy(get_metric("panda"), Q0, V0)
    return GeodesicReference(synergy, duration=1.5, steps=150)


def _run(ctl, ref, q0, v0, duration, payload=None):
    plant = PinocchioPlant(ctl.robot, payload=payload)
    plant.reset(q0, v0)
    ctl.reset(q0, v0)
    V = []
    ro = plant.rollout(
        ctl, duration, callback=lambda t, q, v, tau: V.append(ctl.diagnostics.extra["lyapunov"])
    )
    V.append(ctl.lyapunov(ro.t[-1], ro.q[-1], ro.v[-1]))
    err = ro.q - np.array([ref.sample(t).q for t in ro.t])
    return ro, err, np.array(V)


@pytest.mark.parametrize("payload, bound", [(None, 1e-3), (("panda_hand_tcp", 1.0), 2e-2)])
def test_tracks_panda_synergy_with_bounded_error(synergy_reference, payload, bound):
    ref = synergy_reference
    ctl = RiemannianPD(get_robot("panda"), LAM, K, reference=ref)
    q0, v0, _ = ref.sample(0.0)
    _, err, V = _run(ctl, ref, q0, v0, 1.5, payload)
    rms = np.sqrt(np.mean(err**2))
    assert rms <= bound, rms
    # Bounded: the error does not grow towards the end of the motion.
    assert np.abs(err[-300:]).max() <= 2.0 * np.abs(err[:-300]).max() + 1e-9
    assert np.all(np.isfinite(V))


def test_lyapunov_function_decreases_from_initial_error(synergy_reference):
    """V = 1/2 s^T M s + e^T Lambda K e decreases monotonically along the closed loop,
    at the rate predicted by the docstring, and the error converges."""
    ref = synergy_reference
    robot = get_robot("panda")
    lam = np.array([15.0, 15.0, 20.0, 20.0, 25.0, 25.0, 25.0])
    k = np.array([60.0, 60.0, 40.0, 40.0, 10.0, 10.0, 10.0])
    ctl = RiemannianPD(robot, lam, k, reference=ref)
    q_ref0, v_ref0, _ = ref.sample(0.0)
    e0 = np.array([0.05, -0.04, 0.03, 0.05, -0.05, 0.04, 0.05])
    ro, err, V = _run(ctl, ref, q_ref0 + e0, v_ref0 + 0.2, 1.0)
    assert V[0] > 0.0
    dV = np.diff(V)
    assert np.all(dV <= 1e-9 * V[0]), dV.max()
    assert V[-1] < 1e-4 * V[0]
    assert np.abs(err[-1]).max() < 1e-3 * np.abs(e0).max()
    # dV/dt = -(edot^T K edot + e^T Lambda K Lambda e) along the exact closed loop.
    for i in (10, 100, 300):
        t, q, v = ro.t[i], ro.q[i], ro.v[i]
        q_r, v_r, _ = ref.sample(t)
        e, edot = q - q_r, v - v_r
        rate = -(edot @ (k * edot) + e @ (lam * k * lam * e))
        numeric = (V[i + 1] - V[i - 1]) / (ro.t[i + 1] - ro.t[i - 1])
        assert numeric == pytest.approx(rate, rel=2e-2), (i, numeric, rate)


def test_torque_is_slotine_li_law():
    """tau = M a_r + C(q, v) v_r + g - K s, assembled independently of the controller."""
    robot = get_robot("panda")
    model, data = robot.model, robot.model.createData()
    rng = np.random.default_rng(5)
    ref = JointTrajectoryReference(
        np.array([0.0, 1.0]), np.stack([robot.random_q(rng, 0.3), robot.random_q(rng, 0.3)])
    )
    lam, k = rng.uniform(5, 20, 7), rng.uniform(1, 30, 7)
    ctl = RiemannianPD(robot, lam, k, reference=ref)
    q, v = robot.random_q(rng, 0.3), rng.normal(size=7)
    q_ref, v_ref, a_ref = ref.sample(0.4)
    v_r = v_ref - lam * (q - q_ref)
    a_r = a_ref - lam * (v - v_ref)
    s = v - v_r
    M = pin.crba(model, data, q)
    C = pin.computeCoriolisMatrix(model, data, q, v)
    g = pin.computeGeneralizedGravity(model, data, q)
    expected = M @ a_r + C @ v_r + g - k * s
    tau = ctl.compute(0.4, q, v)
    np.testing.assert_allclose(ctl.last_unclipped_torque, expected, atol=1e-9)
    np.testing.assert_allclose(tau, np.clip(expected, -robot.tau_max, robot.tau_max), atol=1e-9)
    V = 0.5 * s @ M @ s + (q - q_ref) @ (lam * k * (q - q_ref))
    assert ctl.diagnostics.extra["lyapunov"] == pytest.approx(V, rel=1e-12)
    assert ctl.lyapunov(0.4, q, v) == pytest.approx(V, rel=1e-12)


def test_coriolis_matrix_is_christoffel_and_mdot_minus_2c_is_skew():
    """The stability argument's assumptions: C_ij = sum_k Gamma_ijk v_k for the metric's
    Christoffel symbols, and Mdot - 2C skew-symmetric (Mdot by finite differences)."""
    robot = get_robot("planar3")
    metric = get_metric("planar3")
    model, data = robot.model, robot.model.createData()
    rng = np.random.default_rng(2)
    for _ in range(3):
        q, v = robot.random_q(rng), rng.normal(size=3)
        C = pin.computeCoriolisMatrix(model, data, q, v).copy()
        gamma = metric.christoffel(q)
        np.testing.assert_allclose(C, np.einsum("ijk,k->ij", gamma, v), atol=1e-9)
        h = 1e-6
        Mdot = (pin.crba(model, data, q + h * v) - pin.crba(model, data, q - h * v)) / (2 * h)
        N = Mdot - 2 * C
        np.testing.assert_allclose(N, -N.T, atol=1e-7)


@pytest.mark.parametrize(
    "lam, k, match",
    [
        (np.ones(3), 1.0, r"lam must be a scalar or an array of shape \(7,\)"),
        (1.0, -1.0, "k must be finite and >= 0"),
        (np.inf, 1.0, "lam must be finite"),
    ],
)
def test_rejects_bad_gains(lam, k, match):
    with pytest.raises(InvalidArgument, match=match):
        RiemannianPD(get_robot("panda"), lam, k)


def test_rejects_reference_of_wrong_dimension():
    ctl = RiemannianPD(get_robot("panda"), LAM, K)
    ref = JointTrajectoryReference(np.array([0.0, 1.0]), np.zeros((2, 3)))
    with pytest.raises(InvalidArgument, match="dimension 3.*nv=7"):
        ctl.set_reference(ref)
