"""Clearance gradients against central differences of the clearances they differentiate.

- `NativeSphereCheck.clearance_gradients` (C: the nearest sphere-obstacle pair's shape
  gradient times the sphere centre's joint Jacobian) against central differences of the
  C clearances (themselves tested against Pinocchio's kinematics and closed-form
  distances in ``test_sphere_native.py``), every obstacle kind alone, spheres inside
  the shapes too; trees with unaligned hinges, a slide joint and two root joints.
- `configuration_gradients` (coal's witness point and normal times Pinocchio's joint
  Jacobian) against central differences of coal's distances (GJK to 1e-9 m), on the
  Panda's URDF meshes, separated and penetrating.

A minimum over pairs has kinks where the nearest pair changes; a configuration whose
forward and backward differences disagree (a kink within the step) is left out, and
most are compared. Tolerances: 1e-6 m/rad on the spheres (round-off of a 1e-6 rad
difference; measured 1e-9), 1e-4 relative on coal (measured 1.2e-5).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from geosyn.metrics.planning.exact_path import configuration_clearances, configuration_gradients
from geosyn.metrics.planning.sphere_native import NativeSphereCheck
from geosyn.robots import load_robot
from geosyn.robots.robot import CollisionSphere
from geosyn.world import shapes
from geosyn.world.exact_clearance import ExactClearance

FIXTURES = Path(__file__).parent / "fixtures"
HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def _differences(values, Q: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """((K, n) central differences of ``values`` at ``Q`` (K, n) with step ``h`` [rad],
    (K,) the largest gap between its forward and backward differences [m/rad])."""
    c, n = values(Q), Q.shape[1]
    up = np.stack([values(Q + h * e) for e in np.eye(n)], axis=1)
    down = np.stack([values(Q - h * e) for e in np.eye(n)], axis=1)
    gap = np.abs((up - c[:, None]) - (c[:, None] - down)).max(axis=1) / h
    return (up - down) / (2.0 * h), gap


def _spheres(robot, rng) -> list[CollisionSphere]:
    """Three random spheres on every joint (seeded)."""
    return [
        CollisionSphere(name, tuple(rng.uniform(-0.1, 0.1, 3)), float(rng.uniform(0.01, 0.05)))
        for name in robot.model.names[1:]
        for _ in range(3)
    ]


def _obstacles(rng, at: np.ndarray) -> list[shapes.Shape]:
    """One obstacle of every kind about the points ``at`` (5, 3) [m] (sphere centres of
    the robot: some spheres end up inside), turned at random (seeded)."""
    R = pin.rpy.rpyToMatrix(*rng.uniform(-1.0, 1.0, 3))
    a, b, c, d, e = (tuple(x) for x in at)
    return [
        shapes.Sphere(a, 0.08),
        shapes.Box(b, (0.08, 0.1, 0.05), R),
        shapes.Capsule(c, tuple(np.add(c, (0.2, 0.1, 0.0))), 0.05),
        shapes.Cylinder(d, 0.06, 0.1, R.T),
        shapes.HalfSpace(tuple(R[:, 2]), float(R[:, 2] @ np.asarray(e))),
    ]


def _centres(robot, spheres, q: np.ndarray) -> np.ndarray:
    """(S, 3) world centres of ``spheres`` at ``q``, placed by Pinocchio."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    return np.array([data.oMi[robot.joint_id(s.joint)].act(np.asarray(s.center)) for s in spheres])


@pytest.mark.parametrize(
    "robot_name", ["panda", str(FIXTURES / "arm_root_quat.xml"), str(FIXTURES / "two_fingers.xml")]
)
def test_sphere_clearance_gradients_are_the_central_differences(robot_name: str) -> None:
    """200 seeded configurations within the limits, each obstacle kind alone; at least
    90 % compared (no kink within the step) and some inside every shape."""
    robot = load_robot(robot_name)
    rng = np.random.default_rng(5)
    spheres = _spheres(robot, rng)
    check = NativeSphereCheck(robot, spheres)
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -np.pi)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, np.pi)
    Q = rng.uniform(lo, hi, size=(200, robot.nq))
    at = np.array([_centres(robot, spheres, q)[-1] for q in Q[:5]])  # a tip's, five times
    for ob in _obstacles(rng, at):
        check.set_obstacles([ob])
        c, g = check.clearance_gradients(Q)
        np.testing.assert_array_equal(c, check.clearances(Q))
        fd, gap = _differences(check.clearances, Q, 1e-6)
        smooth = gap < 1e-3
        assert smooth.mean() >= 0.9, type(ob).__name__
        if isinstance(ob, shapes.Box | shapes.Cylinder):  # their inside branches too
            assert np.any(c[smooth] < 0.0), type(ob).__name__
        assert np.abs(g - fd)[smooth].max() < 1e-6, type(ob).__name__


def test_sphere_clearance_gradients_without_obstacles_are_zero() -> None:
    robot = load_robot("panda")
    check = NativeSphereCheck(robot, _spheres(robot, np.random.default_rng(1)))
    c, g = check.clearance_gradients(np.tile(HOME, (3, 1)))
    assert np.all(np.isinf(c)) and not g.any()


@pytest.fixture(scope="module")
def panda_exact() -> ExactClearance:
    return ExactClearance(load_robot("panda"))


def test_exact_clearance_gradients_are_coals_central_differences(
    panda_exact: ExactClearance,
) -> None:
    """Configurations near the Panda's home among obstacles of every kind, separated
    and penetrating; relative error below 1e-4 where no kink is within the step."""
    exact = panda_exact
    exact.set_obstacles([
        shapes.Box((0.45, 0.0, 0.45), (0.05, 0.3, 0.05)),
        shapes.Sphere((0.3, 0.3, 0.6), 0.08),
        shapes.Capsule((0.2, -0.4, 0.2), (0.5, -0.2, 0.7), 0.04),
        shapes.Cylinder((0.0, 0.4, 0.3), 0.05, 0.3),
        shapes.HalfSpace((0.0, 0.0, 1.0), -0.05),
    ])  # fmt: skip
    rng = np.random.default_rng(7)
    Q = HOME + 0.4 * rng.standard_normal((120, 7))
    c, g = configuration_gradients(exact, Q)
    np.testing.assert_array_equal(c, configuration_clearances(exact, Q))
    fd, gap = _differences(lambda X: configuration_clearances(exact, X), Q, 1e-5)
    near = c < exact.near
    smooth = near & (gap < 1e-2)
    assert near.sum() >= 60 and smooth.sum() >= 0.9 * near.sum()
    assert np.any(c[smooth] < 0.0) and np.any(c[smooth] > 0.0)
    scale = np.maximum(np.linalg.norm(fd, axis=1), 1e-3)
    assert (np.linalg.norm(g - fd, axis=1) / scale)[smooth].max() < 1e-4
    assert not g[~near].any()  # beyond ``near`` the value is ``near``: flat


def test_capped_exact_clearances_are_coals_below_the_cap(panda_exact: ExactClearance) -> None:
    """``cap``: the configuration-by-configuration coal check's clearance where it is below
    the cap, the cap elsewhere (to coal's GJK tolerance, 1e-6 m); gradients only below it."""
    exact = panda_exact
    exact.set_obstacles([shapes.Box((0.45, 0.0, 0.45), (0.05, 0.3, 0.05)),
                         shapes.Sphere((0.3, 0.3, 0.6), 0.08)])  # fmt: skip
    Q = HOME + 0.4 * np.random.default_rng(11).standard_normal((120, 7))
    cap = 0.01
    referee = np.array([exact.clearance(q)[0] for q in Q])
    capped = configuration_clearances(exact, Q, cap=cap)
    assert np.sum(referee < cap) >= 20 and np.sum(referee > cap + 1e-4) >= 20
    np.testing.assert_allclose(capped, np.minimum(referee, cap), rtol=0.0, atol=1e-6)
    c, g = configuration_gradients(exact, Q, cap=cap)
    np.testing.assert_array_equal(c, capped)
    assert not g[c >= cap].any() and np.all(np.linalg.norm(g[c < cap], axis=1) > 0.0)
