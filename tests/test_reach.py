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


def _limited_arm():
    """tests/fixtures/floating_arm.xml with its base welded: 3 joints limited to +-2.5 rad."""
    import warnings
    from pathlib import Path

    from geosyn.metrics import KineticEnergyMetric
    from geosyn.robots import load_robot

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(Path(__file__).parent / "fixtures" / "floating_arm.xml", fixed_base=True)
    return robot, KineticEnergyMetric(robot)


def test_reach_stays_inside_the_joint_limits():
    """A target only reached straight on by turning j1 to 2.9 rad (limit 2.5): the motion
    returned stays inside the limits (the best it can do is reported, not converged)."""
    robot, metric = _limited_arm()
    q0 = np.array([2.2, 0.3, 0.5])
    np.testing.assert_array_equal(robot.q_max, [2.5, 2.5, 2.5])
    basis = orthonormal_synergies(metric, q0, 3)
    target = fk(robot, np.array([2.9, 0.3, 0.5]), "tip")
    res = reach(basis.synergies, target, "tip", robot, q_start=q0, restarts=2)
    q = res.trajectory.q
    assert np.all(q <= robot.q_max) and np.all(q >= robot.q_min)
    assert q[:, 0].max() > 2.4  # it went as far as the limit allows
    assert not res.converged and res.error > 0.05
    # Inside the limits, a target is still reached as before.
    near = fk(robot, np.array([2.0, 0.5, 0.3]), "tip")
    ok = reach(basis.synergies, near, "tip", robot, q_start=q0)
    assert ok.converged and np.all(np.abs(ok.trajectory.q) <= 2.5)


def test_reach_from_outside_the_limits_names_the_joint():
    from geosyn.synergies.reach import ReachOutsideLimits

    robot, metric = _limited_arm()
    q_out = np.array([0.1, 2.7, 0.0])
    basis = orthonormal_synergies(metric, q_out, 2)
    with pytest.raises(ReachOutsideLimits, match="joint 'j2' at 2.7 passes its limit 2.5") as err:
        reach(basis.synergies, [0.3, 0.0, 0.8], "tip", robot, q_start=q_out)
    assert err.value.joint == "j2" and err.value.limit == 2.5
