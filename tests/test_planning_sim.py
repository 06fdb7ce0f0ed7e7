"""A planned path around a box, executed in MuJoCo with contact enabled: no contact force
is recorded, while the straight joint-space line through the box records one (so the
check can fail). Reference: MuJoCo's own contact solver on the robot's collision geoms."""

from __future__ import annotations

import numpy as np
import pytest

from geosyn.controllers import ComputedTorque
from geosyn.controllers.reference import JointTrajectoryReference
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import Planner
from geosyn.metrics.planning.planner import densify
from geosyn.robots import load_robot
from geosyn.sim import Simulation
from geosyn.world import Box

HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
POST = Box((0.4, 0.0, 0.3), (0.05, 0.05, 0.4))  # geodex's quickstart post
DURATION = 2.0


def _track(robot, metric, path: np.ndarray):  # type: ignore[no-untyped-def]
    t = np.linspace(0.0, DURATION, len(path))
    ref = JointTrajectoryReference(t, path)
    ctrl = ComputedTorque(robot, kp=900.0, kd=60.0, metric=metric, reference=ref)
    sim = Simulation(robot, ctrl, obstacles=[POST], contact=True)
    q0, v0, _ = ref.sample(0.0)
    return sim.run(q0, v0, DURATION + 0.3)


@pytest.mark.slow
def test_planned_path_around_a_box_makes_no_contact_in_mujoco() -> None:
    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot)
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = -1.1, 1.1
    # 3 cm node margin: the planner's spheres and MuJoCo's capsules are different models
    planner = Planner(metric, capacity=1, margin=0.03)
    plan = planner.plan(q0, q1, [POST], budget=20.0)
    # the plan is certified on the URDF meshes (its spheres may overlap the post where
    # they reach beyond the links); MuJoCo's contacts below are the referee
    assert plan.exact_clearance > 0.0
    run = _track(robot, metric, plan.q)
    assert run.status == "ok"
    assert np.all(run.contact_force == 0.0)
    assert run.clearance.min() > 0.0
    # the straight line hits the post (computed torque then pushes against it until the
    # run may diverge: only the recorded force matters here) [N]
    line = densify(np.array([q0, q1]), 24)
    assert _track(robot, metric, line).contact_force.max() > 1.0
