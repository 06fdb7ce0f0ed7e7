"""Exact verification of plans against the robot's own collision geometry (issue 22).

A planted obstacle grazes a Panda collision mesh between the capsule spheres the planner
is given: the spheres see it clear, the mesh penetrates it. Reference: the planted ball
is centred on a vertex of a convex collision mesh, so the exact signed distance is minus
its radius (an invariant, independent of coal's algorithm).
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import Planner, PlanningError
from geosyn.robots import load_robot
from geosyn.world import Sphere
from geosyn.world.exact_clearance import ExactClearance

HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
BALL = 0.004  # [m]


def _grazing_ball(robot, exact: ExactClearance, q: np.ndarray, spheres) -> Sphere:  # type: ignore[no-untyped-def]
    """A ball centred on a mesh vertex at ``q`` that lies >= 2 cm outside every sphere."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    C = np.array([data.oMi[robot.joint_id(s.joint)].act(np.asarray(s.center)) for s in spheres])
    R = np.array([s.radius for s in spheres])
    for obj in exact.objects:
        if obj.kind != "mesh" or obj.joint in ("universe", "panda_joint1"):
            continue
        M = data.oMi[robot.joint_id(obj.joint)] * pin.SE3(obj.placement)
        V = obj.vertices @ M.rotation.T + M.translation
        gap = (np.linalg.norm(V[:, None] - C[None], axis=2) - R[None]).min(axis=1)
        if gap.max() > 0.02:
            return Sphere(tuple(V[int(np.argmax(gap))]), BALL)
    raise AssertionError("no mesh vertex 2 cm outside the capsule spheres")


@pytest.fixture(scope="module")
def setup():  # type: ignore[no-untyped-def]
    robot = load_robot("panda")
    spheres = robot.collision_spheres()  # the 15 capsule spheres: they miss mesh parts
    planner = Planner(KineticEnergyMetric(robot), capacity=1, spheres=spheres, coarse_nodes=0)
    return robot, spheres, planner


def test_exact_check_catches_a_path_grazing_a_mesh_between_spheres(setup) -> None:  # type: ignore[no-untyped-def]
    robot, spheres, planner = setup
    qa, qb = HOME.copy(), HOME.copy()
    qa[0], qb[0] = -0.6, 0.6  # the straight line passes through HOME
    ball = _grazing_ball(robot, planner.exact, HOME, spheres)
    planner.term.set_obstacles([ball])
    line = np.array([qa + s * (qb - qa) for s in np.linspace(0.0, 1.0, 121)])
    assert min(planner.term.min_clearance(q) for q in line) > 0.01  # spheres: clear
    planner.exact.set_obstacles([ball])
    check = planner.exact.path_clearance(np.array([qa, qb]), resolution=0.005)
    assert check.clearance <= -BALL + 1e-4  # the mesh vertex sits at the ball's centre
    assert check.checked >= 240  # 1.2 rad at 5 mrad


def test_planner_never_returns_a_grazing_path_as_free(setup) -> None:  # type: ignore[no-untyped-def]
    """Planted on the planner's own free path: repaired (exact clearance >= 0, re-checked
    twice as finely) or refused with a planning error."""
    robot, spheres, planner = setup
    qa, qb = HOME.copy(), HOME.copy()
    qa[0], qb[0] = -0.6, 0.6
    free = planner.plan(qa, qb, [], budget=20.0)
    middle = free.q[len(free.q) // 2]
    ball = _grazing_ball(robot, planner.exact, middle, spheres)
    try:
        plan = planner.plan(qa, qb, [ball], budget=20.0)
    except PlanningError as err:
        assert "exact check" in str(err)
        return
    assert plan.exact_clearance >= 0.0
    assert any("exact check" in a for a in plan.attempts)  # it was caught, then repaired
    recheck = ExactClearance(robot)
    recheck.set_obstacles([ball])
    assert recheck.path_clearance(plan.q, resolution=0.0025).clearance >= -1e-6


def test_given_spheres_beyond_the_file_keep_clear() -> None:
    """A held ball (a given sphere 0.25 m below the flange, 4 cm radius, beyond the
    URDF's geometry) over a bar that the hand's meshes clear by 3 cm at HOME and the ball
    enters by 4 cm: the plan keeps the ball clear on coal's sphere-box distance with
    Pinocchio's kinematics (every 0.002 rad; the verification decides on the given
    spheres too, `Query.decide`: before, a path tightened on the meshes alone put the
    ball 36 mm into the bar) and the meshes clear on Pinocchio's own collision model
    (1e-6 m)."""
    from test_planning_anytime import _mesh_referee

    from geosyn.metrics.planning.exact_path import checked_configurations
    from geosyn.robots.collision_spheres import file_spheres
    from geosyn.robots.robot import CollisionSphere
    from geosyn.world import Box

    robot = load_robot("panda")
    ball = CollisionSphere("panda_joint7", (0.0, 0.0, 0.25), 0.04)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, HOME)
    centre = data.oMi[robot.joint_id("panda_joint7")].act(np.array(ball.center))
    bar = Box((centre[0], 0.0, centre[2] - 0.05), (0.05, 0.5, 0.05))  # top at the ball's centre
    planner = Planner(KineticEnergyMetric(robot), capacity=1,
                      spheres=(*file_spheres(robot).moving, ball))  # fmt: skip
    qa, qb = HOME.copy(), HOME.copy()
    qa[0], qb[0] = -0.9, 0.9
    plan = planner.plan(qa, qb, [bar], budget=1.0)
    box = coal.CollisionObject(coal.Box(*(2.0 * np.asarray(bar.half_extents))),
                               coal.Transform3s(np.eye(3), np.asarray(bar.center)))  # fmt: skip

    def ball_clearance(q: np.ndarray) -> float:
        pin.forwardKinematics(robot.model, data, q)
        c = data.oMi[robot.joint_id("panda_joint7")].act(np.array(ball.center))
        obj = coal.CollisionObject(coal.Sphere(ball.radius), coal.Transform3s(np.eye(3), c))
        return coal.distance(obj, box, coal.DistanceRequest(), coal.DistanceResult())

    assert ball_clearance(HOME) < -0.03  # the straight line puts the ball in the bar
    dense = checked_configurations(plan.q, 0.002)
    assert min(ball_clearance(q) for q in dense) >= -1e-6
    referee = _mesh_referee(robot, bar)
    assert min(referee(q) for q in dense) >= -1e-6
