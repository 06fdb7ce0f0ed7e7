"""With contact, the obstacles collide with the robot file's own collision geometry
(sim/collision_geoms.py), not with the capsules: MuJoCo's own distances between the
plant's geoms and an obstacle are coal's (an independent library) on the same file, and
contact happens where the meshes are."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from geosyn.controllers import ComputedTorque, JointTrajectoryReference
from geosyn.robots import load_robot
from geosyn.sim import Simulation, build_scene
from geosyn.sim.collision_geoms import COLLISION_PREFIX
from geosyn.world import Box, Sphere
from geosyn.world.exact_clearance import ExactClearance

Q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])  # [rad]
Q1 = np.array([0.6, 0.1, 0.0, -1.8, 0.0, 2.0, 0.8])  # [rad]


@pytest.fixture(scope="module")
def panda():
    robot = load_robot("panda")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, Q1)
    return robot, np.asarray(data.oMf[robot.model.getFrameId("panda_hand")].translation)


def plant_distance(scene, q: np.ndarray, distmax: float = 1.0) -> float:
    """Smallest MuJoCo distance [m] between the plant's file geoms and obstacle 0 at q."""
    m = scene.model
    data = mujoco.MjData(m)
    data.qpos[scene.qpos_adr] = q
    mujoco.mj_forward(m, data)
    ob, fromto = int(scene.obstacle_geom_ids[0]), np.zeros(6)
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(m.ngeom)]
    ids = [g for g, n in enumerate(names) if n.startswith(COLLISION_PREFIX)]
    return min(mujoco.mj_geomDistance(m, data, g, ob, distmax, fromto) for g in ids)


def test_the_plants_contact_geometry_is_the_files(panda) -> None:
    """At seeded configurations, MuJoCo's distance from the plant's geoms to a box equals
    coal's from the URDF's collision meshes (their convex hulls both), to 1e-8 m."""
    robot, hand = panda
    box = Box(tuple(hand + [0.0, 0.0, -0.16]), (0.1, 0.1, 0.02))
    scene = build_scene(robot, obstacles=[box], contact=True)
    exact = ExactClearance(robot, near=1.0)
    exact.set_obstacles([box])
    rng = np.random.default_rng(5)
    for s in rng.uniform(0.0, 1.0, 6):
        q = Q0 + s * (Q1 - Q0) + rng.normal(scale=0.05, size=7)
        coal_d = exact.clearance(q)[0]
        assert 0.0 < coal_d < 0.5
        assert abs(plant_distance(scene, q) - coal_d) < 1e-8


def test_contact_happens_where_the_meshes_are_not_the_capsules(panda) -> None:
    """Two obstacles that tell the geometries apart (measured exactly first): a box the
    capsules reach but the meshes clear by > 2 cm (no contact over the run), and a ball
    the meshes enter while the capsules stay clear (contact from the first tick)."""
    robot, hand = panda
    ref = JointTrajectoryReference(np.array([0.0, 1.0]), np.array([Q0, Q1]))

    def run(box: Box, duration: float):
        sim = Simulation(robot, ComputedTorque(robot, 400.0, 40.0), obstacles=[box], contact=True)
        return sim.run(Q0, duration=duration, reference=ref)

    capsules_only = Box(tuple(hand + [0.0, 0.0, -0.16]), (0.1, 0.1, 0.02))
    res = run(capsules_only, 1.5)
    assert res.clearance.min() < -0.005 and res.mesh_clearance > 0.02  # told apart
    assert res.contact_force.max() == 0.0
    # beside link 6 (+y): its mesh stands ~7 cm out of its capsule
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, Q0)
    side = np.asarray(data.oMf[robot.model.getFrameId("panda_link6")].translation)
    exact = ExactClearance(robot, near=1.0)
    exact.set_obstacles([Sphere(tuple(side + [0.0, 0.16, 0.0]), 0.02)])
    gap = exact.clearance(Q0)[0]
    meshes_only = Sphere(tuple(side + [0.0, 0.16 - gap - 0.004, 0.0]), 0.02)  # 4 mm in
    res = run(meshes_only, 0.005)
    assert res.clearance[0] > 0.02 and res.mesh_clearance < 0.0  # told apart
    assert res.contact_force[0] > 0.0


def test_a_robot_without_file_geometry_collides_its_capsules_and_says_so() -> None:
    robot = load_robot("planar2")
    with pytest.warns(RuntimeWarning, match="capsules collide"):
        scene = build_scene(
            robot, obstacles=[Box((0.5, 0.5, 0.0), (0.05, 0.05, 0.05))], contact=True
        )
    names = [
        mujoco.mj_id2name(scene.model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        for g in range(scene.model.ngeom)
    ]
    colliding = [n for g, n in enumerate(names) if scene.model.geom_contype[g]]
    assert colliding and all(n.startswith("capsule") for n in colliding)
