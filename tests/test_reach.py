"""Tests of geosyn.synergies.reach: synergy weights that reach a Cartesian target."""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.metrics.geodesic import exp
from geosyn.robots.errors import UnknownFrame
from geosyn.synergies import (
    GeodesicSynergy,
    InvalidSynergyInput,
    orthonormal_synergies,
    reach,
)

Q_PANDA = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])


def fk(robot, q, frame):
    """Frame position by Pinocchio's framesForwardKinematics (reference)."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.frame_id(frame)].translation.copy()


@pytest.mark.slow
def test_reaches_20_seeded_targets_within_1mm():
    metric, robot = get_metric("panda"), get_robot("panda")
    basis = orthonormal_synergies(metric, Q_PANDA, 7)
    frame = robot.ee_frame
    rng = np.random.default_rng(0)
    errors, starts = [], []
    t0 = time.perf_counter()
    for _ in range(20):
        w_true = rng.normal(0, 0.5, 7)
        target = fk(robot, exp(metric, Q_PANDA, basis.V @ w_true).q[-1], frame)
        res = reach(basis.synergies, target, frame, robot)
        # Independent checks of what was returned: FK of the trajectory's end and the
        # trajectory is the geodesic of the weighted sum.
        np.testing.assert_allclose(fk(robot, res.trajectory.q[-1], frame), res.position, atol=1e-12)
        ref = exp(metric, Q_PANDA, basis.V @ res.weights)
        np.testing.assert_allclose(res.trajectory.q, ref.q, atol=1e-12)
        err = np.linalg.norm(fk(robot, ref.q[-1], frame) - target)
        assert err <= 1e-3 and res.converged
        assert abs(err - res.error) < 1e-12
        errors.append(err)
        starts.append(res.starts)
    print(
        f"reach: 20 targets in {time.perf_counter() - t0:.2f} s, max error "
        f"{max(errors) * 1e3:.2e} mm, solves per target {starts}"
    )


def test_reach_from_another_start_transports_synergies():
    metric, robot = get_metric("panda"), get_robot("panda")
    basis = orthonormal_synergies(metric, Q_PANDA, 4)
    q_start = Q_PANDA + np.array([0.2, 0.1, -0.1, 0.15, 0.0, -0.1, 0.1])
    target = fk(robot, q_start, robot.ee_frame) + np.array([0.05, -0.04, 0.03])
    res = reach(basis.synergies, target, robot.ee_frame, robot, q_start=q_start, duration=0.8)
    np.testing.assert_array_equal(res.trajectory.q[0], q_start)
    assert res.trajectory.t[-1] == pytest.approx(0.8)
    assert res.error <= 1e-3


def test_unreachable_target_is_reported_not_raised():
    metric, robot = get_metric("planar2"), get_robot("planar2")
    basis = orthonormal_synergies(metric, np.array([0.3, 0.9]), 2)
    res = reach(basis.synergies, [5.0, 0.0, 0.0], "tip", robot, restarts=1)
    assert not res.converged and res.starts == 2
    # Best possible is the workspace boundary at 2 m from the base: 3 m away.
    assert res.error >= 3.0 - 1e-6
    assert res.error == pytest.approx(np.linalg.norm(res.position - [5.0, 0.0, 0.0]))


def test_bad_input():
    metric, robot = get_metric("planar2"), get_robot("planar2")
    s = GeodesicSynergy(metric, [0.0, 1.0], [1.0, 0.0])
    with pytest.raises(InvalidSynergyInput, match=r"target must have shape \(3,\)"):
        reach([s], [1.0, 0.0], "tip", robot)
    with pytest.raises(UnknownFrame, match="hand"):
        reach([s], [1.0, 0.0, 0.0], "hand", robot)
    with pytest.raises(InvalidSynergyInput, match="nv=7"):
        reach([s], [1.0, 0.0, 0.0], "panda_hand_tcp", get_robot("panda"))
    with pytest.raises(InvalidSynergyInput, match="lam"):
        reach([s], [1.0, 0.0, 0.0], "tip", robot, lam=-1.0)
    with pytest.raises(InvalidSynergyInput, match="duration"):
        reach([s], [1.0, 0.0, 0.0], "tip", robot, duration=0.0)
