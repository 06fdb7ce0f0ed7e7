"""Loading built-in robots and robot files (robots/loading.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import BUILTIN_NAMES, get_robot
from geosyn.core import GeosynError
from geosyn.robots import RobotFileError, UnknownFrame, UnknownRobot, load_robot
from geosyn.robots.builtins import planar2
from geosyn.robots.files import example_robot_data_dir

CONTINUOUS_URDF = """<?xml version="1.0"?>
<robot name="wheelarm">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.1 0 0"/><mass value="1.5"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.2 0 0"/><mass value="0.7"/>
    <inertia ixx="0.005" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l3"><inertial><origin xyz="0 0 0.05"/><mass value="0.2"/>
    <inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit effort="10" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="5" velocity="3"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.4 0 0"/><axis xyz="0.6 0.8 0"/><limit effort="2" velocity="4"/></joint>
</robot>
"""


@pytest.mark.parametrize(
    ("name", "dof"), [("planar2", 2), ("planar3", 3), ("panda", 7), ("talos_arm", 7), ("ur5", 6)]
)
def test_builtins_have_expected_dof(name: str, dof: int) -> None:
    robot = get_robot(name)
    assert robot.nq == robot.nv == dof
    assert len(robot.joint_names) == dof
    assert robot.tau_max.shape == robot.v_max.shape == (dof,)
    assert np.all(robot.tau_max > 0) and np.all(robot.v_max > 0)
    assert np.all(robot.q_min < robot.q_max)
    robot.frame_id(robot.ee_frame)
    assert robot.capsules, "every built-in has collision geometry"


def test_panda_matches_pinocchio_with_fingers_locked() -> None:
    """The 7-DoF panda equals the full URDF model with the finger joints held closed."""
    panda = get_robot("panda")
    full = pin.buildModelFromUrdf(
        str(example_robot_data_dir() / "panda_description/urdf/panda.urdf")
    )
    assert full.nq == 9
    rng = np.random.default_rng(5)
    q7 = panda.random_q(rng)
    q9 = np.concatenate([q7, [0.0, 0.0]])
    data = full.createData()
    M9 = pin.crba(full, data, q9)[:7, :7] + np.diag(panda.armature)
    M7 = pin.crba(panda.model, panda.model.createData(), q7)
    np.testing.assert_allclose(M7, M9, atol=1e-12)


def test_planar2_parameters_are_overridable() -> None:
    robot = planar2(m1=2.0, m2=0.5, l1=1.5, l2=0.75)
    masses = [robot.model.inertias[j].mass for j in (1, 2)]
    assert masses == [2.0, 0.5]
    np.testing.assert_allclose(robot.model.jointPlacements[2].translation, [1.5, 0.0, 0.0])
    assert robot.total_mass == pytest.approx(2.5, abs=1e-15)


def test_continuous_joints_load_as_plain_revolute(tmp_path) -> None:
    path = tmp_path / "wheelarm.urdf"
    path.write_text(CONTINUOUS_URDF)
    raw = pin.buildModelFromUrdf(str(path))
    assert raw.nq == 5 and raw.nv == 3  # Pinocchio's (cos, sin) continuous joints
    robot = load_robot(path)
    assert robot.nq == robot.nv == 3
    assert np.isinf(robot.q_min[0]) and np.isinf(robot.q_max[2])
    assert (robot.q_min[1], robot.q_max[1]) == (-1.0, 1.0)
    # Same dynamics: q = angles <-> raw (cos, sin) configuration.
    angles = np.array([0.7, -0.4, 2.1])
    q_raw = np.array([np.cos(0.7), np.sin(0.7), -0.4, np.cos(2.1), np.sin(2.1)])
    v = np.array([0.3, -1.2, 0.8])
    M_raw = pin.crba(raw, raw.createData(), q_raw)
    M = pin.crba(robot.model, robot.model.createData(), angles)
    np.testing.assert_allclose(M, M_raw, atol=1e-14)
    b_raw = pin.rnea(raw, raw.createData(), q_raw, v, np.zeros(3))
    b = pin.rnea(robot.model, robot.model.createData(), angles, v, np.zeros(3))
    np.testing.assert_allclose(b, b_raw, atol=1e-13)


def test_keep_joints_locks_the_rest(tmp_path) -> None:
    path = tmp_path / "wheelarm.urdf"
    path.write_text(CONTINUOUS_URDF)
    robot = load_robot(path, keep_joints=["j2", "j3"], lock_q={"j1": 0.0})
    assert robot.joint_names == ("j2", "j3")
    with pytest.raises(UnknownFrame, match="available: j1, j2, j3") as info:
        load_robot(path, keep_joints=["j9"])
    assert info.value.name == "j9" and info.value.available == ("j1", "j2", "j3")


def test_unknown_robot_lists_available() -> None:
    with pytest.raises(UnknownRobot) as info:
        load_robot("pandda")
    msg = str(info.value)
    for name in BUILTIN_NAMES:
        assert name in msg
    assert isinstance(info.value, GeosynError)
    assert info.value.name == "pandda" and set(BUILTIN_NAMES) <= set(info.value.available)


def test_missing_and_malformed_files(tmp_path) -> None:
    with pytest.raises(RobotFileError, match="does not exist") as info:
        load_robot(tmp_path / "nothing.urdf")
    assert info.value.path == str(tmp_path / "nothing.urdf")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot")
    with pytest.raises(RobotFileError, match="could not parse"):
        load_robot(bad)


def test_bad_builder_options() -> None:
    with pytest.raises(GeosynError, match="masses"):
        planar2(m1=-1.0)
    with pytest.raises(GeosynError, match="bad option"):
        load_robot("planar2", mass=3.0)
    with pytest.raises(GeosynError, match="armature"):
        load_robot("planar2", armature=-0.1)
