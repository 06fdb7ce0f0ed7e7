"""MuJoCo model built from a Robot has the Pinocchio model's dynamics (robots/mjcf.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from conftest import BUILTIN_NAMES, get_robot
from geosyn.core import GeosynError
from geosyn.robots import load_robot


def _mj_state(robot, **options):
    mm = robot.mj_model(limits=False, **options)
    return mm, mujoco.MjData(mm)


@pytest.mark.parametrize("name", BUILTIN_NAMES)
def test_mass_matrix_and_bias_match_pinocchio(name: str) -> None:
    robot = get_robot(name)
    mm, md = _mj_state(robot)
    data = robot.model.createData()
    rng = np.random.default_rng(11)
    worst_M = worst_b = 0.0
    for _ in range(200):
        q = robot.random_q(rng)
        v = rng.normal(size=robot.nv)
        md.qpos[:], md.qvel[:] = q, v
        mujoco.mj_forward(mm, md)
        M_mj = np.zeros((robot.nv, robot.nv))
        mujoco.mj_fullM(mm, md, M_mj)
        M_pin = pin.crba(robot.model, data, q)
        worst_M = max(worst_M, np.abs(M_pin - M_mj).max() / np.abs(M_pin).max())
        b_pin = pin.rnea(robot.model, data, q, v, np.zeros(robot.nv))
        worst_b = max(worst_b, np.abs(b_pin - md.qfrc_bias).max())
    assert worst_M <= 1e-9, f"{name}: max |M_pin - M_mj| / max|M| = {worst_M:.2e}"
    assert worst_b <= 1e-8, f"{name}: max |bias_pin - qfrc_bias| = {worst_b:.2e} N m"


@pytest.mark.parametrize("name", BUILTIN_NAMES)
def test_model_parameters_carry_over(name: str) -> None:
    robot = get_robot(name)
    mm = robot.mj_model()
    assert mm.nv == robot.nv and mm.nu == robot.nv
    np.testing.assert_allclose(mm.dof_armature, robot.armature, rtol=0, atol=1e-15)
    np.testing.assert_allclose(mm.actuator_ctrlrange[:, 1], robot.tau_max, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mm.actuator_ctrlrange[:, 0], -robot.tau_max, rtol=0, atol=1e-12)
    masses = [robot.model.inertias[j].mass for j in range(1, robot.model.njoints)]
    np.testing.assert_allclose(mm.body_mass[1:], masses, rtol=1e-14)
    np.testing.assert_allclose(mm.opt.gravity, robot.gravity, rtol=0, atol=0)
    limited = np.isfinite(robot.q_min)
    np.testing.assert_array_equal(mm.jnt_limited.astype(bool), limited)
    np.testing.assert_allclose(mm.jnt_range[limited, 0], robot.q_min[limited])


def test_gravity_is_configurable_and_planar_gravity_does_no_work() -> None:
    robot = get_robot("planar2")
    mm = robot.mj_model(gravity=(0.0, 0.0, -3.0))
    assert tuple(mm.opt.gravity) == (0.0, 0.0, -3.0)
    md = mujoco.MjData(mm)
    md.qpos[:] = [0.4, -1.1]
    mujoco.mj_forward(mm, md)
    # Joints rotate about z and gravity is along z: no gravity torque at rest.
    np.testing.assert_allclose(md.qfrc_bias, 0.0, atol=1e-15)


def test_ee_site_matches_pinocchio_frame() -> None:
    robot = get_robot("panda")
    mm = robot.mj_model()
    md = mujoco.MjData(mm)
    q = robot.random_q(np.random.default_rng(3))
    md.qpos[:] = q
    mujoco.mj_kinematics(mm, md)
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    fid = robot.frame_id(robot.ee_frame)
    np.testing.assert_allclose(md.site(robot.ee_frame).xpos, data.oMf[fid].translation, atol=1e-12)


def test_mjcf_round_trip_through_file(tmp_path) -> None:
    """Writing the MJCF and loading it back as a robot file gives the same mass matrix."""
    robot = get_robot("planar3")
    path = tmp_path / "planar3.xml"
    path.write_text(robot.mjcf())
    again = load_robot(path)
    assert again.nv == robot.nv
    q = np.array([0.3, -0.7, 1.2])
    M0 = pin.crba(robot.model, robot.model.createData(), q)
    M1 = pin.crba(again.model, again.model.createData(), q)
    np.testing.assert_allclose(M1, M0, atol=1e-12 * np.abs(M0).max())


def test_bad_options_raise_clear_errors() -> None:
    robot = get_robot("planar2")
    with pytest.raises(GeosynError, match="integrator"):
        robot.mjcf(integrator="leapfrog")
    with pytest.raises(GeosynError, match="timestep"):
        robot.mjcf(timestep=-1.0)
    with pytest.raises(GeosynError, match="body_extra"):
        robot.mjcf(body_extra={"nope": "<geom/>"})
