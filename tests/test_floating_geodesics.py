"""Geodesics of a free robot are its passive, gravity-free motions (geosyn.metrics.geodesic.
group_rk4 through `exp`).

References: the invariants of a free system (Pinocchio's centroidal momentum conserved,
the centre of mass on a straight line), MuJoCo's own RK4 simulation of the same MJCF file
(free joint, gravity off, contacts off), and the method's order of convergence.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from floating_cases import floater_file, load_quietly

from geosyn.metrics import FloatingKineticEnergyMetric, exp
from geosyn.metrics.errors import NonFiniteResult
from geosyn.metrics.geodesic.group_rk4 import dexpinv
from geosyn.robots.floating import from_mujoco


@pytest.mark.parametrize(("name", "steps"), [("solo12", 200), ("talos_reduced", 400)])
def test_momentum_is_conserved_and_the_com_moves_on_a_line(name, steps) -> None:
    robot = load_quietly(name)
    metric = FloatingKineticEnergyMetric(robot)
    rng = np.random.default_rng(26)
    q0, v0 = robot.random_q(rng), rng.normal(scale=0.5, size=robot.nv)
    geo = exp(metric, q0, v0, duration=1.0, steps=steps)
    h = np.array([metric.momentum(q, v) for q, v in zip(geo.q, geo.v, strict=True)])
    com = np.array([metric.center_of_mass(q) for q in geo.q])
    line = com[0] + geo.t[:, None] * h[0, :3] / robot.total_mass
    assert np.linalg.norm(h[0, :3]) > 0.1 and np.linalg.norm(h[0, 3:]) > 0.01  # not at rest
    assert np.abs(h - h[0]).max() / np.linalg.norm(h[0]) < 1e-9
    assert np.abs(com - line).max() < 1e-9
    assert np.abs(np.linalg.norm(geo.q[:, 3:7], axis=1) - 1.0).max() < 1e-14
    energy = [metric.energy(q, v) for q, v in zip(geo.q, geo.v, strict=True)]
    assert np.ptp(energy) / energy[0] < 1e-9
    # the base really turned and travelled: a q + v dt integrator would be visibly wrong
    assert np.linalg.norm(geo.q[-1, :3] - geo.q[0, :3]) > 0.1


def test_exp_matches_mujocos_passive_simulation_of_the_same_file(tmp_path) -> None:
    path = floater_file(tmp_path, dt=1e-4)
    robot = load_quietly(path)
    metric = FloatingKineticEnergyMetric(robot)
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    d.qpos[7:] += rng.uniform(-0.5, 0.5, m.nq - 7)
    d.qvel[:] = rng.normal(size=m.nv)  # world-frame linear base velocity (MuJoCo's)
    q0, v0 = from_mujoco(d.qpos, d.qvel)
    geo = exp(metric, q0, v0, duration=1.0, steps=1000)
    worst = 0.0
    for k in range(1, 11):  # every 0.1 s over 1 s
        while d.time < 0.1 * k - 1e-9:
            mujoco.mj_step(m, d)
        q_mj, v_mj = from_mujoco(d.qpos, d.qvel)
        worst = max(worst, float(np.abs(metric.difference(q_mj, geo.q[100 * k])).max()))
        assert np.abs(v_mj - geo.v[100 * k]).max() < 1e-6
    assert d.time == pytest.approx(1.0) and worst < 1e-6
    assert np.linalg.norm(metric.difference(q0, geo.q[-1])) > 0.5  # it moved


def test_fourth_order_convergence_on_the_group() -> None:
    robot = load_quietly("go2")
    metric = FloatingKineticEnergyMetric(robot)
    rng = np.random.default_rng(5)
    q0, v0 = robot.random_q(rng), rng.normal(size=robot.nv)
    ref = exp(metric, q0, v0, steps=1600).q[-1]
    errors = [
        np.abs(metric.difference(ref, exp(metric, q0, v0, steps=s).q[-1])).max()
        for s in (50, 100, 200)
    ]
    # measured 14.1 and 15.1 (2^4 = 16 as dt -> 0)
    assert errors[0] / errors[1] > 13.0 and errors[1] / errors[2] > 14.0


def test_dexpinv_is_the_chart_velocity() -> None:
    robot = load_quietly("solo12")
    metric = FloatingKineticEnergyMetric(robot)
    rng = np.random.default_rng(6)
    q, xi, v = robot.random_q(rng), 0.05 * rng.normal(size=robot.nv), rng.normal(size=robot.nv)
    h = 1e-6  # central difference of q exp(xi + t dxi) against the body velocity v
    dxi = dexpinv(xi, v)
    ahead = metric.integrate(q, xi + h * dxi)
    behind = metric.integrate(q, xi - h * dxi)
    assert np.abs(metric.difference(behind, ahead) / (2 * h) - v).max() < 1e-6


def test_an_overflowing_geodesic_is_reported() -> None:
    robot = load_quietly("solo12")
    metric = FloatingKineticEnergyMetric(robot)
    with pytest.raises(NonFiniteResult, match="left the float64 range"):
        exp(metric, robot.neutral(), np.full(robot.nv, 1e150), steps=10)
