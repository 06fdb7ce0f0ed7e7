"""End-effector goals (`geosyn.metrics.planning.goals`, issue 22): inverse kinematics
within the limits and clear of the scene, several solutions, the lowest-energy plan kept.

References: the 2-link arm's closed-form inverse kinematics (elbow up / down); Pinocchio's
forward kinematics called by the test; the Panda URDF's own ``<limit>`` elements read as
XML; coal distances between the URDF's collision geometry (Pinocchio's GeometryModel,
built by the test) and an obstacle; the planner's energies of plans to each closed-form
solution, made separately.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from geosyn.core.errors import InvalidArgument
from geosyn.experiments.schema.synergies import PlannedReference
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import (
    EndEffectorGoal,
    GoalUnreachable,
    InCollision,
    Planner,
    ik_solutions,
)
from geosyn.robots import Robot, load_robot
from geosyn.world import Sphere
from geosyn.world.exact_clearance import ExactClearance

PLANAR = dataclasses.replace(
    load_robot("planar2"), q_min=np.full(2, -np.pi), q_max=np.full(2, np.pi)
)
TIP = np.array([1.2, 0.9, 0.0])  # reachable by the 2-link arm (links 1 m)


def closed_form(p: np.ndarray) -> list[np.ndarray]:
    """The two configurations of the unit 2-link arm whose tip is at ``p`` (x, y)."""
    c2 = (p[0] ** 2 + p[1] ** 2 - 2.0) / 2.0
    out = []
    for q2 in (np.arccos(c2), -np.arccos(c2)):
        q1 = np.arctan2(p[1], p[0]) - np.arctan2(np.sin(q2), 1.0 + np.cos(q2))
        out.append(np.array([q1, q2]))
    return out


def fk(robot: Robot, q: np.ndarray, frame: str) -> pin.SE3:
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    return pin.updateFramePlacement(robot.model, data, robot.model.getFrameId(frame)).copy()


@pytest.fixture(scope="module")
def planar() -> Planner:
    with pytest.warns(UserWarning, match="capsule spheres only"):
        return Planner(KineticEnergyMetric(PLANAR), capacity=1, nodes=16)


def test_two_link_ik_finds_both_closed_form_solutions() -> None:
    goal = EndEffectorGoal(tuple(TIP), position_tolerance=1e-6, solutions=4)
    sols, refused = ik_solutions(PLANAR, goal, np.array([0.1, 0.2]), seed=3)
    assert refused == [] and len(sols) == 2  # an arm of 2 links has exactly two
    ref = closed_form(TIP)
    for s in sols:
        assert min(np.abs(s.q - r).max() for r in ref) < 1e-5
        assert np.linalg.norm(fk(PLANAR, s.q, "tip").translation - TIP) <= 1e-6
    assert {np.sign(s.q[1]) for s in sols} == {1.0, -1.0}


def test_plan_to_a_tip_position_keeps_the_lower_energy_solution(planar: Planner) -> None:
    q0 = np.array([1.4, -0.6])
    goal = EndEffectorGoal(tuple(TIP), position_tolerance=1e-6)
    plan = planar.plan(q0, goal, [], budget=20.0)
    assert np.linalg.norm(fk(PLANAR, plan.q[-1], "tip").translation - TIP) <= 1e-6
    np.testing.assert_allclose(plan.q[0], q0, atol=1e-12)
    energies = [planar.plan(q0, q, [], budget=20.0).result.energy for q in closed_form(TIP)]
    assert max(energies) > 1.5 * min(energies)  # the choice matters here
    assert abs(plan.result.energy - min(energies)) <= 1e-6 * min(energies)
    assert plan.attempts[0].startswith("IK: 2 solution(s)")


def test_a_goal_solution_in_collision_is_refused_and_the_other_one_used(planar: Planner) -> None:
    """A ball on the outer link of the lower-energy solution: that solution is refused
    (its spheres penetrate the ball), the plan goes to the other one, clear of the ball."""
    q0 = np.array([1.4, -0.6])
    low = min(closed_form(TIP), key=lambda q: float(np.abs(q - q0).sum()))
    middle = TIP - 0.5 * np.array([np.cos(low.sum()), np.sin(low.sum()), 0.0])
    ball = Sphere(tuple(middle), 0.1)
    plan = planar.plan(q0, EndEffectorGoal(tuple(TIP), position_tolerance=1e-6), [ball],
                       budget=20.0)  # fmt: skip
    assert np.abs(plan.q[-1] - low).max() > 0.5  # the other elbow
    assert np.linalg.norm(fk(PLANAR, plan.q[-1], "tip").translation - TIP) <= 1e-6
    assert "1 refused" in plan.attempts[0]
    assert plan.check_clearance >= 0.0
    with pytest.raises(InCollision):  # the start itself: named before any IK
        planar.plan(np.array([0.0, 0.0]), EndEffectorGoal(tuple(TIP)),
                    [Sphere((0.5, 0.0, 0.0), 0.05)], budget=5.0)  # fmt: skip
    far = EndEffectorGoal((2.5, 0.0, 0.0))  # out of reach (links sum to 2 m)
    with pytest.raises(GoalUnreachable, match="'tip'"):
        planar.plan(q0, far, [], budget=5.0)


def test_panda_pose_ik_within_tolerance_limits_and_clear_of_an_obstacle() -> None:
    """Pose goal of the Panda's hand: every solution within the tolerances (Pinocchio FK),
    inside the URDF's own limits, and clear of a ball by coal's distance to the URDF's
    collision geometry (a GeometryModel the test builds from the file)."""
    robot = load_robot("panda")
    urdf = Path(robot.source_file)  # type: ignore[arg-type]
    rng = np.random.default_rng(7)
    q_ref = robot.random_q(rng, margin=0.3)
    M = fk(robot, q_ref, robot.ee_frame)
    goal = EndEffectorGoal(tuple(M.translation), tuple(map(tuple, M.rotation)),
                           position_tolerance=1e-4, orientation_tolerance=1e-3, solutions=3)  # fmt: skip
    ball = Sphere(tuple(fk(robot, q_ref, "panda_link4").translation), 0.06)  # on the elbow
    exact = ExactClearance(robot)
    exact.set_obstacles([ball])

    def accept(q: np.ndarray) -> str:
        return "" if exact.clearance(q)[0] >= 0.0 else "in collision"

    assert accept(q_ref) == "in collision"  # the configuration the goal came from
    sols, refused = ik_solutions(robot, goal, robot.neutral(), accept=accept, seed=1)
    assert len(sols) >= 2
    root = ET.parse(urdf).getroot()
    limits = {j.get("name"): j.find("limit") for j in root.iter("joint")}
    lo = np.array([float(limits[n].attrib["lower"]) for n in robot.joint_names])  # type: ignore[union-attr]
    hi = np.array([float(limits[n].attrib["upper"]) for n in robot.joint_names])  # type: ignore[union-attr]
    full = pin.buildModelFromUrdf(str(urdf))
    share = [str(p) for p in urdf.parents if p.name == "share"]
    gm = pin.buildGeomFromUrdf(full, str(urdf), pin.GeometryType.COLLISION, package_dirs=share)
    import coal

    ob = coal.CollisionObject(coal.Sphere(0.06), coal.Transform3s(np.eye(3), np.array(ball.center)))
    for s in sols:
        T = fk(robot, s.q, robot.ee_frame)
        assert np.linalg.norm(T.translation - M.translation) <= 1e-4
        assert np.linalg.norm(pin.log3(M.rotation.T @ T.rotation)) <= 1e-3
        assert np.all(s.q >= lo) and np.all(s.q <= hi)
        qf = pin.neutral(full)
        qf[: robot.nq] = s.q  # the arm's joints come first; the fingers stay closed
        gd = gm.createData()
        pin.updateGeometryPlacements(full, full.createData(), gm, gd, qf)
        d = min(
            coal.distance(
                coal.CollisionObject(g.geometry, coal.Transform3s(P.rotation, P.translation)),
                ob, coal.DistanceRequest(), coal.DistanceResult(),
            )
            for g, P in zip(gm.geometryObjects, gd.oMg, strict=True)
            if "finger" not in g.name
        )  # fmt: skip
        assert d >= -1e-6  # convex meshes: coal's BVH distance is the hull's
    assert len({tuple(np.round(s.q, 1)) for s in sols}) == len(sols)


def test_goal_validation_and_the_yaml_goal() -> None:
    with pytest.raises(InvalidArgument, match="position_tolerance"):
        EndEffectorGoal((0.5, 0.0, 0.3), position_tolerance=0.0)
    with pytest.raises(InvalidArgument, match="rotation"):
        EndEffectorGoal((0.5, 0.0, 0.3), ((1.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 1.0)))
    ref = PlannedReference.model_validate(
        {
            "type": "planned",
            "q_start": [0.0, 0.1],
            "goal": {
                "position": [1.2, 0.9, 0.0],
                "rpy": [0.1, -0.2, 0.3],
                "frame": "tip",
                "position_tolerance": 0.002,
                "solutions": 2,
            },
        }  # fmt: skip
    )
    goal = ref.planner_goal()
    assert isinstance(goal, EndEffectorGoal)
    assert goal.frame == "tip" and goal.position_tolerance == 0.002 and goal.solutions == 2
    Rz, Ry, Rx = (pin.utils.rotate(a, t) for a, t in (("z", 0.3), ("y", -0.2), ("x", 0.1)))
    np.testing.assert_allclose(np.array(goal.rotation), Rz @ Ry @ Rx, atol=1e-15)
    joint = PlannedReference.model_validate({"type": "planned", "q_start": [0.0, 0.1],
                                             "goal": [0.5, 0.2]})  # fmt: skip
    np.testing.assert_array_equal(joint.planner_goal(), [0.5, 0.2])
    with pytest.raises(ValueError, match="tolerance"):
        PlannedReference.model_validate({"type": "planned", "q_start": [0.0], "goal": {
            "position": [1.0, 0.0, 0.0], "tolerance": 0.1}})  # fmt: skip


def test_a_redundant_arm_s_solution_is_nearest_the_start_in_the_metric() -> None:
    """Panda position goal (4-D null space) near the start: the start-seeded solution is
    a stationary point of ``(q - q0)^T M(q0) (q - q0)`` on the solution set (its
    gradient has no component in the task's null space, projector from Pinocchio's
    Jacobian and ``crba`` in the test) and no farther than the configuration the goal
    came from."""
    robot = load_robot("panda")
    q0 = np.array([0.2, -0.5, 0.1, -2.0, 0.1, 1.8, 0.6])
    q_goal = q0 + np.array([0.3, 0.2, -0.2, 0.3, 0.2, -0.2, 0.1])
    target = fk(robot, q_goal, robot.ee_frame).translation
    data = robot.model.createData()
    W = pin.crba(robot.model, data, q0)
    W = np.triu(W) + np.triu(W, 1).T
    goal = EndEffectorGoal(tuple(target), position_tolerance=1e-5, solutions=1)
    (sol,), _ = ik_solutions(robot, goal, q0, weight=W)
    assert sol.start == "start"
    q = sol.q
    assert np.linalg.norm(fk(robot, q, robot.ee_frame).translation - target) <= 1e-5
    J = pin.computeFrameJacobian(robot.model, data, q, robot.frame_id(robot.ee_frame),
                                 pin.LOCAL_WORLD_ALIGNED)[:3]  # fmt: skip
    W_inv = np.linalg.inv(W)
    P = np.eye(7) - W_inv @ J.T @ np.linalg.solve(J @ W_inv @ J.T, J)
    assert np.abs(P @ (q - q0)).max() <= 1e-3 * np.abs(q - q0).max()
    energy = float((q - q0) @ W @ (q - q0))
    assert energy <= float((q_goal - q0) @ W @ (q_goal - q0))
