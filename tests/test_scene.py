"""Scene: payload bodies, obstacle geoms and clearance, name resolution."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from conftest import get_robot
from geosyn.core.errors import InvalidArgument
from geosyn.metrics.shaping import ObstacleTerm
from geosyn.sim import UnknownBody, build_scene
from geosyn.sim.obstacles import obstacle_geom
from geosyn.world import Box, Capsule, HalfSpace, InvalidGeometry, Payload, Sphere


def rot(axis, angle):
    return pin.AngleAxis(angle, np.asarray(axis, dtype=float) / np.linalg.norm(axis)).matrix()


OBSTACLES = (
    Sphere((0.5, 0.1, 0.5), 0.1),
    Box((0.3, -0.4, 0.3), (0.1, 0.05, 0.2), tuple(map(tuple, rot((1, 2, 3), 0.7)))),
    Capsule((-0.4, 0.3, 0.0), (-0.2, 0.5, 0.8), 0.05),
    HalfSpace((0.0, 0.0, 1.0), -0.05),
)


def pinocchio_with_payload(robot, frame, mass, offset, radius):
    """Pinocchio model with a solid sphere welded to ``frame`` (independent of geosyn.sim)."""
    model = pin.Model(robot.model)
    f = model.frames[model.getFrameId(frame)]
    inertia = pin.Inertia(mass, np.asarray(offset, dtype=float), np.eye(3) * 0.4 * mass * radius**2)
    model.inertias[f.parentJoint] = model.inertias[f.parentJoint] + f.placement.act(inertia)
    return model


def test_payload_gravity_matches_pinocchio():
    robot = get_robot("panda")
    payload = Payload("panda_hand_tcp", 1.5, com=(0.01, 0.02, 0.05), radius=0.04)
    scene = build_scene(robot, payloads=[payload])
    m, d = scene.model, mujoco.MjData(scene.model)
    ref_model = pinocchio_with_payload(robot, "panda_hand_tcp", 1.5, (0.01, 0.02, 0.05), 0.04)
    ref_data = ref_model.createData()
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = robot.random_q(rng)
        v = rng.normal(size=7)
        d.qpos[:], d.qvel[:] = q, v
        mujoco.mj_forward(m, d)
        assert np.allclose(d.qfrc_bias, pin.rnea(ref_model, ref_data, q, v, np.zeros(7)), atol=1e-9)
        M = np.zeros((7, 7))
        mujoco.mj_fullM(m, d, M)
        assert np.allclose(M, pin.crba(ref_model, ref_data, q), atol=1e-10)
    assert m.body_mass[scene.payload_body_ids[0]] == 1.5
    assert m.body_subtreemass[0] == pytest.approx(robot.total_mass + 1.5)


def test_payload_with_inertia_matches_pinocchio():
    """A payload given by a full (rotated) inertia in a rotated frame: MuJoCo's mass matrix
    equals Pinocchio's with the same rigid body appended to the frame."""
    robot = get_robot("panda")
    com = np.array([0.01, -0.02, 0.04])
    inertia = np.array([[0.02, 0.003, -0.001], [0.003, 0.03, 0.002], [-0.001, 0.002, 0.025]])
    payload = Payload("panda_hand_tcp", 1.2, com=tuple(com), inertia=inertia)
    scene = build_scene(robot, payloads=[payload])
    m, d = scene.model, mujoco.MjData(scene.model)
    ref_model = pin.Model(robot.model)
    f = ref_model.frames[ref_model.getFrameId("panda_hand_tcp")]
    ref_model.appendBodyToJoint(f.parentJoint, pin.Inertia(1.2, com, inertia), f.placement)
    ref_data = ref_model.createData()
    M = np.zeros((7, 7))
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = robot.random_q(rng)
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, M)
        assert np.allclose(M, pin.crba(ref_model, ref_data, q), atol=1e-10)
    # The inertia matters (the test can fail): a ball payload gives another matrix.
    ball = build_scene(robot, payloads=[Payload("panda_hand_tcp", 1.2, com=tuple(com))])
    db = mujoco.MjData(ball.model)
    db.qpos[:] = q
    mujoco.mj_forward(ball.model, db)
    Mb = np.zeros((7, 7))
    mujoco.mj_fullM(ball.model, db, Mb)
    assert np.abs(Mb - M).max() > 1e-3


def test_obstacle_geoms_are_placed_as_the_shapes():
    robot = get_robot("panda")
    scene = build_scene(robot, obstacles=OBSTACLES)
    d = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, d)
    sphere, box, capsule, plane = scene.obstacle_geom_ids
    assert np.allclose(d.geom_xpos[sphere], OBSTACLES[0].center)
    assert np.allclose(d.geom_xpos[box], OBSTACLES[1].center)
    assert np.allclose(
        d.geom_xmat[box].reshape(3, 3), np.asarray(OBSTACLES[1].rotation), atol=1e-12
    )
    assert np.allclose(scene.model.geom_size[box], OBSTACLES[1].half_extents)
    axis = d.geom_xmat[capsule].reshape(3, 3)[:, 2]
    seg = np.subtract(OBSTACLES[2].p1, OBSTACLES[2].p0)
    assert np.allclose(np.abs(axis @ seg), np.linalg.norm(seg))
    assert np.allclose(d.geom_xmat[plane].reshape(3, 3)[:, 2], [0, 0, 1])
    assert np.allclose(d.geom_xpos[plane], [0, 0, -0.05])
    # visual only by default
    assert np.all(scene.model.geom_contype[scene.obstacle_geom_ids] == 0)
    assert np.all(scene.model.geom_conaffinity[scene.obstacle_geom_ids] == 0)


@pytest.mark.parametrize("index", range(4))
def test_signed_distance_matches_mujoco_geom_distance(index):
    """Analytic distance of a point vs mj_geomDistance to a tiny sphere at the point."""
    ob = obstacle_geom(OBSTACLES[index], 0)
    rng = np.random.default_rng(index)
    pts = rng.uniform(-0.8, 0.8, size=(20, 3)) + np.array([0.0, 0.0, 0.4])
    xml = (
        "<mujoco><worldbody>"
        + ob.xml
        + '<body name="probe" mocap="true"><geom name="probe" type="sphere" size="1e-6"/></body>'
        + "</worldbody></mujoco>"
    )
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    for p in pts:
        d.mocap_pos[0] = p
        mujoco.mj_forward(m, d)
        dist = mujoco.mj_geomDistance(m, d, 0, 1, 10.0, None) + 1e-6
        if isinstance(ob.shape, HalfSpace):
            assert ob.signed_distance(p[None])[0] == pytest.approx(dist, abs=1e-6)
        elif dist > 0:  # MuJoCo's penetration depth inside a solid is not a signed distance
            assert ob.signed_distance(p[None])[0] == pytest.approx(dist, abs=1e-6)
        else:
            assert ob.signed_distance(p[None])[0] < 1e-6


def test_clearance_matches_obstacle_term():
    """Clearance from MuJoCo body poses equals the shaping term's CasADi clearance."""
    robot = get_robot("panda")
    scene = build_scene(robot, obstacles=OBSTACLES)
    term = ObstacleTerm(OBSTACLES).bind(robot)
    d = mujoco.MjData(scene.model)
    rng = np.random.default_rng(3)
    values = []
    for _ in range(5):
        q = robot.random_q(rng)
        d.qpos[:] = q
        mujoco.mj_kinematics(scene.model, d)
        c = scene.clearance(d.xpos, d.xmat)
        assert c == pytest.approx(term.min_clearance(q), abs=1e-9)
        # given q: the compiled check for the rounded shapes, numpy for the half-space
        assert scene.clearance(d.xpos, d.xmat, q) == pytest.approx(c, abs=1e-9)
        values.append(c)
    assert len(set(np.round(values, 6))) == 5


@pytest.mark.parametrize("which", range(len(OBSTACLES) + 1))
def test_each_shapes_clearance_matches_the_obstacle_term(which):
    """Each shape alone (the batched rounded boxes and the per-shape formulas: a
    half-space, a cylinder measured exactly), from MuJoCo body poses and, given q, by the
    compiled sphere check, against the
    shaping term's CasADi clearance (Pinocchio kinematics) or, for the cylinder, the
    closed form at the spheres' centres from Pinocchio; 1e-9 m at seeded configurations."""
    from geosyn.world import Cylinder, signed_distance

    robot = get_robot("panda")
    cylinder = Cylinder((0.4, 0.4, 0.3), 0.06, 0.2)
    shape = OBSTACLES[which] if which < len(OBSTACLES) else cylinder
    scene = build_scene(robot, obstacles=[shape])
    term = ObstacleTerm([shape]).bind(robot) if shape is not cylinder else None
    d, data = mujoco.MjData(scene.model), robot.model.createData()
    spheres = robot.collision_spheres()
    rng = np.random.default_rng(7)
    for _ in range(4):
        q = robot.random_q(rng)
        d.qpos[:] = q
        mujoco.mj_kinematics(scene.model, d)
        if term is not None:
            expected = term.min_clearance(q)
        else:
            pin.forwardKinematics(robot.model, data, q)
            centres = np.array(
                [data.oMi[robot.joint_id(s.joint)].act(np.array(s.center)) for s in spheres]
            )
            expected = float(
                np.min(signed_distance(cylinder, centres) - [s.radius for s in spheres])
            )
        assert scene.clearance(d.xpos, d.xmat) == pytest.approx(expected, abs=1e-9)  # numpy
        # given q: the compiled check for spheres, boxes and capsules (numpy for the rest)
        assert scene.clearance(d.xpos, d.xmat, q) == pytest.approx(expected, abs=1e-9)
    compiled = isinstance(shape, (Sphere, Box, Capsule))
    assert (scene.clearance._native is not None) == compiled


def test_clearance_inf_without_obstacles():
    robot = get_robot("panda")
    scene = build_scene(robot)
    d = mujoco.MjData(scene.model)
    mujoco.mj_kinematics(scene.model, d)
    assert scene.clearance(d.xpos, d.xmat) == np.inf


def test_contact_option_makes_obstacles_collide():
    robot = get_robot("panda")
    q = robot.neutral()
    probe = build_scene(robot)
    d = mujoco.MjData(probe.model)
    d.qpos[:] = q
    mujoco.mj_kinematics(probe.model, d)
    hand = probe.resolve_body("panda_link7")
    inside = Sphere(tuple(d.xpos[hand]), 0.1)
    for contact, expected in ((False, 0), (True, 1)):
        scene = build_scene(robot, obstacles=[inside], contact=contact)
        dd = mujoco.MjData(scene.model)
        dd.qpos[:] = q
        mujoco.mj_forward(scene.model, dd)
        obstacle_contacts = [
            c for c in dd.contact[: dd.ncon] if scene.obstacle_geom_ids[0] in (c.geom1, c.geom2)
        ]
        assert (len(obstacle_contacts) > 0) == bool(expected)
        # robot geoms never collide with each other
        assert all(scene.obstacle_geom_ids[0] in (c.geom1, c.geom2) for c in dd.contact[: dd.ncon])


def test_resolve_body_names():
    robot = get_robot("panda")
    scene = build_scene(robot, payloads=[Payload("panda_hand", 0.5, name="box")])
    link7 = scene.resolve_body("panda_link7")
    assert scene.resolve_body("panda_hand") == link7  # frame on joint 7
    assert scene.resolve_body("panda_joint7") == link7
    assert scene.resolve_body("box") == scene.payload_body_ids[0]
    with pytest.raises(UnknownBody, match="'hand'.*available MuJoCo bodies: world, panda_link1"):
        scene.resolve_body("hand")
    # a point in the hand frame expressed in the link7 body frame
    f = robot.model.frames[robot.frame_id("panda_hand")]
    assert np.allclose(
        scene.frame_point_in_body("panda_hand", [0, 0, 0.1]), f.placement.act(np.array([0, 0, 0.1]))
    )


def test_bad_scene_input():
    robot = get_robot("panda")
    with pytest.raises(UnknownBody, match="'nowhere'"):
        build_scene(robot, payloads=[Payload("nowhere", 1.0)])
    with pytest.raises(InvalidArgument, match="fixed to the world"):
        build_scene(robot, payloads=[Payload("panda_link0", 1.0)])
    with pytest.raises(InvalidArgument, match="mass"):
        Payload("panda_hand", -1.0)
    with pytest.raises(InvalidArgument, match="unique"):
        build_scene(
            robot,
            payloads=[Payload("panda_hand", 1.0, name="a"), Payload("panda_hand", 1.0, name="a")],
        )
    with pytest.raises(InvalidGeometry, match=r"obstacles\[0\] is a str"):
        build_scene(robot, obstacles=["a cube"])
    with pytest.raises(InvalidArgument, match="timestep"):
        build_scene(robot, timestep=0.0)


def test_a_payload_on_a_link_named_like_a_joint_rides_on_the_link() -> None:
    """The Unitree Z1's ``gripperStator`` names a link and a joint (two Pinocchio frames;
    before, `link_placement` raised Pinocchio's ValueError): the payload frame is the
    link's, its world pose equal to Pinocchio's ``oMf`` of the body frame (1e-12 m) at a
    seeded configuration."""
    from geosyn.robots import load_robot
    from geosyn.sim.scene import link_placement

    robot = load_robot("z1")
    model = robot.model
    joint, jMf = link_placement(robot, "gripperStator")
    body = model.getFrameId("gripperStator", pin.FrameType.BODY)
    q = robot.random_q(np.random.default_rng(2))
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    ours = (data.oMi[joint] * jMf).homogeneous
    assert np.abs(ours - data.oMf[body].homogeneous).max() < 1e-12
