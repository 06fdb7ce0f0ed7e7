"""Floating-base robots load as they are (geosyn.robots.floating, geosyn.robots.free_flyer).

References: Pinocchio's own free-flyer model of the same URDF
(``buildModelFromUrdf(path, JointModelFreeFlyer())``) and MuJoCo's own compile of an MJCF
file with a free joint.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from floating_cases import CATALOG_FLOATING, FLOATER, floater_file, load_quietly

from geosyn.controllers import ComputedTorque, PinocchioPlant
from geosyn.core import GeosynError
from geosyn.robots import FloatingBaseError, RobotFileError, load_robot, robot_to_mjcf, symbolic
from geosyn.robots.catalog import catalog
from geosyn.robots.files import example_robot_data_dir
from geosyn.robots.floating import QUATERNION_TOL, from_mujoco, to_mujoco


@pytest.mark.parametrize("name", CATALOG_FLOATING)
def test_catalog_robot_loads_floating_like_pinocchios_free_flyer(name) -> None:
    robot = load_quietly(name)
    ref = pin.buildModelFromUrdf(
        str(example_robot_data_dir() / catalog()[name].relative_path), pin.JointModelFreeFlyer()
    )
    assert robot.floating and robot.base.startswith("floating")
    assert (robot.nq, robot.nv) == (ref.nq, ref.nv) == (len(robot.joint_names) + 7, robot.nv)
    assert robot.model.names[1] == "root_joint" and list(robot.model.names) == list(ref.names)
    assert np.all(robot.tau_max[:6] == 0.0) and np.all(np.isinf(robot.q_min[:7]))
    data, ref_data = robot.model.createData(), ref.createData()
    rng = np.random.default_rng(7)
    for _ in range(5):  # every frame of the reference model at the same configuration
        q = robot.random_q(rng)
        pin.framesForwardKinematics(robot.model, data, q)
        pin.framesForwardKinematics(ref, ref_data, q)
        for i, frame in enumerate(ref.frames):
            mine = data.oMf[robot.model.getFrameId(frame.name, frame.type)]
            assert np.abs(mine.homogeneous - ref_data.oMf[i].homogeneous).max() < 1e-12
    assert robot.total_mass == pytest.approx(pin.computeTotalMass(ref), rel=1e-12)


def test_fixed_base_option_still_welds_the_root() -> None:
    with pytest.warns(UserWarning, match="floating base is fixed"):
        go2 = load_robot("go2", fixed_base=True)
    assert not go2.floating and go2.nq == go2.nv == 12 and "fixed_base=True" in go2.base


def test_neutral_and_random_configurations_are_on_the_group() -> None:
    robot = load_quietly("solo12")
    q = robot.neutral()
    assert q.shape == (19,) and np.array_equal(q[:7], [0, 0, 0, 0, 0, 0, 1])
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = robot.random_q(rng)
        assert abs(np.linalg.norm(q[3:7]) - 1.0) < 1e-15
        assert np.all(q[7:] >= robot.q_min[7:]) and np.all(q[7:] <= robot.q_max[7:])


def test_a_quaternion_that_is_not_unit_is_one_clear_error() -> None:
    robot = load_quietly("solo12")
    q = robot.neutral()
    q[3:7] = [0.0, 0.0, 0.0, 1.0 + 10 * QUATERNION_TOL]
    with pytest.raises(FloatingBaseError, match=r"q\[3:7\] .* must be unit .* norm is 1\.00000001"):
        robot.check_q(q)
    q[3:7] = 0.0
    with pytest.raises(FloatingBaseError, match="'solo12'"):
        robot.check_q(q)
    q[3:7] = [0.0, 0.0, 0.0, 1.0 + 0.1 * QUATERNION_TOL]  # within the tolerance
    assert robot.check_q(q) is not None


def test_mjcf_free_joint_loads_floating_with_mujocos_mass_matrix(tmp_path) -> None:
    path = floater_file(tmp_path)
    robot = load_quietly(path)
    assert robot.floating and "MJCF free joint 'root' of body 'torso'" in robot.base
    assert robot.joint_names == ("hip_l", "knee_l", "hip_r", "slide")
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    data = robot.model.createData()
    for _ in range(10):
        quat = rng.normal(size=4)  # MuJoCo's (w, x, y, z)
        d.qpos[:] = np.concatenate(
            [rng.normal(size=3), quat / np.linalg.norm(quat)] + [rng.uniform(-1, 1, 4)]
        )
        mujoco.mj_forward(m, d)
        M_mj = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M_mj)
        q, _ = from_mujoco(d.qpos, np.zeros(m.nv))
        # qvel = T v (world-frame linear base velocity): the same energy needs T^T M_mj T
        T = np.eye(m.nv)
        T[:3, :3] = d.xmat[1].reshape(3, 3)
        M = pin.crba(robot.model, data, q)
        assert np.abs(M - T.T @ M_mj @ T).max() < 1e-12
        pin.framesForwardKinematics(robot.model, data, q)
        for site in ("foot_l", "torso_site"):
            frame = data.oMf[robot.model.getFrameId(site)]
            sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, site)
            assert np.abs(frame.translation - d.site_xpos[sid]).max() < 1e-12
            assert np.abs(frame.rotation - d.site_xmat[sid].reshape(3, 3)).max() < 1e-12


def test_mujoco_conversions_are_inverse_and_match_the_world_velocity(tmp_path) -> None:
    m = mujoco.MjModel.from_xml_path(str(floater_file(tmp_path)))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(2)
    d.qpos[7:] = rng.uniform(-1, 1, 4)
    d.qvel[:] = rng.normal(size=m.nv)
    mujoco.mj_forward(m, d)
    q, v = from_mujoco(d.qpos, d.qvel)
    qpos, qvel = to_mujoco(q, v)
    assert np.abs(qpos - d.qpos).max() < 1e-15 and np.abs(qvel - d.qvel).max() < 1e-15
    # the base frame's world velocity: MuJoCo's qvel[:3]; Pinocchio's R v[:3]
    R = d.xmat[1].reshape(3, 3)
    assert np.abs(R @ v[:3] - d.qvel[:3]).max() < 1e-15 and np.array_equal(v[3:], d.qvel[3:])


@pytest.mark.filterwarnings("ignore:robot 'floater'")
def test_mjcf_refusals_and_the_welded_option(tmp_path) -> None:
    path = floater_file(tmp_path)
    with pytest.warns(UserWarning, match="welded"):
        welded = load_robot(path, fixed_base=True)
    assert not welded.floating and welded.nq == 4
    two = tmp_path / "two.xml"
    two.write_text(
        FLOATER.format(dt=1e-3).replace(
            "</worldbody>",
            '<body name="ball"><freejoint name="ball_free"/><geom size="0.1"/></body></worldbody>',
        )
    )
    with pytest.raises(RobotFileError, match="'ball_free' of body 'ball' is a free joint that"):
        load_robot(two)


def test_fixed_base_consumers_refuse_a_floating_robot_by_name() -> None:
    robot = load_quietly("solo12")
    refused = {
        "the MuJoCo twin": robot.mj_model,
        "robot_to_mjcf": lambda: robot_to_mjcf(robot),
        "PinocchioPlant": lambda: PinocchioPlant(robot),
        "ComputedTorque": lambda: ComputedTorque(robot, kp=1.0, kd=1.0),
    }
    for what, call in refused.items():
        with pytest.raises(FloatingBaseError, match=f"{what}.*'solo12' has a floating base"):
            call()
    with pytest.raises(GeosynError, match=r"floating base: its free flyer"):
        symbolic.crba(robot.model, np.zeros(robot.nq))
