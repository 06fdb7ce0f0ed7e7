"""The kinetic-energy metric on SE(3) x R^n (geosyn.metrics.floating).

Referee: Pinocchio's CRBA on its own free-flyer model of the same URDF; refusals of what
does not work on the group yet are checked by their error class and the names they give.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from floating_cases import CATALOG_FLOATING, load_quietly

from geosyn.metrics import (
    FloatingBaseUnsupported,
    FloatingKineticEnergyMetric,
    KineticEnergyMetric,
    distance,
    exp,
    log,
    parallel_transport,
    path_energy,
)
from geosyn.metrics.planning import Planner
from geosyn.metrics.shaping import ShapedMetric
from geosyn.robots import FloatingBaseError
from geosyn.robots.catalog import catalog
from geosyn.robots.files import example_robot_data_dir
from geosyn.synergies import GeodesicSynergy
from geosyn.synergies.errors import InvalidSynergyInput


@pytest.mark.parametrize("name", CATALOG_FLOATING)
def test_G_is_pinocchios_free_flyer_crba(name) -> None:
    robot = load_quietly(name)
    metric = FloatingKineticEnergyMetric(robot)
    ref = pin.buildModelFromUrdf(
        str(example_robot_data_dir() / catalog()[name].relative_path), pin.JointModelFreeFlyer()
    )
    ref_data = ref.createData()
    rng = np.random.default_rng(26)
    worst = 0.0
    for _ in range(50):
        q = robot.random_q(rng)
        M_ref = pin.crba(ref, ref_data, q)
        M_ref = np.triu(M_ref) + np.triu(M_ref, 1).T  # whichever triangle CRBA filled
        G = metric.G(q)
        worst = max(worst, float(np.abs(G - M_ref).max()))
        assert np.array_equal(G, G.T)
    assert worst < 1e-12


def test_energy_is_left_invariant_and_inner_products_use_G() -> None:
    robot = load_quietly("solo12")
    metric = FloatingKineticEnergyMetric(robot)
    rng = np.random.default_rng(3)
    q, v = robot.random_q(rng), rng.normal(size=robot.nv)
    moved = q.copy()
    moved[:7] = robot.random_q(rng)[:7]  # another base pose, same joints
    assert metric.energy(moved, v) == pytest.approx(metric.energy(q, v), rel=1e-13)
    G = metric.G(q)
    assert metric.energy(q, v) == pytest.approx(0.5 * v @ G @ v, rel=1e-14)
    # kinetic energy from the bodies' own spatial velocities (Pinocchio's forward pass)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q, v)
    body = sum(0.5 * robot.model.inertias[j].vtiv(data.v[j]) for j in range(1, robot.model.njoints))
    assert metric.energy(q, v) == pytest.approx(body, rel=1e-12)


def test_integrate_and_difference_are_the_groups() -> None:
    robot = load_quietly("go2")
    metric = FloatingKineticEnergyMetric(robot)
    rng = np.random.default_rng(4)
    q0, q1 = robot.random_q(rng), robot.random_q(rng)
    back = metric.integrate(q0, metric.difference(q0, q1))
    assert np.abs(back[7:] - q1[7:]).max() < 1e-12
    pose, pose1 = pin.XYZQUATToSE3(back[:7]), pin.XYZQUATToSE3(q1[:7])  # q and -q: one pose
    assert np.abs(pose.homogeneous - pose1.homogeneous).max() < 1e-12
    # a base twist along x in the base frame moves the base along its own x axis
    R = pin.Quaternion(q0[6], q0[3], q0[4], q0[5]).matrix()
    step = np.zeros(robot.nv)
    step[0] = 0.3
    assert np.abs(metric.integrate(q0, step)[:3] - (q0[:3] + 0.3 * R[:, 0])).max() < 1e-14


def test_bad_quaternion_is_refused_by_every_entry_point() -> None:
    robot = load_quietly("solo12")
    metric = FloatingKineticEnergyMetric(robot)
    q = robot.neutral()
    q[6] = 0.5
    v = np.zeros(robot.nv)
    for call in (
        lambda: metric.G(q),
        lambda: metric.geodesic_acceleration(q, v),
        lambda: metric.integrate(q, v),
        lambda: exp(metric, q, v),
    ):
        with pytest.raises(FloatingBaseError, match=r"must be unit .* norm is 0\.5"):
            call()


def test_fixed_base_metric_refuses_a_floating_robot_and_names_the_right_one() -> None:
    robot = load_quietly("go2")
    with pytest.raises(FloatingBaseUnsupported, match="FloatingKineticEnergyMetric"):
        KineticEnergyMetric(robot)
    with pytest.raises(Exception, match="floating-base geosyn Robot"):
        FloatingKineticEnergyMetric(load_quietly("go2", fixed_base=True))
    assert KineticEnergyMetric(load_quietly("go2", fixed_base=True)).n == 12


def test_vector_space_operations_refuse_clearly() -> None:
    robot = load_quietly("solo12")
    metric = FloatingKineticEnergyMetric(robot)
    q, v = robot.neutral(), np.full(robot.nv, 0.1)
    geo = exp(metric, q, v, steps=5)
    refused = {
        "log": lambda: log(metric, q, q),
        "parallel_transport": lambda: parallel_transport(metric, geo.t, geo.q, v),
        "path_energy": lambda: path_energy(metric, geo.t, geo.q),
        "distance": lambda: distance(metric, q, q),
        "Planner": lambda: Planner(metric),
        "ShapedMetric": lambda: ShapedMetric(metric),
        "christoffel": lambda: metric.christoffel(q),
        "symbolic_G": lambda: metric.symbolic_G(None),
    }
    for name, call in refused.items():
        with pytest.raises(FloatingBaseUnsupported, match=rf"{name}.*floating base"):
            call()
    with pytest.raises(InvalidSynergyInput, match="floating base's metric"):
        GeodesicSynergy(metric, q, v)
    with pytest.raises(Exception, match="method 'dop853' integrates in coordinates"):
        exp(metric, q, v, method="dop853")
