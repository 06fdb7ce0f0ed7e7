"""Tests of geosyn.controllers.replan: a geodesic from a disturbed state to the goal."""

from __future__ import annotations

import numpy as np
import pytest
from test_reference import rk4_geodesic

from conftest import get_metric, get_robot
from geosyn.controllers import GeodesicReference
from geosyn.controllers.computed_torque import ComputedTorque
from geosyn.controllers.plant import PinocchioPlant
from geosyn.controllers.qp import QPController
from geosyn.controllers.replan import replan_geodesic
from geosyn.controllers.riemannian_pd import RiemannianPD
from geosyn.core import InvalidArgument
from geosyn.metrics import GeodesicNotFound
from geosyn.synergies import GeodesicSynergy

Q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
V0 = 0.5 * np.array([1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
KICK_Q = np.array([0.25, -0.2, 0.15, 0.2, -0.25, 0.2, 0.3])  # a large disturbance [rad]
KICK_V = np.array([1.0, -1.0, 0.5, 0.5, -1.0, 1.0, 1.0])  # [rad/s]


@pytest.fixture(scope="module")
def disturbed():
    """Synergy reference, and a disturbed state at t = 0.5 s."""
    metric = get_metric("panda")
    ref = GeodesicReference(GeodesicSynergy(metric, Q0, V0), duration=1.5, steps=150)
    q_ref, v_ref, _ = ref.sample(0.5)
    return metric, ref, q_ref + KICK_Q, v_ref + KICK_V


def test_replanned_reference_is_a_geodesic_from_state_to_goal(disturbed):
    metric, ref, q, v = disturbed
    new = replan_geodesic(
        metric, q, v, ref.goal(), duration=1.2, steps=120, t0=0.5, rest_to_rest=False
    )
    assert isinstance(new, GeodesicReference) and new.t0 == 0.5
    assert new.duration == pytest.approx(1.2)
    np.testing.assert_allclose(new.sample(0.5).q, q, atol=1e-12)
    np.testing.assert_allclose(new.sample(0.5 + 1.2).q, ref.goal(), atol=1e-8)
    np.testing.assert_allclose(new.goal(), ref.goal(), atol=1e-8)
    # Independent check: the same geodesic from an independent RK4 with the initial
    # velocity read off the reference (unit-time velocity = duration * v_ref).
    v_unit = 1.2 * new.sample(0.5).v
    check = rk4_geodesic(metric, q, v_unit, 1.0, 1000)
    for k in (250, 500, 1000):
        np.testing.assert_allclose(new.sample(0.5 + 1.2 * check.t[k]).q, check.q[k], atol=1e-6)
    # The acceleration is the geodesic acceleration at the reference state.
    qs, vs, as_ = new.sample(1.0)
    np.testing.assert_allclose(as_, metric.geodesic_acceleration(qs, vs), atol=1e-10)
    # Default timing: the same path, starting and ending at rest.
    rest = replan_geodesic(metric, q, v, ref.goal(), duration=1.2, steps=120, t0=0.5)
    assert rest.rest_to_rest
    for t in (0.5, 1.7):
        np.testing.assert_allclose(rest.sample(t).v, 0.0, atol=1e-12)
    np.testing.assert_allclose(rest.sample(1.1).q, new.sample(1.1).q, atol=1e-7)  # midpoint


@pytest.mark.parametrize(
    "make",
    [
        lambda r: ComputedTorque(r, 400.0, 40.0),
        lambda r: RiemannianPD(r, 20.0, 50.0),
        lambda r: QPController(r, 400.0, 40.0, 1e-3, braking_acceleration=10.0),
    ],
    ids=["computed_torque", "riemannian_pd", "qp"],
)
def test_every_controller_reaches_goal_after_replanning(disturbed, make):
    """After the kick, each controller follows the replanned geodesic to the goal."""
    metric, ref, q, v = disturbed
    robot = get_robot("panda")
    ctl = make(robot)
    new = replan_geodesic(metric, q, v, ref.goal(), duration=1.0, t0=0.5)
    ctl.set_reference(new)
    plant = PinocchioPlant(robot)
    plant.reset(q, v, t=0.5)
    ctl.reset(q, v, t=0.5)
    ro = plant.rollout(ctl, 1.4)
    err = ro.q - np.array([new.sample(t).q for t in ro.t])
    assert np.abs(ro.q[-1] - ref.goal()).max() < 1e-3
    assert np.abs(ro.v[-1]).max() < 1e-2
    # The velocity kick is absorbed: the error peaks early and stays small afterwards.
    assert np.abs(err[400:]).max() < 0.2 * np.abs(err).max()
    assert ctl.diagnostics.fallback_count == 0


def test_replan_rejects_bad_input(disturbed):
    metric, ref, q, v = disturbed
    goal = ref.goal()
    with pytest.raises(InvalidArgument, match=r"q must have shape \(7,\)"):
        replan_geodesic(metric, q[:3], v, goal)
    with pytest.raises(InvalidArgument, match="v must be finite"):
        replan_geodesic(metric, q, np.full(7, np.nan), goal)
    with pytest.raises(InvalidArgument, match="duration"):
        replan_geodesic(metric, q, v, goal, duration=-1.0)
    with pytest.raises(InvalidArgument, match="steps"):
        replan_geodesic(metric, q, v, goal, steps=0)
    with pytest.raises(InvalidArgument, match="metric"):
        replan_geodesic("panda", q, v, goal)


def test_replan_reports_failed_log_map(disturbed):
    metric, ref, q, v = disturbed
    with pytest.raises(GeodesicNotFound):
        replan_geodesic(metric, q, v, ref.goal(), max_iter=1, tol=1e-300)


def test_replan_with_a_shaped_metric_is_tracked():
    """Controllers take any Metric: a payload-shaped metric's geodesic is tracked."""
    from geosyn.metrics import KineticEnergyMetric
    from geosyn.metrics.shaping import LoadTerm, ShapedMetric

    robot = get_robot("planar3")
    metric = ShapedMetric(KineticEnergyMetric(robot), [LoadTerm(robot.ee_frame, 2.0)])
    q = robot.neutral()
    goal = q + np.array([0.8, -0.5, 0.4])
    v = np.array([0.3, 0.0, -0.2])
    ref = replan_geodesic(metric, q, v, goal, duration=1.0, exact_acceleration=False)
    # The shaped geodesic differs from the kinetic-energy one (the metric matters).
    ke = replan_geodesic(get_metric("planar3"), q, v, goal, duration=1.0)
    assert np.abs(ref.sample(0.5).q - ke.sample(0.5).q).max() > 1e-3
    ctl = ComputedTorque(robot, 400.0, 40.0, metric=metric, reference=ref)
    plant = PinocchioPlant(robot)
    plant.reset(q, v)
    ctl.reset(q, v)
    ro = plant.rollout(ctl, 1.3)
    assert np.abs(ro.q[-1] - goal).max() < 1e-3
