"""Clearance certified between the checked configurations (`geosyn.metrics.planning.certify`).

References, none of them the certificate's own code: Pinocchio's forward kinematics of the
Panda's collision vertices (the weights bound every vertex's motion), coal's exact distance
(`ExactClearance.path_clearance`, configuration by configuration) at a step 50 times finer
than the certified one, and a ball centred on a vertex of a convex collision mesh between
two checked configurations (its signed distance is minus its radius: an invariant).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from geosyn.core.errors import InvalidArgument
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import NoPathFound, Plan, Planner, certified_clearance
from geosyn.metrics.planning.certify import certified_plan, displacement_weights
from geosyn.metrics.planning.verify import feasible_result
from geosyn.robots import load_robot
from geosyn.world import Box, Sphere
from geosyn.world.exact_clearance import ExactClearance

HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
BALL = 0.003  # [m]


@pytest.fixture(scope="module")
def panda():  # type: ignore[no-untyped-def]
    robot = load_robot("panda")
    return robot, ExactClearance(robot)


def _points(robot, exact: ExactClearance, q: np.ndarray) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    """Each collision object's points in the world at ``q``: a mesh's vertices, a box's
    corners (the objects are convex: their motion is their vertices' motion)."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    out = []
    for obj, j in zip(exact.objects, exact.joints, strict=True):
        if obj.kind == "mesh":
            local = obj.vertices
        elif obj.kind == "box":
            signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
            local = signs * obj.size
        else:
            raise AssertionError(f"the Panda has no {obj.kind} collision object")
        M = (data.oMi[j] if j else pin.SE3.Identity()) * pin.SE3(obj.placement)
        out.append(local @ M.rotation.T + M.translation)
    return out


def test_weights_bound_every_vertex_motion(panda) -> None:  # type: ignore[no-untyped-def]
    """Over 30 seeded segments of 2 mrad per joint, no vertex moves farther than the bound,
    and the bound is not loose by more than 3x somewhere (it is a useful one)."""
    robot, exact = panda
    w = displacement_weights(exact)
    assert w.shape == (len(exact.objects), 7)
    rng = np.random.default_rng(7)
    tightest = 0.0
    for _ in range(30):
        q = robot.random_q(rng)
        dq = 2e-3 * rng.uniform(-1.0, 1.0, 7)
        moved = [np.linalg.norm(b - a, axis=1).max() for a, b in
                 zip(_points(robot, exact, q), _points(robot, exact, q + dq), strict=True)]  # fmt: skip
        for k, d in enumerate(moved):
            bound = float(w[k] @ np.abs(dq))
            assert d <= bound * (1.0 + 1e-9) + 1e-15, exact.objects[k].name
            if bound > 0.0:
                tightest = max(tightest, d / bound)
    assert tightest > 1.0 / 3.0


def test_certificate_never_above_the_fine_exact_clearance(panda) -> None:  # type: ignore[no-untyped-def]
    """Six seeded paths past a box (five clear of it, by 0.15-42 mm): the certified bound is
    a lower bound of coal's clearance checked 50x finer (1e-9 m); every path clear by more
    than 1 mm is certified (bound >= 0), the one through the box is a collision."""
    robot, exact = panda
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, HOME)
    hand = data.oMi[robot.joint_id("panda_joint7")].translation
    exact.set_obstacles([Box(center=tuple(hand + [0.0, 0.2, 0.0]), half_extents=(0.05, 0.03, 0.2))])
    rng = np.random.default_rng(3)
    seen = {"clear": 0, "collides": 0}
    for _ in range(6):
        qa = HOME + rng.uniform(-0.3, 0.3, 7)
        qb = HOME + rng.uniform(-0.3, 0.3, 7)
        path = np.array([qa, HOME + rng.uniform(-0.1, 0.1, 7), qb])
        cert = certified_clearance(exact, path, 0.005)
        fine = exact.path_clearance(path, 0.0001).clearance
        assert cert.bound <= fine + 1e-9
        if fine > 0.001:
            assert cert.bound >= 0.0 and not cert.collision
            seen["clear"] += 1
        if fine < 0.0:
            assert cert.collision and cert.bound < 0.0
            seen["collides"] += 1
    assert seen == {"clear": 4, "collides": 1}  # and one clear by 0.15 mm: either way


def _pad_crossing(robot, exact: ExactClearance) -> tuple[Sphere, np.ndarray]:  # type: ignore[no-untyped-def]
    """A ball on the outer corner of the left fingertip pad (a box) at HOME, and a path of
    one segment through HOME whose ends move the pad 25 mm either way along its thin
    axis (the ball is then 7 mm clear of the robot at both ends)."""
    data = robot.model.createData()
    k = max(i for i, o in enumerate(exact.objects) if o.link == "panda_leftfinger")
    pad = exact.objects[k]
    assert pad.kind == "box"

    def placement(q: np.ndarray) -> pin.SE3:
        pin.forwardKinematics(robot.model, data, q)
        return data.oMi[exact.joints[k]] * pin.SE3(pad.placement)

    M = placement(HOME)
    J = np.column_stack([(placement(HOME + 1e-6 * e).translation - M.translation) / 1e-6
                         for e in np.eye(7)])  # fmt: skip
    dq = np.linalg.pinv(J) @ M.rotation[:, 1]  # the pad's centre along its thin axis, 1 m/unit
    corner = M.rotation @ (pad.size * [1.0, -1.0, 1.0]) + M.translation  # on the outer face
    return Sphere(center=tuple(corner), radius=BALL), np.array(
        [HOME - 0.025 * dq, HOME + 0.025 * dq]
    )


def test_certificate_finds_a_collision_between_checked_configurations(panda) -> None:  # type: ignore[no-untyped-def]
    """The pad crossing (`_pad_crossing`) checked at its two ends only: the check sees
    7 mm of clearance, the certificate halves the segment and measures minus the ball's
    radius at HOME (the ball is centred on a corner of the convex pad; 1e-9 m)."""
    robot, exact = panda
    ball, path = _pad_crossing(robot, exact)
    exact.set_obstacles([ball])
    assert exact.clearance(HOME)[0] == pytest.approx(-BALL, abs=1e-9)
    step = float(np.abs(path[1] - path[0]).max())  # one checked segment
    assert exact.path_clearance(path, step).clearance > 0.005  # the two ends: missed
    cert = certified_clearance(exact, path, step)
    assert cert.collision and cert.bound < 0.0
    assert cert.sampled == pytest.approx(-BALL, abs=1e-9)  # the first midpoint is HOME
    assert cert.halved >= 1 and cert.measured == 2 + cert.halved


@pytest.fixture(scope="module")
def planner(panda) -> Planner:  # type: ignore[no-untyped-def]
    robot, _ = panda  # test_planning_exact's planner: its node functions are cached once
    return Planner(KineticEnergyMetric(robot), capacity=1, spheres=robot.collision_spheres(),
                   coarse_nodes=0)  # fmt: skip


def test_plan_with_certify_reports_a_lower_bound(planner: Planner) -> None:
    """A plan past a ball 3 cm from the hand's straight swing, certified: its bound is
    clear, below its own exact clearance and below coal's on the URDF meshes 20x finer
    than the planner's check (1e-9 m); its attempts say so."""
    qa, qb = HOME.copy(), HOME.copy()
    qa[0], qb[0] = -0.6, 0.6
    data = planner.robot.model.createData()
    pin.forwardKinematics(planner.robot.model, data, HOME)
    hand = data.oMi[planner.robot.joint_id("panda_joint7")].translation
    ball = Sphere(center=tuple(hand + [0.0, 0.0, 0.12]), radius=0.03)
    plan = planner.plan(qa, qb, [ball], budget=1.0, certify=True)
    assert 0.0 <= plan.certified_clearance <= plan.exact_clearance + 1e-12
    exact = ExactClearance(planner.robot)
    exact.set_obstacles([ball])
    assert (
        plan.certified_clearance
        <= exact.path_clearance(plan.q, planner.exact_resolution / 20).clearance + 1e-9
    )
    assert any("certified between" in a for a in plan.attempts)
    assert math.isnan(planner.plan(qa, qb, [ball], budget=1.0).certified_clearance)  # not asked


def test_a_plan_colliding_between_checked_configurations_is_refused(
    panda, planner: Planner
) -> None:  # type: ignore[no-untyped-def]
    """A plan whose path is the pad crossing (`_pad_crossing`, at the planner's 5 mrad
    step): `certified_plan` refuses it with `NoPathFound`, never returns it as free."""
    robot, _ = panda
    ball, path = _pad_crossing(robot, planner.exact)
    plan = Plan(feasible_result(planner.metric, path, "planted"), "planted", math.nan, 0.0, ())
    with pytest.raises(NoPathFound, match="between its checked configurations"):
        certified_plan(planner, plan, [ball], 1.0)


def test_planner_certify_refuses_a_robot_without_file_geometry() -> None:
    with pytest.warns(UserWarning, match="capsule spheres only"):  # said at build
        planner = Planner(KineticEnergyMetric(load_robot("planar2")), capacity=1, coarse_nodes=0)
    with pytest.raises(InvalidArgument, match="no file collision geometry"):
        planner.certify(np.zeros((2, 2)), [])


def test_certified_clearance_refuses_bad_arguments(panda) -> None:  # type: ignore[no-untyped-def]
    _, exact = panda
    with pytest.raises(InvalidArgument, match="resolution"):
        certified_clearance(exact, np.array([HOME, HOME]), 0.0)
    with pytest.raises(InvalidArgument, match="target"):
        certified_clearance(exact, np.array([HOME, HOME]), 0.005, target=-1.0)
    with pytest.raises(InvalidArgument, match=r"path: a \(T, 7\) array.*non-finite"):
        certified_clearance(exact, np.array([HOME, HOME * np.nan]), 0.005)
    with pytest.raises(InvalidArgument, match=r"path: a \(T, 7\) array"):
        certified_clearance(exact, np.zeros((3, 6)), 0.005)
    with pytest.raises(InvalidArgument, match="path"):
        certified_clearance(exact, "not a path", 0.005)
