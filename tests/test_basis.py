"""Tests of geosyn.synergies.basis: G-orthonormal synergy bases."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.metrics.base import Metric
from geosyn.synergies import InvalidSynergyInput, orthonormal_synergies


class ConstantMetric(Metric):
    """A constant SPD metric without a robot (exercises the joint-speed ordering)."""

    def __init__(self, A: np.ndarray) -> None:
        self.A = np.asarray(A, dtype=np.float64)
        self.n = self.A.shape[0]

    def G(self, q):
        return self.A.copy()

    def symbolic_G(self, q):
        return ca.SX(ca.DM(self.A))


def fd_position_jacobian(robot, q, frame, eps=1e-6):
    """Central finite-difference Jacobian of a frame position (independent of pin's J)."""
    data = robot.model.createData()
    fid = robot.frame_id(frame)

    def pos(x):
        pin.framesForwardKinematics(robot.model, data, x)
        return data.oMf[fid].translation.copy()

    return np.column_stack(
        [(pos(q + eps * e) - pos(q - eps * e)) / (2 * eps) for e in np.eye(q.size)]
    )


@pytest.mark.parametrize("name", ["planar3", "panda", "talos_arm"])
def test_orthonormal_and_complete(name):
    metric, robot = get_metric(name), get_robot(name)
    rng = np.random.default_rng(0)
    q0 = robot.random_q(rng)
    n = metric.n
    basis = orthonormal_synergies(metric, q0, n)
    G = metric.G(q0)
    np.testing.assert_allclose(basis.V.T @ G @ basis.V, np.eye(n), rtol=0, atol=1e-10)
    for _ in range(5):
        v = rng.normal(0, 1, n)
        w = np.linalg.solve(basis.V, v)  # weights reproducing v
        np.testing.assert_allclose(basis.V @ w, v, rtol=0, atol=1e-10)
        np.testing.assert_allclose(w, basis.V.T @ G @ v, rtol=0, atol=1e-10 * np.abs(w).max())
    assert [s.v0.tolist() for s in basis.synergies] == basis.V.T.tolist()
    assert all(np.array_equal(s.q0, q0) for s in basis.synergies)


@pytest.mark.parametrize("name", ["planar3", "panda"])
def test_ordering_matches_end_effector_criterion(name):
    """Scores are the eigenvalues of G^-1 J^T J (J by finite differences), decreasing."""
    metric, robot = get_metric(name), get_robot(name)
    q0 = robot.random_q(np.random.default_rng(1))
    basis = orthonormal_synergies(metric, q0, metric.n)
    J = fd_position_jacobian(robot, q0, robot.ee_frame)
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(metric.G(q0), J.T @ J)).real)[::-1]
    np.testing.assert_allclose(basis.scores, lam, rtol=1e-6, atol=1e-8 * lam[0])
    np.testing.assert_allclose(
        np.sum((J @ basis.V) ** 2, axis=0), lam, rtol=1e-6, atol=1e-8 * lam[0]
    )
    rank = min(3 if name != "planar3" else 2, metric.n)
    # Columns beyond the rank of J do not move the frame; they are ordered by joint speed.
    assert np.all(np.abs(J @ basis.V[:, rank:]) < 1e-6)
    joint_speed = np.sum(basis.V[:, rank:] ** 2, axis=0)
    assert np.all(np.diff(joint_speed) <= 1e-12)
    # Deterministic (signs included): the same call gives the same basis.
    again = orthonormal_synergies(metric, q0, metric.n)
    np.testing.assert_array_equal(again.V, basis.V)
    assert np.all(basis.V[np.argmax(np.abs(basis.V), axis=0), np.arange(metric.n)] > 0)
    k3 = orthonormal_synergies(metric, q0, 2)
    np.testing.assert_array_equal(k3.V, basis.V[:, :2])


def test_directions_are_g_orthonormalized_in_order():
    metric, robot = get_metric("panda"), get_robot("panda")
    rng = np.random.default_rng(2)
    q0 = robot.random_q(rng)
    D = rng.normal(0, 1, (7, 4))
    basis = orthonormal_synergies(metric, q0, 3, directions=D)
    G = metric.G(q0)
    V = basis.V
    assert V.shape == (7, 3)
    np.testing.assert_allclose(V.T @ G @ V, np.eye(3), rtol=0, atol=1e-10)
    # Gram-Schmidt: D[:, :3] = V R with R upper triangular, positive diagonal.
    R = V.T @ G @ D[:, :3]
    np.testing.assert_allclose(np.tril(R, -1), 0, atol=1e-10)
    assert np.all(np.diag(R) > 0)
    np.testing.assert_allclose(V @ R, D[:, :3], rtol=0, atol=1e-10)


def test_constant_metric_without_robot_orders_by_joint_speed():
    A = np.array([[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 0.5]])
    metric = ConstantMetric(A)
    basis = orthonormal_synergies(metric, np.zeros(3), 3)
    np.testing.assert_allclose(basis.V.T @ A @ basis.V, np.eye(3), atol=1e-12)
    # ||v||^2 for G-unit v are the eigenvalues of A^-1, decreasing.
    np.testing.assert_allclose(basis.scores, np.sort(1 / np.linalg.eigvalsh(A))[::-1], rtol=1e-12)


def test_bad_input():
    metric = get_metric("planar3")
    q0 = np.array([0.1, 0.2, 0.3])
    with pytest.raises(InvalidSynergyInput, match=r"k must be an integer in \[1, 3\]"):
        orthonormal_synergies(metric, q0, 4)
    with pytest.raises(InvalidSynergyInput, match="k must"):
        orthonormal_synergies(metric, q0, 0)
    with pytest.raises(InvalidSynergyInput, match=r"q0 must have shape \(3,\)"):
        orthonormal_synergies(metric, [0.0, 0.0], 2)
    with pytest.raises(InvalidSynergyInput, match=r"directions must have shape \(3, m\)"):
        orthonormal_synergies(metric, q0, 2, directions=np.ones((2, 2)))
    with pytest.raises(InvalidSynergyInput, match="m >= k"):
        orthonormal_synergies(metric, q0, 3, directions=np.eye(3)[:, :2])
    D = np.array([[1.0, 2.0, 0.0], [0.0, 0.0, 1.0], [1.0, 2.0, 0.0]])
    with pytest.raises(InvalidSynergyInput, match=r"directions\[:, 1\]") as info:
        orthonormal_synergies(metric, q0, 3, directions=D)
    assert info.value.index == 1 and info.value.argument == "directions"
    with pytest.raises(InvalidSynergyInput, match="linearly dependent") as info:
        orthonormal_synergies(metric, q0, 1, directions=np.zeros((3, 1)))
    assert info.value.index == 0
    with pytest.raises(InvalidSynergyInput, match="nv"):
        orthonormal_synergies(metric, q0, 2, robot=get_robot("planar2"))
