"""Point stances: a quadruped's four feet held at their positions (geosyn.metrics.stance,
``points=True``).

References: the feet's positions (an invariant), energy conservation, d'Alembert's
principle (the constraint force does no work on tangent motions).
"""

from __future__ import annotations

import numpy as np
import pytest
from floating_cases import load_quietly

from geosyn.metrics import FloatingKineticEnergyMetric
from geosyn.metrics.errors import StanceError
from geosyn.metrics.stance import Stance

FEET = ["FL_foot", "FR_foot", "RL_foot", "RR_foot"]


def go2_stance() -> tuple[Stance, np.ndarray, np.ndarray]:
    robot = load_quietly("go2")
    metric = FloatingKineticEnergyMetric(robot)
    q_ref = robot.neutral()
    q_ref[7:] = np.tile([0.0, 0.8, -1.6], 4)
    stance = Stance(metric, FEET, q_ref, points=True)
    q, v = stance.project(q_ref, np.random.default_rng(2).normal(scale=0.3, size=robot.nv))
    return stance, q, v


def test_four_feet_stay_put_and_energy_is_conserved() -> None:
    stance, q0, v0 = go2_stance()
    metric = stance.metric
    assert stance.dimension == 6 and stance.jacobian(q0).shape == (12, 18)
    geo = stance.geodesic(q0, v0, duration=1.0, steps=200)
    assert max(np.abs(stance.residual(q)).max() for q in geo.q) < 1e-8  # [m]
    energy = np.array([metric.energy(q, v) for q, v in zip(geo.q, geo.v, strict=True)])
    assert np.ptp(energy) / energy[0] < 1e-5  # measured 2.2e-6 (RK4 at 5 ms)
    feet = [metric.robot.frame_id(f) for f in FEET]
    data = metric.robot.model.createData()
    import pinocchio as pin

    pin.framesForwardKinematics(metric.robot.model, data, geo.q[-1])
    turned = [
        np.linalg.norm(pin.log3(t.rotation.T @ data.oMf[i].rotation))
        for t, i in zip(stance.targets, feet, strict=True)
    ]
    assert max(turned) > 0.05  # the feet roll about their points: only positions are held
    assert np.linalg.norm(metric.difference(q0, geo.q[-1])) > 0.2


def test_the_constraint_force_does_no_work_on_tangent_motions() -> None:
    stance, q, v = go2_stance()
    metric = stance.metric
    force = metric.G(q) @ stance.acceleration(q, v) + metric.coriolis(q, v)
    N = stance.tangent_basis(q)
    assert N.shape == (18, 6)
    assert np.abs(N.T @ force).max() < 1e-9 * np.abs(force).max()


def test_five_point_feet_over_constrain_nothing_but_full_poses_do() -> None:
    stance, q, _ = go2_stance()
    with pytest.raises(StanceError, match=r"24 constraints \(6 per frame\) .* on nv = 18"):
        Stance(stance.metric, FEET, q)
